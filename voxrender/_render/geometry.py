"""Where the ray through a pixel centre meets a box of voxels: the geometry of the view contract.

A run of voxels ``[s, e]`` in row ``(y, z)`` is the box ``[s - 1/2, e + 1/2] x [y - 1/2, y + 1/2] x
[z - 1/2, z + 1/2]``; a voxel is the box of a run of one, and an octant's face a box with one half-extent 0.
The mappings between object, image and pixels are the :class:`~voxrender.space.view.View`'s; this module adds
what boxes need: the ray-box entry, the projection of boxes onto pixels (:func:`paint_boxes`) and, for the
dynamic screen, the scanlines and spans a box covers.  Every renderer paints with these functions, so that
all of them agree with each other and with the contract.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

# Pixel centres that fall exactly on a face belong to the (closed) box.
EPS = 1e-9


def reach(matrix, half):
    """Half-extents ``(rx, ry)`` in voxel units of the projection of boxes with half-extents ``half``.

    ``half`` is ``(3,)`` (one box) or ``(N, 3)`` (x, y, z per box).

    >>> reach(np.eye(3), (0.5, 0.5, 0.5))
    (np.float64(0.5), np.float64(0.5))
    """
    half = np.asarray(half, dtype=float)
    return (np.abs(matrix[0]) * half).sum(axis=-1), (np.abs(matrix[1]) * half).sum(axis=-1)


def ray_box_entry(dx, dy, matrix, half_x=0.5, half_y=0.5, half_z=0.5):
    """Depth at which rays enter boxes, relative to each box centre's ``Z'``.

    Parameters
    ----------
    dx, dy : ndarray
        ``X' - Xc`` and ``Y' - Yc``: pixel centre minus box centre in image space (voxel units).
    matrix : (3, 3) ndarray
        The view rotation ``R``.
    half_x, half_y, half_z : float or ndarray
        Half the box's extent along object x, y, z (1/2 for one voxel).

    Returns
    -------
    hit : ndarray of bool
        The ray meets the closed box.
    entry : ndarray of float
        ``Z'`` of the first point of the box on the ray, minus the centre's ``Z'``.

    Examples
    --------
    >>> hit, entry = ray_box_entry(np.array([0.0, 0.7]), np.array([0.0, 0.0]), np.eye(3))
    >>> hit.tolist(), round(float(entry[0]), 6)
    ([True, False], -0.5)
    """
    # In object space the ray is q(t) = dx * R[0] + dy * R[1] + t * R[2]; the box is |q_k| <= half_k.
    direction = np.where(np.abs(matrix[2]) < 1e-12, 1e-12, matrix[2])
    entry = np.full(np.broadcast(dx, dy, half_x).shape, -np.inf)
    leave = np.full_like(entry, np.inf)
    for k, half in enumerate((half_x, half_y, half_z)):
        along = dx * matrix[0, k] + dy * matrix[1, k]
        near = (-half - EPS - along) / direction[k]
        far = (half + EPS - along) / direction[k]
        if direction[k] < 0:
            near, far = far, near
        np.maximum(entry, near, out=entry)
        np.minimum(leave, far, out=leave)
    return entry <= leave, entry


class Fragments(NamedTuple):
    """What :func:`paint_boxes` found: one entry per (pixel, box) whose ray meets the box."""

    pixels: np.ndarray     # flat index into the (H, W) picture
    depths: np.ndarray     # Z' where the pixel's ray enters the box
    owner: np.ndarray      # index of the box
    scanlines: int         # (box, pixel row) pairs with at least one fragment


def paint_boxes(view, shape, x, y, z, half=(0.5, 0.5, 0.5), count_scanlines=False, chunk_pixels=2_000_000):
    """Every pixel whose ray meets one of the boxes, with the depth where it enters the box.

    Parameters
    ----------
    view : View
        With ``scale`` set.
    shape : (nz, ny, nx)
        The volume the boxes live in (its centre is the contract's ``c``).
    x, y, z : ndarray
        Object-space box centres (voxel indices; half-integers for octants of even size).
    half : (3,) or (N, 3) array
        Half-extents along x, y, z: 1/2 for voxels; one of them 0 for octant faces.
    count_scanlines : bool
        Also count the (box, pixel row) pairs with a fragment (Zhao and Davis's scanlines); ``0`` otherwise.
    chunk_pixels : int
        At most about this many candidate pixels are tested at once, to bound memory.

    Returns
    -------
    Fragments
        ``pixels``, ``depths``, ``owner`` (index of the box) and ``scanlines``.

    Examples
    --------
    >>> from voxrender.space.view import View
    >>> found = paint_boxes(View(size=(4, 4), scale=1.0), (1, 1, 1), np.array([0]), np.array([0]), np.array([0]),
    ...                     count_scanlines=True)
    >>> found.pixels.tolist(), found.depths.round(6).tolist(), found.scanlines
    ([5, 6, 9, 10], [-0.5, -0.5, -0.5, -0.5], 2)
    """
    count = int(np.broadcast(x, y, z).size)
    if not count:
        return Fragments(np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.int64), 0)
    matrix = view.matrix
    height, width = view.size
    half = np.asarray(half, dtype=float)
    reach_x, reach_y = (r * view.scale for r in reach(matrix, half))
    kx = int(math.floor(2 * float(np.max(reach_x)))) + 1
    ky = int(math.floor(2 * float(np.max(reach_y)))) + 1
    per_chunk = max(1, chunk_pixels // (kx * ky))
    uniform = half.ndim == 1
    extents = [float(h) for h in half] if uniform else None
    parts, scanlines = [], 0
    for start in range(0, count, per_chunk):
        part = slice(start, start + per_chunk)
        centres = (x, y, z) if count <= per_chunk else (c[part] if np.ndim(c) else c for c in (x, y, z))
        xc, yc, zc = view.to_image(*centres, shape)
        column, row = view.pixel_index(xc, yc)
        rx, ry = (reach_x, reach_y) if uniform else (reach_x[part], reach_y[part])
        i = np.ceil(column - rx - EPS).astype(np.int64)[:, None, None] + np.arange(kx)
        j = np.ceil(row - ry - EPS).astype(np.int64)[:, None, None] + np.arange(ky)[:, None]
        px, py = view.pixel_centres(i, j)
        if not uniform:
            extents = [half[part, k, None, None] for k in range(3)]
        hit, entry = ray_box_entry(px - xc[:, None, None], py - yc[:, None, None], matrix, *extents)
        hit &= (i >= 0) & (i < width) & (j >= 0) & (j < height)
        if count_scanlines:
            scanlines += int(hit.any(axis=2).sum())
        owner = np.nonzero(hit)[0]
        parts.append(((np.broadcast_to(j, hit.shape) * width + np.broadcast_to(i, hit.shape))[hit],
                      (entry + zc[:, None, None])[hit], owner + start if start else owner))
    pixels, depths, owner = (np.concatenate(p) for p in zip(*parts, strict=True)) if len(parts) > 1 else parts[0]
    return Fragments(pixels, depths, owner, scanlines)


def box_rows(yc, half_y, half_z, view):
    """First and last scanline (pixel row) whose centre ray can meet a box centred at ``Y' = yc``.

    Needs ``view.matrix[1, 0] == 0`` (alpha and beta only, the paper's Theorem 1), so that ``Y'``
    does not change along object x.  Rows outside the picture are not clipped.

    >>> from voxrender.space.view import View
    >>> box_rows(np.array([0.0]), 0.5, 0.5, View(size=(4, 4), scale=1.0))
    (array([1]), array([2]))
    """
    matrix = view.matrix
    extent = abs(matrix[1, 1]) * half_y + abs(matrix[1, 2]) * half_z + EPS
    _, top = view.pixel_index(0.0, yc - extent)
    _, bottom = view.pixel_index(0.0, yc + extent)
    return np.ceil(top - EPS).astype(np.int64), np.floor(bottom + EPS).astype(np.int64)


def row_spans(dy, xc, half_x, half_y, half_z, view):
    """First and last pixel column of a box's projection on a scanline ``dy = Y' - Yc`` away from its centre.

    With ``view.matrix[1, 0] == 0`` a box's projection is the parallelogram of its y and z edges
    swept along the horizontal projection of its x edge (the paper's Fig. 8); on one scanline
    that is an interval, computed here in closed form.  Columns outside the picture are
    clipped; an empty span has ``first > last``.  The two halves, :func:`cross_section_reach` (of ``dy``
    alone) and :func:`span_columns`, are apart for boxes that share a cross-section.

    >>> from voxrender.space.view import View
    >>> row_spans(np.array([0.0]), np.array([0.0]), np.array([1.5]), 0.5, 0.5, View(size=(8, 8), scale=1.0))
    (array([2]), array([5]))
    """
    return span_columns(xc, half_x, *cross_section_reach(dy, half_y, half_z, view), view)


def cross_section_reach(dy, half_y, half_z, view):
    """How far left and right of its centre line (``X'`` offsets) a box's (y, z) cross-section reaches on a
    scanline ``dy = Y' - Yc`` away from its centre, and where it does not reach the scanline at all:
    ``(left, right, empty)``, the first half of :func:`row_spans`.
    """
    # Points of the (y, z) cross-section on the scanline: (a, b) = dy (R11, R12) + t (-R12, R11); X' moves by
    # t * kappa along it.  |a| <= half_y and |b| <= half_z bound t (a 2-D slab test).
    matrix = view.matrix
    r11, r12 = matrix[1, 1], matrix[1, 2]
    kappa = matrix[0, 2] * r11 - matrix[0, 1] * r12
    low = np.full(np.shape(dy), -np.inf)
    high = np.full(np.shape(dy), np.inf)
    for centre, slope, half in ((dy * r11, -r12, half_y), (dy * r12, r11, half_z)):
        if abs(slope) < 1e-12:
            outside = np.abs(centre) > half + EPS
            low = np.where(outside, np.inf, low)
            continue
        t1, t2 = (-half - EPS - centre) / slope, (half + EPS - centre) / slope
        low, high = np.maximum(low, np.minimum(t1, t2)), np.minimum(high, np.maximum(t1, t2))
    empty = low > high
    low, high = np.where(empty, 0.0, low), np.where(empty, 0.0, high)
    return np.minimum(kappa * low, kappa * high), np.maximum(kappa * low, kappa * high), empty


def span_columns(xc, half_x, left, right, empty, view):
    """The second half of :func:`row_spans`: first and last pixel column of boxes centred at ``X' = xc`` with
    half-length ``half_x`` along object x whose cross-sections reach ``(left, right, empty)``
    (:func:`cross_section_reach`) on the scanline.
    """
    width = view.size[1]
    spread = np.abs(view.matrix[0, 0]) * (half_x + EPS)
    left, _ = view.pixel_index(xc + left - spread, 0.0)
    right, _ = view.pixel_index(xc + right + spread, 0.0)
    first = np.maximum(np.ceil(left - EPS).astype(np.int64), 0)
    last = np.minimum(np.floor(right + EPS).astype(np.int64), width - 1)
    return np.where(empty, 1, first), np.where(empty, 0, last)
