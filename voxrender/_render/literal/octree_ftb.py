"""Zhao and Davis's front-to-back octree display with blocking quadtrees, as the paper writes it.

This is the literal, recursive implementation: the oracle for the vectorised version
(:mod:`voxrender._render.octree_ftb`, registered as ``octree-ftb``).  It takes nothing from the
production renderers but the region octree: faces are scan-converted by :mod:`.geometry`.

One blocking quadtree per potentially visible axis (the seven viewing classes XYZ, XY,
XZ, YZ, X, Y, Z are the non-zero components of the VPN), each stored as a *blocking
bitmap*: the complete quadtree of the face plane, all levels, 2 bits a node (W, B, G),
four nodes a byte.  Node ``card`` of depth ``d`` sits at index ``ind_tab[d] + card``
(formula 1), in byte ``index // 4`` at bit ``2 * (index % 4)`` (formula 2); its children
at ``ind_tab[d + 1] + 4 * card + j`` (formula 3); a child octant's face has the cardinal
number ``4 * card + quad_tab[label][axis]`` (formula 4).

``quad_tab`` (the paper's Table I, for our octant labels): the quadrant of the face plane
perpendicular to ``axis`` that child ``label`` projects to, ``2 * high(b) + high(a)`` with
``a < b`` the two other axes.

Ties: a face is scan-converted as the closed square of the view contract (every pixel whose ray
meets it), so a pixel whose ray runs exactly along an edge shared by two faces is reached by both,
which the paper's half-open scanline fill never does.  Such faces need not occlude one another, and
the FTB order may reach the farther first; the nearer depth is then kept (a pixel is still painted
once, as the paper counts).  Without this, axis-aligned views whose pixel centres fall on voxel
boundaries lose the contract on up to a fifth of the pixels.
"""

from __future__ import annotations

import numpy as np

from ...object import octree
from .octree_btf import FaceScan, children_front_to_back, literal_tree, visible_faces

W, B, G = 0, 1, 2


def _quad_tab():
    table = np.zeros((8, 3), np.int64)
    for label in range(8):
        high = octree.CHILD_OFFSETS[label]
        for axis in range(3):
            a, b = [other for other in range(3) if other != axis]
            table[label, axis] = 2 * high[b] + high[a]
    return table


QUAD_TAB = _quad_tab()


def ind_tab(depth):
    """Index of the first node of ``depth`` in a complete quadtree stored level by level: (4^d - 1) / 3.

    >>> [ind_tab(d) for d in range(4)]
    [0, 1, 5, 21]
    """
    return (4 ** depth - 1) // 3


class BlockingBitmap:
    """A complete quadtree of ``n + 1`` levels, 2 bits a node, initially all white.

    Three of them take ``(4^(n+1) - 1) / 3 * 3 * 2 / 8``, about ``4^n`` bytes: 64 KB for a 256^3 octree,
    as the paper says.

    >>> 3 * len(BlockingBitmap(8).bits), 4 ** 8
    (65538, 65536)
    """

    def __init__(self, n):
        self.nodes = ind_tab(n + 1)
        self.bits = bytearray((self.nodes + 3) // 4)

    def get(self, index):
        return (self.bits[index >> 2] >> (2 * (index & 3))) & 3

    def set(self, index, color):
        shift = 2 * (index & 3)
        self.bits[index >> 2] = (self.bits[index >> 2] & ~(3 << shift) & 0xFF) | (color << shift)


def render_octree_ftb_literal(segments, view, clip=None, arrivals=None, tree=None):
    """Front-to-back octree display with blocking bitmaps (Zhao and Davis, Sec. 4), recursively.

    Returns the depth image and Table II/III statistics: octants visited and blocked by
    colour, black faces scan-converted, scanlines and pixels accumulated, pixels painted.
    ``arrivals``, a dict, receives for every visited node the bitmap value per axis it found.
    """
    tree = literal_tree(segments, view, clip, tree)
    scan = FaceScan(tree, view, segments.shape)
    vpn = scan.vpn()
    axes = visible_faces(vpn)
    order = children_front_to_back(vpn)
    height, width = view.size
    image = np.full(height * width, np.inf)
    stats = {f"{c}_{what}": 0 for c in ("white", "black", "grey") for what in ("visited", "blocked")}
    stats.update(black_faces=0, scanlines_accumulated=0, pixels_accumulated=0, pixels_painted=0)
    bitmaps = {axis: BlockingBitmap(tree.n) for axis, _ in axes}
    stats["bitmap_bytes"] = sum(len(b.bits) for b in bitmaps.values())

    def scan_convert(node, axis, side):
        pixels, scanlines = scan.face(node, axis, side)
        stats["black_faces"] += 1
        stats["scanlines_accumulated"] += scanlines
        stats["pixels_accumulated"] += len(pixels)
        for pixel, depth in pixels:
            if not np.isfinite(image[pixel]):          # fill un-painted pixels
                image[pixel] = depth
                stats["pixels_painted"] += 1
            elif depth < image[pixel]:                 # a ray along an edge that two faces share: see the module
                image[pixel] = depth

    def record(node, index):
        if arrivals is not None:
            arrivals[node] = {axis: bitmaps[axis].get(index[axis]) for axis, _ in axes}

    def process_white_or_black(node, depth, card):
        color = int(tree.color[node])
        name = "black" if color == octree.BLACK else "white"
        stats[f"{name}_visited"] += 1
        index = {axis: ind_tab(depth) + card[axis] for axis, _ in axes}
        record(node, index)
        if all(bitmaps[axis].get(index[axis]) == B for axis, _ in axes):
            stats[f"{name}_blocked"] += 1
            return
        if color == octree.BLACK:
            for axis, side in axes:
                if bitmaps[axis].get(index[axis]) != B:
                    scan_convert(node, axis, side)
        for axis, _ in axes:
            bitmaps[axis].set(index[axis], B if color == octree.BLACK else W)

    def process_grey(node, depth, card):
        stats["grey_visited"] += 1
        index = {axis: ind_tab(depth) + card[axis] for axis, _ in axes}
        record(node, index)
        if all(bitmaps[axis].get(index[axis]) == B for axis, _ in axes):
            stats["grey_blocked"] += 1            # discarded with all its descendants
            return
        for axis, _ in axes:                       # refine
            color = bitmaps[axis].get(index[axis])
            if color != G:
                for j in range(4):
                    bitmaps[axis].set(ind_tab(depth + 1) + 4 * card[axis] + j, color)
                bitmaps[axis].set(index[axis], G)
        for label in order:
            child = int(tree.first_child[node]) + label
            child_card = {axis: 4 * card[axis] + int(QUAD_TAB[label, axis]) for axis, _ in axes}
            if tree.color[child] == octree.GREY:
                process_grey(child, depth + 1, child_card)
            else:
                process_white_or_black(child, depth + 1, child_card)
        for axis, _ in axes:                       # compact
            first = ind_tab(depth + 1) + 4 * card[axis]
            if all(bitmaps[axis].get(first + j) == B for j in range(4)):
                bitmaps[axis].set(index[axis], B)

    root = int(tree.color[0])
    if root == octree.BLACK:
        stats["black_visited"] += 1
        for axis, side in axes:
            scan_convert(0, axis, side)
    elif root == octree.GREY:
        process_grey(0, 0, {axis: 0 for axis, _ in axes})
    else:
        stats["white_visited"] += 1
    return image.reshape(height, width).astype(np.float32), stats
