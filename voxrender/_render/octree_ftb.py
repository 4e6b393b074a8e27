"""Zhao and Davis's front-to-back octree display with blocking quadtrees, vectorised.

The literal version (:mod:`.literal.octree_ftb`) keeps the blocking bitmaps and recurses
octant by octant.  Its decisions can be computed without the recursion, from what the
bitmaps *mean* (derived from the procedures of Sec. 4; the tests prove it by comparing every
statistic with the literal version):

1. Refine and compact never change which pixels of a face plane lie under a B node; only
   leaves write (a black leaf B, a white leaf W, over its own square).  So the value an octant
   finds on one axis is B exactly when every leaf just across its front face on that axis has
   left B there: a black leaf, or any leaf the traversal blocked or never reached.
2. Hence an octant is blocked exactly when no front face of it touches the boundary of the
   octree space or a white leaf that was *seen*, and a white leaf is seen when a front face of
   it touches the boundary or a seen white leaf.  The seen leaves are the white leaves reachable
   from the front of the octree space by steps away from the viewer across faces: one
   breadth-first search over face-adjacent white leaves (:attr:`RegionOctree.white_to_white`).
   It never reaches inside a blocked octant.
3. A grey octant off the boundary is unblocked exactly when it holds a seen white leaf or a black
   leaf whose front face touches one: a seen leaf across its front face lies against such a leaf
   inside, and a path of seen leaves into it from outside must cross one of its front faces.
4. The traversal then goes down one depth at a time, every octant of a depth at once: blocked
   octants are counted and dropped with their subtrees (never descended); unblocked grey octants
   hand on their eight children; unblocked black leaves scan-convert their open faces.
5. Painting "un-painted pixels only" in the FTB order is done as: every open face's pixels, keeping
   per pixel the nearest.  In FTB order the first face to reach a pixel is the nearest, except on a
   ray that runs along an edge two faces share (see the ties in :mod:`.literal.octree_ftb`), where
   both versions keep the nearer.
"""

from __future__ import annotations

import time

import numpy as np

from ..object import octree
from ..space.view import vpn_from_angles
from .octree_btf import front_to_back_children, paint_faces, region_octree, visible_axes


def _behind(axes):
    """Direction codes of :attr:`RegionOctree.white_to_white` that step away from the viewer on each axis."""
    return [2 * axis + (0 if side > 0 else 1) for axis, side in axes]


def _near_bits(axes):
    """Per child label, bit ``i`` set when the child lies in the half towards the viewer on visible axis ``i``:
    then the child's front face on that axis lies on its parent's front face.
    """
    near = [[octree.CHILD_OFFSETS[label, axis] == (side > 0) for axis, side in axes] for label in range(8)]
    return np.array([sum(1 << i for i, is_near in enumerate(row) if is_near) for row in near], np.uint8)


def _white_leaves_in_front(tree, axes):
    """White leaves with a front face on the boundary of the octree space, found down the front layers."""
    near_bits = _near_bits(axes)
    found, nodes, on_boundary = [], np.zeros(1, np.int64), np.full(1, (1 << len(axes)) - 1, np.uint8)
    while len(nodes):
        leaf = tree.first_child[nodes] < 0
        found.append(nodes[leaf & (tree.color[nodes] == octree.WHITE)])
        children = (tree.first_child[nodes[~leaf]][:, None] + np.arange(8)).ravel()
        on_boundary = (on_boundary[~leaf][:, None] & near_bits).ravel()
        nodes, on_boundary = children[on_boundary != 0], on_boundary[on_boundary != 0]
    return np.concatenate(found)


def seen_from_the_front(tree, axes):
    """What the viewer sees of the empty space, from which every blocking decision follows.

    Returns ``seen``, the white leaves the viewer sees (points 1 and 2 of the module docstring);
    ``faces``, for each black leaf, bit ``i`` set when its front face on visible axis ``i`` touches a seen
    leaf; and ``lit``, the nodes holding a seen leaf or a black leaf with such a face (point 3).

    >>> tree = octree.build(np.array([[[0, 0], [0, 0]], [[0, 0], [0, 1]]], bool))   # voxel (1, 1, 1) black
    >>> seen, faces, lit = seen_from_the_front(tree, visible_axes((-1, -1, -1)))    # seen from the far side
    >>> int(seen.sum()), int(faces[1 + 0]), bool(lit[0])   # seven white voxels; all 3 faces of label 0 open
    (7, 7, True)
    """
    behind = _behind(axes)
    white = tree.white_leaves                               # the search runs on their numbers 0..len - 1
    reached = np.zeros(len(white), bool)
    slot = np.zeros(len(white), np.int64)                   # to keep one of each leaf a wave reaches twice
    wave = np.searchsorted(white, _white_leaves_in_front(tree, axes))
    reached[wave] = True
    while len(wave):                                        # breadth first, one wave of leaves at a time
        found = np.concatenate([tree.white_to_white[direction].neighbours(wave) for direction in behind])
        found = found[~reached[found]]
        slot[found] = np.arange(len(found))
        wave = found[slot[found] == np.arange(len(found))]
        reached[wave] = True
    rows = np.flatnonzero(reached)
    seen = np.zeros(len(tree.color), bool)
    seen[white[rows]] = True
    faces = np.zeros(len(tree.color), np.uint8)
    for i, direction in enumerate(behind):
        faces[tree.white_to_black[direction].neighbours(rows)] |= np.uint8(1 << i)
    lit = seen | (faces != 0)
    for level in range(tree.n, 0, -1):                       # up to the ancestors
        low, high = tree.level_starts[level], tree.level_starts[level + 1]
        lit[tree.parent[low + np.flatnonzero(lit[low:high])]] = True
    return seen, faces, lit


