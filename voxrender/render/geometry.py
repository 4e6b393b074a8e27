"""Where the ray through a pixel centre meets a box of voxels: the geometry of the view contract.

A run of voxels ``[s, e]`` in row ``(y, z)`` is the box ``[s - 1/2, e + 1/2] x [y - 1/2, y + 1/2] x
[z - 1/2, z + 1/2]``; a voxel is the box of a run of one.  Every renderer paints with these functions,
so that all of them agree with each other and with the contract to the last bit.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["EPS", "footprint", "ray_box_entry", "ray_cube_entry", "box_rows", "row_spans"]

# Pixel centres that fall exactly on a face belong to the (closed) box.
EPS = 1e-9


def footprint(matrix, scale):
    """Half-extents ``(hx, hy)`` in pixels of a unit cube's projection, and the window side in pixels.

    >>> footprint(np.eye(3), 1.0)
    (0.5, 0.5, 2, 2)
    """
    hx = 0.5 * float(np.abs(matrix[0]).sum()) * scale
    hy = 0.5 * float(np.abs(matrix[1]).sum()) * scale
    return hx, hy, int(math.floor(2 * hx)) + 1, int(math.floor(2 * hy)) + 1


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


def ray_cube_entry(dx, dy, matrix):
    """:func:`ray_box_entry` for single voxels."""
    return ray_box_entry(dx, dy, matrix)


def box_rows(yc, half_y, half_z, matrix, scale, height):
    """First and last scanline (pixel row) whose centre ray can meet a box centred at ``Y' = yc``.

    Needs ``matrix[1, 0] == 0`` (alpha and beta only, the paper's Theorem 1), so that ``Y'``
    does not change along object x.

    >>> box_rows(np.array([0.0]), 0.5, 0.5, np.eye(3), 1.0, 4)
    (array([1]), array([2]))
    """
    reach = abs(matrix[1, 1]) * half_y + abs(matrix[1, 2]) * half_z + EPS
    first = np.ceil((yc - reach) * scale + height / 2 - 0.5 - EPS).astype(np.int64)
    last = np.floor((yc + reach) * scale + height / 2 - 0.5 + EPS).astype(np.int64)
    return first, last


def row_spans(dy, xc, half_x, half_y, half_z, matrix, scale, width):
    """First and last pixel column of a box's projection on a scanline ``dy = Y' - Yc`` away from its centre.

    With ``matrix[1, 0] == 0`` a box's projection is the parallelogram of its y and z edges
    swept along the horizontal projection of its x edge (the paper's Fig. 8); on one scanline
    that is an interval, computed here in closed form.  Columns outside ``[0, width)`` are
    clipped; an empty span has ``first > last``.

    >>> row_spans(np.array([0.0]), np.array([0.0]), np.array([1.5]), 0.5, 0.5, np.eye(3), 1.0, 8)
    (array([2]), array([5]))
    """
    # Points of the (y, z) cross-section on the scanline: (a, b) = dy (R11, R12) + t (-R12, R11); X' moves by
    # t * kappa along it.  |a| <= half_y and |b| <= half_z bound t (a 2-D slab test).
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
    spread = np.abs(matrix[0, 0]) * (half_x + EPS)
    left = xc + np.minimum(kappa * low, kappa * high) - spread
    right = xc + np.maximum(kappa * low, kappa * high) + spread
    first = np.ceil(left * scale + width / 2 - 0.5 - EPS).astype(np.int64)
    last = np.floor(right * scale + width / 2 - 0.5 + EPS).astype(np.int64)
    first, last = np.maximum(first, 0), np.minimum(last, width - 1)
    return np.where(empty, 1, first), np.where(empty, 0, last)
