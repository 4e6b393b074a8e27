"""Meagher's back-to-front octree display (the baseline of Zhao and Davis).

The region octree is traversed recursively, the eight children of a grey octant in
back-to-front order (the octant farthest from the viewer first); every black octant's
potentially visible faces (one per axis whose VPN component is not zero, on the side the
VPN points to) are scan-converted into the depth image, each pixel overwritten by
whatever is painted later, i.e. nearer.

A face is scan-converted exactly: every pixel whose ray meets the closed square gets the
depth where the ray meets it.  :func:`render_octree_btf` paints the faces of all black
octants of one size at once and keeps the nearest depth per pixel (the result of painting
back to front); :func:`.literal.octree_btf.render_octree_btf_literal` recurses and paints
face by face (the oracle).  Statistics follow Zhao and Davis's Tables II and III: octants visited by colour,
black faces scan-converted, scanlines and pixels accumulated; the vectorised version also
times its work on black octants (``black_seconds``).
"""

from __future__ import annotations

import time

import numpy as np

from ..object import octree
from ..object.segments import Segments
from ..space.view import vpn_from_angles
from .geometry import paint_boxes


def visible_axes(vpn):
    """The axes with a potentially visible face, and the side (+1 high, -1 low) each face is on."""
    return [(axis, 1 if vpn[axis] > 0 else -1) for axis in range(3) if vpn[axis] != 0]


def front_to_back_children(vpn):
    """Child labels (Table 1 of the linear-octree paper) nearest first: the nearest, then those one,
    two and three halves away.

    >>> front_to_back_children((1, 1, 1))
    [0, 1, 2, 4, 3, 5, 6, 7]
    """
    near = np.array([1 if v > 0 else 0 for v in vpn])
    away = [int(np.sum(octree.CHILD_OFFSETS[label] != near)) for label in range(8)]
    return sorted(range(8), key=lambda label: (away[label], label))


def _face_geometry(tree, nodes, axis, side):
    """Object-space centres and half extents of the given octants' faces on ``axis`` (``side`` +1 or -1)."""
    size = tree.size(nodes).astype(float)
    centre = tree.origin[nodes] + (size[:, None] - 1) / 2          # voxel-index centre of the octant
    centre[:, axis] += side * size / 2
    half = np.repeat(size[:, None] / 2, 3, axis=1)
    half[:, axis] = 0.0
    return centre, half


def paint_faces(tree, nodes, axis, side, view, shape):
    """:func:`~voxrender._render.geometry.paint_boxes` for the faces of ``nodes`` on ``axis`` (``side`` +1 or -1);
    ``owner`` holds node numbers.
    """
    centre, half = _face_geometry(tree, nodes, axis, side)
    found = paint_boxes(view, shape, centre[:, 0], centre[:, 1], centre[:, 2], half, count_scanlines=True)
    return found._replace(owner=np.asarray(nodes)[found.owner])


def region_octree(segments, view, clip=None, tree=None):
    """The region octree to traverse: ``tree`` (the object's, built by the caller and kept), or one built now;
    with active clip limits, the octree of the clipped object.
    """
    if clip is not None and clip.active:
        return octree.build_from_segments(_clipped(segments, view, clip))
    return tree if tree is not None else octree.build_from_segments(segments)


def _clipped(segments, view, clip):
    """The runs of ``segments`` that ``clip`` keeps, cut as it cuts them (:meth:`Clip.apply_runs`): the clipped
    object, made from the runs and not from a mask of the volume.
    """
    rows = segments.run_rows()
    ny = segments.shape[1]
    keep, starts, ends = clip.apply_runs(rows // ny, rows % ny, segments.starts, segments.ends, view, segments.shape)
    offsets = np.zeros(len(segments.offsets), np.int64)
    np.cumsum(np.bincount(rows[keep], minlength=len(offsets) - 1), out=offsets[1:])
    return Segments(segments.shape, starts[keep].astype(np.int32), ends[keep].astype(np.int32), offsets)


def _new_stats(tree):
    return {"white_visited": 0, "black_visited": 0, "grey_visited": 0, "black_faces": 0,
            "scanlines_accumulated": 0, "pixels_accumulated": 0, "pixel_writes": 0}


def render_octree_btf(segments, view, progress=None, clip=None, tree=None):
    """Meagher's back-to-front octree display, vectorised over the black octants of each size.

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
        Tables II and III of Zhao and Davis: ``white_visited``, ``black_visited``, ``grey_visited``,
        ``black_faces``, ``scanlines_accumulated``, ``pixels_accumulated``, ``pixel_writes``, ``black_seconds``.

    Examples
    --------
    >>> from voxrender.object import segments
    >>> from voxrender.space.view import View
    >>> depth, stats = render_octree_btf(segments.encode(np.ones((4, 4, 4), bool)), View(30, 20, 0, (16, 16), 2.0))
    >>> stats["black_visited"], stats["black_faces"], bool(np.isfinite(depth).any())
    (1, 3, True)
    """
    tree = region_octree(segments, view, clip, tree)
    vpn = vpn_from_angles(view.alpha, view.beta, view.gamma)
    height, width = view.size
    image = np.full(height * width, np.inf)
    stats = _new_stats(tree)
    for color, name in ((octree.WHITE, "white"), (octree.BLACK, "black"), (octree.GREY, "grey")):
        stats[f"{name}_visited"] = int((tree.color == color).sum())  # back to front visits every node
    started = time.perf_counter()
    black = np.flatnonzero(tree.color == octree.BLACK)
    for level in np.unique(tree.level[black]):
        nodes = black[tree.level[black] == level]
        for axis, side in visible_axes(vpn):
            pixels, depths, _, scanlines = paint_faces(tree, nodes, axis, side, view, segments.shape)
            np.minimum.at(image, pixels, depths)
            stats["black_faces"] += len(nodes)
            stats["scanlines_accumulated"] += scanlines
            stats["pixels_accumulated"] += len(pixels)
    stats["pixel_writes"] = stats["pixels_accumulated"]
    stats["black_seconds"] = time.perf_counter() - started   # Table II's time in black octants: all of it
    return image.reshape(height, width).astype(np.float32), stats
