"""Display of a linear octree by sorting recoded voxels (Chandran, Gupta and Patgawkar), and the z-buffer.

``octree-sort``: the object's linear octree (Gargantini codes, X for full octants) is
broken into voxels; each voxel code Q is recoded to Q' by a permutation of its bits
chosen from the view plane normal, so that sorting by Q' lists the voxels front to back;
the voxels are then painted in that order, each pixel keeping its first write (or, with
``order="painter"``, in the reverse order, each write replacing the last).

The recoding (the paper's Tables 5 and 6, whose complement bars were lost in the
extracted text, derived here): write each octal digit as bits ``L M R`` (backward, south,
west: z, y and x in their low half).  Q' concatenates one bit string per axis, the axis of
the largest VPN component first; an axis's string holds its bits from the most significant
level down, complemented when the VPN component is negative (the viewer is then on the low
side, so low coordinates must sort first).  For VPN (1.0, 1.1, 1.2) this is
``Q' = L..L M..M R..R`` and for (-2.0, 1.5, 1.0) ``Q' = ~R..R M..M L..L``: Table 2.

``zbuffer``: the same voxels in code order (unsorted), each front face drawn with a
depth test (back faces culled, as the paper's OpenGL comparison did).

A voxel's visible faces (Table 3) cover exactly the projection of its cube, and a pixel
takes the depth where its ray enters the cube, so both give the contract's depth image.
"""

from __future__ import annotations

import numpy as np

from ..object import octree
from ..object.segments import ranges
from ..space.view import vpn_from_angles
from .geometry import paint_boxes
from .octree_btf import region_octree

_AXIS_BIT = {0: 0, 1: 1, 2: 2}  # x -> R (bit 0 of a digit), y -> M (bit 1), z -> L (bit 2)


def _axis_order(vpn):
    """Axes (0 x, 1 y, 2 z) from the largest VPN component to the smallest (ties: z, y, x)."""
    return sorted(range(3), key=lambda axis: (-abs(vpn[axis]), -axis))


def recode(codes, n, vpn):
    """Q -> Q' for voxel codes (integers of ``n`` octal digits), vectorised.

    >>> [oct(q)[2:].zfill(2) for q in recode(np.array([0o00, 0o24, 0o40]), 2, (1.0, 1.1, 1.2))]
    ['00', '30', '40']
    >>> [oct(q)[2:].zfill(2) for q in recode(np.array([0o00, 0o01, 0o24]), 2, (-2.0, 1.5, 1.0))]
    ['60', '40', '71']
    """
    codes = np.asarray(codes, np.int64)
    result = np.zeros_like(codes)
    for axis in _axis_order(vpn):
        bit = _AXIS_BIT[axis]
        string = np.zeros_like(codes)
        for level in range(n - 1, -1, -1):            # digit of weight 8^level, most significant first
            string = (string << 1) | ((codes >> (3 * level + bit)) & 1)
        if vpn[axis] < 0:
            string = ~string & ((1 << n) - 1)
        result = (result << n) | string
    return result


def voxel_codes(tree):
    """The code Q of every voxel of every black octant (full octants broken into voxels), in code order."""
    digits = tree.linear
    prefix = np.zeros(len(digits), np.int64)
    below = np.zeros(len(digits), np.int64)
    for d in range(tree.n):
        is_digit = digits[:, d] != octree.X_MARKER
        prefix = np.where(is_digit, prefix * 8 + digits[:, d], prefix * 8)
        below += ~is_digit
    return ranges(prefix, 8 ** below)


def decode(codes, n):
    """Voxel codes to voxel coordinates ``(x, y, z)``."""
    codes = np.asarray(codes, np.int64)
    xyz = np.zeros((len(codes), 3), np.int64)
    for level in range(n - 1, -1, -1):
        digit = (codes >> (3 * level)) & 7
        xyz = xyz * 2 + octree.CHILD_OFFSETS[digit]
    return xyz


def visible_faces(vpn):
    """Table 3: the faces a voxel shows for a VPN (x, y, z)."""
    names = (("eastern", "western"), ("southern", "northern"), ("front", "back"))
    return [names[axis][0 if vpn[axis] > 0 else 1] for axis in range(3) if vpn[axis] != 0]


def _voxels(segments, view, clip, tree):
    tree = region_octree(segments, view, clip, tree)
    return tree, voxel_codes(tree)


def _candidates(view, shape, xyz):
    """(pixel, depth, voxel index) of every voxel's cube."""
    pixels, depths, owner, _ = paint_boxes(view, shape, *xyz.T)
    return pixels, depths, owner


def _stats(tree, codes, vpn, pixels, written):
    return {"voxels": int(len(codes)), "linear_octree_codes": int((tree.color == octree.BLACK).sum()),
            "faces": int(len(codes) * len(visible_faces(vpn))), "fragments": int(len(pixels)),
            "pixel_writes": int(written)}


