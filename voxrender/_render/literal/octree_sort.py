"""The sorted linear octree and the z-buffer one voxel at a time.

The oracles of :mod:`voxrender._render.octree_sort`.  They take nothing from the production renderers but the
region octree: the codes are broken into voxels and recoded bit by bit as the paper writes it
(:func:`recode_literal`), sorted with Python's sort, decoded digit by digit, and each voxel's cube is painted
with :mod:`.geometry`.
"""

from __future__ import annotations

import numpy as np

from ...object import octree
from . import geometry
from .octree_btf import literal_tree


def _axes_by_size(vpn):
    """Axes (0 x, 1 y, 2 z) from the largest VPN component to the smallest, ties to the later axis."""
    return sorted(range(3), key=lambda axis: (-abs(vpn[axis]), -axis))


def recode_literal(code, n, vpn):
    """Q -> Q' for one code of ``n`` octal digits, bit by bit as the paper writes it.

    Each digit is the bits L M R (z, y, x); Q' is one bit string per axis, the largest VPN component's
    first, each complemented when its component is negative.

    >>> oct(recode_literal(0o24, 2, (1.0, 1.1, 1.2)))
    '0o30'
    """
    digits = [(code >> (3 * level)) & 7 for level in range(n - 1, -1, -1)]
    bits = {2: [d >> 2 & 1 for d in digits], 1: [d >> 1 & 1 for d in digits], 0: [d & 1 for d in digits]}
    text = ""
    for axis in _axes_by_size(vpn):
        text += "".join(str(1 - b if vpn[axis] < 0 else b) for b in bits[axis])
    return int(text, 2) if text else 0


def _voxel_codes(tree):
    """Every voxel's code, full octants (marker X) broken into their voxels, in code order."""
    codes = []
    for row in octree.linear_octree(tree):
        known = [int(d) for d in row if d != octree.X_MARKER]
        prefix = 0
        for d in known:
            prefix = prefix * 8 + d
        free = tree.n - len(known)
        codes += [(prefix << (3 * free)) + k for k in range(8 ** free)]
    return sorted(codes)


def _decode(code, n):
    """A voxel code to ``(x, y, z)``: each digit adds its child offset at its level."""
    xyz = [0, 0, 0]
    for level in range(n - 1, -1, -1):
        offset = octree.CHILD_OFFSETS[(code >> (3 * level)) & 7]
        xyz = [2 * xyz[k] + int(offset[k]) for k in range(3)]
    return xyz


def _render(segments, view, clip, tree, codes_in_order, keep):
    """Paint the voxels of ``codes_in_order`` one by one; ``keep(old, new)`` decides each write."""
    tree = literal_tree(segments, view, clip, tree)
    r = geometry.rotation(view.alpha, view.beta, view.gamma)
    vpn = geometry.view_plane_normal(r)
    codes = _voxel_codes(tree)
    nz, ny, nx = segments.shape
    centre = ((nx - 1) / 2, (ny - 1) / 2, (nz - 1) / 2)
    height, width = view.size
    image = np.full(height * width, np.inf)
    counts = {"fragments": 0, "writes": 0}
    for code in codes_in_order(codes, tree.n, vpn):
        for row, column, depth in geometry.box_pixels(r, _decode(code, tree.n), (0.5, 0.5, 0.5), centre,
                                                      tuple(view.size), view.scale, tuple(view.centre)):
            pixel = row * width + column
            counts["fragments"] += 1
            if keep(image[pixel], depth):
                image[pixel] = depth
                counts["writes"] += 1
    faces_per_voxel = sum(1 for v in vpn if v != 0)           # Table 3: one face per non-zero component
    stats = {"voxels": len(codes), "linear_octree_codes": int((tree.color == octree.BLACK).sum()),
             "faces": len(codes) * faces_per_voxel, "fragments": counts["fragments"],
             "pixel_writes": counts["writes"]}
    return image.reshape(height, width).astype(np.float32), stats


def render_octree_sort_literal(segments, view, clip=None, order="ftb", tree=None):
    """Codes recoded one by one and sorted by Q'; ``"ftb"``: each pixel keeps its first write, ``"painter"``:
    the reverse order, each write replacing the last.
    """
    def sorted_codes(codes, n, vpn):
        ordered = sorted(codes, key=lambda q: recode_literal(q, n, vpn))
        return ordered[::-1] if order == "painter" else ordered

    return _render(segments, view, clip, tree, sorted_codes,
                   lambda old, new: order == "painter" or not np.isfinite(old))


def render_zbuffer_literal(segments, view, clip=None, tree=None):
    """Voxels in code order, every fragment depth-tested."""
    return _render(segments, view, clip, tree, lambda codes, n, vpn: codes, lambda old, new: new < old)
