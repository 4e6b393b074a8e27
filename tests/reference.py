"""An independent renderer of the view contract for tests: every pixel's ray against every surface cube.

It shares no code with voxrender: it builds the rotation itself, keeps the voxels that have an empty
(or outside) 26-neighbour (the first cube a ray enters from outside is always one of them), culls
(voxel, pixel) pairs by each cube's bounding sphere, and intersects the ray with the closed cube by
the slab test in object space.  The depth is exact up to rounding, so renderers are held to 1e-5
voxels and identical coverage, except on rays that only touch cubes (ties), which the tests name.
"""

import itertools

import numpy as np

EPS = 1e-9


def rotation(alpha, beta, gamma):
    """``Rz(gamma) Ry(beta) Rx(alpha)``, exact at multiples of 90 degrees (as the contract is)."""
    def cos_sin(degrees):
        if float(degrees) % 90 == 0:
            return [(1, 0), (0, 1), (-1, 0), (0, -1)][int(float(degrees) // 90) % 4]
        return np.cos(np.radians(degrees)), np.sin(np.radians(degrees))

    (ca, sa), (cb, sb), (cg, sg) = (cos_sin(a) for a in (alpha, beta, gamma))
    rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]], float)
    ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]], float)
    rz = np.array([[cg, -sg, 0], [sg, cg, 0], [0, 0, 1]], float)
    return rz @ ry @ rx


def surface(mask):
    """The voxels of ``mask`` with an empty or outside 26-neighbour."""
    padded = np.pad(mask, 1)
    interior = np.ones_like(mask)
    nz, ny, nx = mask.shape
    for dz, dy, dx in itertools.product((0, 1, 2), repeat=3):
        interior &= padded[dz:dz + nz, dy:dy + ny, dx:dx + nx]
    return mask & ~interior


def hits(mask, alpha, beta, gamma, size, scale, voxels=None, chunk=20_000, shrink=0.0, middle=(0.0, 0.0)):
    """``(pixel, entry, exit, voxel index, voxels)`` of every (pixel, cube) pair whose ray meets the closed cube.

    ``voxels`` (an ``(N, 3)`` array of x, y, z) defaults to the surface voxels of ``mask``; ``shrink`` makes
    the cubes smaller by that much on every side (to tell rays through a cube from rays along its surface);
    ``middle`` is the image point at the middle of the picture.
    """
    nz, ny, nx = mask.shape
    height, width = size
    r = rotation(alpha, beta, gamma)
    centre = np.array([(nx - 1) / 2, (ny - 1) / 2, (nz - 1) / 2])
    if voxels is None:
        z, y, x = np.nonzero(surface(mask))
        voxels = np.stack([x, y, z], axis=1)
    radius = 3 ** 0.5 / 2 + EPS
    side = int(np.ceil(2 * radius * scale)) + 1
    found = []
    for start in range(0, len(voxels), chunk):
        p = voxels[start:start + chunk].astype(float)
        image = (p - centre) @ r.T                          # X', Y', Z' of the cube centres
        first_col = np.ceil((image[:, 0] - middle[0] - radius) * scale + width / 2 - 0.5).astype(int)
        first_row = np.ceil((image[:, 1] - middle[1] - radius) * scale + height / 2 - 0.5).astype(int)
        cols = first_col[:, None, None] + np.arange(side)[None, None, :]
        rows = first_row[:, None, None] + np.arange(side)[None, :, None]
        cols, rows = np.broadcast_arrays(cols, rows)
        inside = (cols >= 0) & (cols < width) & (rows >= 0) & (rows < height)
        owner = np.broadcast_to(np.arange(len(p))[:, None, None], cols.shape)[inside]
        cols, rows = cols[inside], rows[inside]
        big_x = (cols + 0.5 - width / 2) / scale + middle[0]
        big_y = (rows + 0.5 - height / 2) / scale + middle[1]
        origin = centre + big_x[:, None] * r[0] + big_y[:, None] * r[1]        # the ray at Z' = 0
        low, high = p[owner] - 0.5 - EPS + shrink, p[owner] + 0.5 + EPS - shrink
        near = np.full(len(owner), -np.inf)
        far = np.full(len(owner), np.inf)
        for k in range(3):
            if abs(r[2, k]) < 1e-12:
                outside = (origin[:, k] < low[:, k]) | (origin[:, k] > high[:, k])
                near[outside] = np.inf
                continue
            t1, t2 = (low[:, k] - origin[:, k]) / r[2, k], (high[:, k] - origin[:, k]) / r[2, k]
            near, far = np.maximum(near, np.minimum(t1, t2)), np.minimum(far, np.maximum(t1, t2))
        met = near <= far
        found.append((rows[met] * width + cols[met], near[met], far[met], owner[met] + start))
    if not found:
        return np.zeros(0, int), np.zeros(0), np.zeros(0), np.zeros(0, int), voxels
    pixels, near, far, owners = (np.concatenate(part) for part in zip(*found, strict=True))
    return pixels, near, far, owners, voxels