def render_octree_sort(segments, view, progress=None, clip=None, order="ftb", tree=None):
    """Sorted linear-octree display, vectorised: recode, ``np.argsort`` on Q', paint in order.

    Parameters
    ----------
    segments : Segments
    view : View
        With ``scale`` set.
    progress : callable, optional
        Unused (the traversal is a few array passes).
    clip : Clip, optional
        Clip limits and cut plane (the octree of the clipped object is built).
    order : {"ftb", "painter"}
        ``"ftb"``: each pixel keeps its first write; ``"painter"``: back to front, each write replaces
        the last (the same picture; only ``pixel_writes`` differs).
    tree : RegionOctree, optional
        The object's region octree (built from ``segments`` when not given).

    Returns
    -------
    depth : ndarray of float32, (H, W)
    stats : dict
        ``voxels``, ``linear_octree_codes``, ``faces`` drawn (Table 3), ``fragments`` (pixel-cube hits) and
        ``pixel_writes``.

    Examples
    --------
    >>> from voxrender.object import segments
    >>> from voxrender.space.view import View
    >>> depth, stats = render_octree_sort(segments.encode(np.ones((2, 2, 2), bool)), View(size=(4, 4), scale=1.0))
    >>> depth[1:3, 1:3].tolist(), stats["voxels"], stats["pixel_writes"]
    ([[-1.0, -1.0], [-1.0, -1.0]], 8, 4)
    """
    tree, codes = _voxels(segments, view, clip, tree)
    vpn = vpn_from_angles(view.alpha, view.beta, view.gamma)
    rank = np.empty(len(codes), np.int64)
    rank[np.argsort(recode(codes, tree.n, vpn), kind="stable")] = np.arange(len(codes))
    shape = tuple(segments.shape)
    pixels, depths, owner = _candidates(view, shape, decode(codes, tree.n))
    height, width = view.size
    first = np.full(height * width, np.iinfo(np.int64).max)
    np.minimum.at(first, pixels, rank[owner])
    winner = rank[owner] == first[pixels]
    image = np.full(height * width, np.inf)
    image[pixels[winner]] = depths[winner]
    written = winner.sum() if order == "ftb" else len(pixels)
    return image.reshape(height, width).astype(np.float32), _stats(tree, codes, vpn, pixels, written)


def render_zbuffer(segments, view, progress=None, clip=None, count_writes=True, tree=None):
    """The unsorted z-buffer with back-face culling, vectorised; ``pixel_writes`` counts depth tests passed.

    Parameters
    ----------
    segments : Segments
    view : View
        With ``scale`` set.
    progress : callable, optional
        Unused (the traversal is a few array passes).
    clip : Clip, optional
        Clip limits and cut plane (the octree of the clipped object is built).
    count_writes : bool
        Counting the passed tests needs a sort of all fragments that the z-buffer itself does not:
        ``False`` skips it (``pixel_writes`` is then ``None``), so that timings compare the z-buffer's own work.
    tree : RegionOctree, optional
        The object's region octree (built from ``segments`` when not given).

    Returns
    -------
    depth : ndarray of float32, (H, W)
    stats : dict
        As :func:`render_octree_sort`'s.

    Examples
    --------
    >>> from voxrender.object import segments
    >>> from voxrender.space.view import View
    >>> depth, stats = render_zbuffer(segments.encode(np.ones((2, 2, 2), bool)), View(size=(4, 4), scale=1.0))
    >>> depth[1:3, 1:3].tolist(), stats["fragments"]
    ([[-1.0, -1.0], [-1.0, -1.0]], 8)
    """
    tree, codes = _voxels(segments, view, clip, tree)
    vpn = vpn_from_angles(view.alpha, view.beta, view.gamma)
    pixels, depths, owner = _candidates(view, tuple(segments.shape), decode(codes, tree.n))
    height, width = view.size
    image = np.full(height * width, np.inf)
    np.minimum.at(image, pixels, depths)
    if not count_writes:
        return image.reshape(height, width).astype(np.float32), dict(_stats(tree, codes, vpn, pixels, 0),
                                                                     pixel_writes=None)
    # A fragment passes when it is nearer than every earlier fragment at its pixel (code order).
    order = np.lexsort((owner, pixels))
    p, key = pixels[order], np.unique(depths, return_inverse=True)[1][order].astype(np.int64)
    group = np.cumsum(np.concatenate([[0], p[1:] != p[:-1]])) if len(p) else p
    shifted = key - group * (len(key) + 1)          # earlier pixels can never lower a later pixel's minimum
    running = np.minimum.accumulate(shifted)
    before = np.concatenate([[np.iinfo(np.int64).max], running[:-1]])
    passes = shifted < before
    return image.reshape(height, width).astype(np.float32), _stats(tree, codes, vpn, pixels, passes.sum())