def new_stats():
    """Zhao and Davis's Table II and III counts, zero; both versions of octree-ftb fill them."""
    stats = {f"{c}_{what}": 0 for c in ("white", "black", "grey") for what in ("visited", "blocked")}
    stats.update(black_faces=0, scanlines_accumulated=0, pixels_accumulated=0, pixels_painted=0)
    return stats


def render_octree_ftb(segments, view, progress=None, clip=None, tree=None):
    """Front-to-back octree display with blocking quadtrees (Zhao and Davis), vectorised.

    Parameters
    ----------
    segments : Segments
    view : View
        With ``scale`` set.
    progress : callable, optional
        Unused (the traversal is a few array passes).
    clip : Clip, optional
        Clip limits and cut plane (the octree of the clipped object is built).
    tree : RegionOctree, optional
        The object's region octree (built from ``segments`` when not given).

    Returns
    -------
    depth : ndarray of float32, (H, W)
    stats : dict
        The literal version's (Tables II and III): octants visited and blocked by colour, black faces
        scan-converted, scanlines and pixels accumulated, pixels painted; plus ``white_seen``, the white
        leaves the viewer sees, and ``black_seconds``, the time spent scan-converting black octants' faces.

    Examples
    --------
    >>> from voxrender.object import segments
    >>> from voxrender.space.view import View
    >>> depth, stats = render_octree_ftb(segments.encode(np.ones((4, 4, 4), bool)), View(30, 20, 0, (16, 16), 2.0))
    >>> stats["black_visited"], stats["black_faces"], bool(np.isfinite(depth).any())
    (1, 3, True)
    """
    tree = region_octree(segments, view, clip, tree)
    vpn = vpn_from_angles(view.alpha, view.beta, view.gamma)
    axes = visible_axes(vpn)
    order = np.array(front_to_back_children(vpn))
    height, width = view.size
    image = np.full(height * width, np.inf)
    stats = new_stats()
    seen, faces, lit = seen_from_the_front(tree, axes)
    stats.update(white_seen=int(seen.sum()), black_seconds=0.0)
    near_bits = _near_bits(axes)[order]

    nodes = np.zeros(1, np.int64)                              # one depth of the octree at a time
    on_boundary = np.full(1, (1 << len(axes)) - 1, np.uint8)   # the root's front faces are the boundary
    while len(nodes):
        color = tree.color[nodes]
        face_open = faces[nodes] | on_boundary        # (the faces of black leaves are all that is painted)
        unblocked = lit[nodes] | (face_open != 0)
        for value, name in ((octree.WHITE, "white"), (octree.BLACK, "black"), (octree.GREY, "grey")):
            of_color = color == value
            stats[f"{name}_visited"] += int(of_color.sum())
            stats[f"{name}_blocked"] += int((of_color & ~unblocked).sum())
        black = (color == octree.BLACK) & unblocked
        for i, (axis, side) in enumerate(axes):
            leaves = nodes[black & (face_open & (1 << i) != 0)]
            if len(leaves):
                started = time.perf_counter()
                pixels, depths, _, scanlines = paint_faces(tree, leaves, axis, side, view, segments.shape)
                np.minimum.at(image, pixels, depths)          # the nearest where two faces share an edge
                stats["black_seconds"] += time.perf_counter() - started
                stats["black_faces"] += len(leaves)
                stats["scanlines_accumulated"] += scanlines
                stats["pixels_accumulated"] += len(pixels)
        grey = (color == octree.GREY) & unblocked     # blocked octants are dropped here with their subtrees
        nodes = (tree.first_child[nodes[grey]][:, None] + order).ravel()
        on_boundary = (on_boundary[grey][:, None] & near_bits).ravel()
    stats["pixels_painted"] = int(np.isfinite(image).sum())   # each painted once: un-painted pixels only
    return image.reshape(height, width).astype(np.float32), stats