def exact(mask, alpha, beta, gamma, size, scale, shrink=0.0, middle=(0.0, 0.0)):
    """The contract's depth image ``(H, W)`` of ``mask[z, y, x]`` (``+inf`` where the ray meets nothing).

    With ``shrink`` (e.g. 1e-6), only cubes that the ray passes through, not along their surface, count.
    """
    pixels, near, _, _, _ = hits(mask, alpha, beta, gamma, size, scale, shrink=shrink, middle=middle)
    depth = np.full(size[0] * size[1], np.inf)
    np.minimum.at(depth, pixels, near)
    return depth.reshape(size)


def ties(mask, alpha, beta, gamma, size, scale, middle=(0.0, 0.0)):
    """Pixels whose ray meets some cube only on its surface (along a face, an edge, or at a corner).

    Such cubes have no depth order along the ray (a ray along the face between two slices is in both), and a
    painter may keep one of them, or a cube behind, where the contract takes the nearest.  Returns a bool image.
    """
    pixels, _, _, owners, voxels = hits(mask, alpha, beta, gamma, size, scale, middle=middle)
    inner, _, _, inner_owners, _ = hits(mask, alpha, beta, gamma, size, scale, voxels=voxels, shrink=1e-6,
                                        middle=middle)
    width = size[1]
    through = set(zip(inner.tolist(), inner_owners.tolist(), strict=True))
    surface_only = np.array([(p, o) not in through
                             for p, o in zip(pixels.tolist(), owners.tolist(), strict=True)], bool)
    tie = np.zeros(size[0] * width, bool)
    tie[pixels[surface_only]] = True
    return tie.reshape(size)


def entries(mask, alpha, beta, gamma, size, scale, middle=(0.0, 0.0)):
    """For each pixel, the entry depths of the surface cubes its ray meets, sorted (a dict pixel -> array)."""
    pixels, near, _, _, _ = hits(mask, alpha, beta, gamma, size, scale, middle=middle)
    order = np.lexsort((near, pixels))
    pixels, near = pixels[order], near[order]
    bounds = np.flatnonzero(np.r_[True, pixels[1:] != pixels[:-1], True])
    return {int(pixels[a]): near[a:b] for a, b in zip(bounds[:-1], bounds[1:], strict=True)}


def agreement(depth, reference, tolerance=1e-5):
    """``(coverage IoU, fraction of co-covered pixels whose depths agree within tolerance)``."""
    a, b = np.isfinite(depth), np.isfinite(reference)
    union = (a | b).sum()
    iou = (a & b).sum() / union if union else 1.0
    both = a & b
    close = np.abs(depth[both] - reference[both]) <= tolerance
    return float(iou), float(close.mean()) if both.any() else 1.0


def exact_labels(labels, alpha, beta, gamma, size, scale, middle=(0.0, 0.0)):
    """The contract's label image ``(H, W)`` of a label map ``labels[z, y, x]``: the label of the cube each ray
    meets first, the smallest of those met at the same depth, 0 where it meets nothing."""
    pixels, near, _, owners, voxels = hits(labels > 0, alpha, beta, gamma, size, scale, middle=middle)
    nearest = np.full(size[0] * size[1], np.inf)
    np.minimum.at(nearest, pixels, near)
    first = near <= nearest[pixels] + 1e-9
    found = np.full(size[0] * size[1], np.iinfo(np.int64).max)
    x, y, z = voxels[owners[first]].T
    np.minimum.at(found, pixels[first], labels[z, y, x].astype(np.int64))
    found[np.isinf(nearest)] = 0
    return found.reshape(size)
