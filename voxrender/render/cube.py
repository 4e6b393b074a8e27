"""Where the ray through a pixel centre meets a voxel's cube: the geometry of the view contract.

Every renderer that paints whole voxels uses these two functions, so that they
agree with each other and with the contract to the last bit.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["footprint", "ray_cube_entry"]

# Pixel centres that fall exactly on a cube face belong to the (closed) cube.
EPS = 1e-9


def footprint(matrix, scale):
    """Half-extents ``(hx, hy)`` in pixels of a unit cube's projection, and the window side in pixels.

    >>> footprint(np.eye(3), 1.0)
    (0.5, 0.5, 2, 2)
    """
    hx = 0.5 * float(np.abs(matrix[0]).sum()) * scale
    hy = 0.5 * float(np.abs(matrix[1]).sum()) * scale
    return hx, hy, int(math.floor(2 * hx)) + 1, int(math.floor(2 * hy)) + 1


def ray_cube_entry(dx, dy, matrix):
    """Depth at which rays enter unit cubes, relative to each cube centre's ``Z'``.

    Parameters
    ----------
    dx, dy : ndarray
        ``X' - Xc`` and ``Y' - Yc``: pixel centre minus cube centre in image space (voxel units).
    matrix : (3, 3) ndarray
        The view rotation ``R``.

    Returns
    -------
    hit : ndarray of bool
        The ray meets the closed cube.
    entry : ndarray of float
        ``Z'`` of the first point of the cube on the ray, minus the centre's ``Z'``.

    Examples
    --------
    >>> hit, entry = ray_cube_entry(np.array([0.0, 0.7]), np.array([0.0, 0.0]), np.eye(3))
    >>> hit.tolist(), round(float(entry[0]), 6)
    ([True, False], -0.5)
    """
    # In object space the ray is q(t) = dx * R[0] + dy * R[1] + t * R[2]; the cube is |q_k| <= 1/2.
    direction = np.where(np.abs(matrix[2]) < 1e-12, 1e-12, matrix[2])
    entry = np.full(np.broadcast(dx, dy).shape, -np.inf)
    leave = np.full_like(entry, np.inf)
    for k in range(3):
        along = dx * matrix[0, k] + dy * matrix[1, k]
        near = (-0.5 - EPS - along) / direction[k]
        far = (0.5 + EPS - along) / direction[k]
        if direction[k] < 0:
            near, far = far, near
        np.maximum(entry, near, out=entry)
        np.minimum(leave, far, out=leave)
    return entry <= leave, entry
