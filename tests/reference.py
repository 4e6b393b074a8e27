"""An independent renderer of the view contract for tests: march every pixel's ray in small steps.

It shares no code with voxrender's renderers: it samples the ray densely and
asks the mask which voxel's cube (nearest grid point) holds each sample.
"""

import numpy as np


def rotation(alpha, beta, gamma):
    a, b, g = np.radians([alpha, beta, gamma])
    rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rz = np.array([[np.cos(g), -np.sin(g), 0], [np.sin(g), np.cos(g), 0], [0, 0, 1]])
    return rz @ ry @ rx


def march(mask, alpha, beta, gamma, size, scale, step=0.02):
    """Depth image ``(H, W)`` of ``mask[z, y, x]`` by dense ray marching (``+inf`` where nothing is met)."""
    nz, ny, nx = mask.shape
    height, width = size
    r = rotation(alpha, beta, gamma)
    centre = np.array([(nx - 1) / 2, (ny - 1) / 2, (nz - 1) / 2])
    xs = (np.arange(width) + 0.5 - width / 2) / scale
    ys = (np.arange(height) + 0.5 - height / 2) / scale
    big_x, big_y = np.meshgrid(xs, ys)
    origins = centre + big_x[..., None] * r[0] + big_y[..., None] * r[1]
    reach = 0.5 * np.sqrt(nx * nx + ny * ny + nz * nz) + 1
    depth = np.full((height, width), np.inf)
    for t in np.arange(-reach, reach + step, step):
        points = origins + t * r[2]
        low = np.ceil(points - 0.5 - 1e-9).astype(np.int64)
        high = np.floor(points + 0.5 + 1e-9).astype(np.int64)
        hit = np.zeros((height, width), bool)
        for corner in np.ndindex(2, 2, 2):
            x, y, z = (np.where(corner[k], high[..., k], low[..., k]) for k in range(3))
            inside = (x >= 0) & (x < nx) & (y >= 0) & (y < ny) & (z >= 0) & (z < nz)
            hit[inside] |= mask[z[inside], y[inside], x[inside]]
        newly = hit & ~np.isfinite(depth)
        depth[newly] = t
        if np.isfinite(depth).all():
            break
    return depth


def agreement(depth, reference, tolerance=1.5):
    """``(coverage IoU, fraction of co-covered pixels whose depths agree within tolerance)``."""
    a, b = np.isfinite(depth), np.isfinite(reference)
    union = (a | b).sum()
    iou = (a & b).sum() / union if union else 1.0
    both = a & b
    close = np.abs(depth[both] - reference[both]) <= tolerance
    return float(iou), float(close.mean()) if both.any() else 1.0
