"""The geometry of the literal versions: the view contract written out again, one pixel at a time.

The literal, paper-shaped renderers are the test oracles of the vectorised ones, so they must not
share the code they check.  They take nothing from the production geometry
(:mod:`voxrender._render.geometry`, the :class:`~voxrender.space.view.View`'s mappings, :mod:`voxrender._render.clip`):
this module computes the rotation (the dynamic-screen paper's Eq. 2), pixel centres, the span of a box on a
scanline by intersecting the box's projected edges with the scanline (the DDA of the paper's Figs. 8 and 9, in
its exact limit), the ray's entry into a box by the slab test, and the clip limits, in plain Python floats.  A
slip in either geometry then shows as a disagreement.

Boxes are closed: a pixel whose ray touches a box within ``EPS`` (voxel units) meets it, as in the
contract.

>>> r = rotation(90, 0)
>>> [round(v, 6) for v in r[1]]
[0.0, 0.0, -1.0]
"""

from __future__ import annotations

import math

import numpy as np

EPS = 1e-9


def _cos_sin(degrees):
    quarter = float(degrees) / 90
    if quarter == math.floor(quarter):           # exact at multiples of 90 degrees, as the contract is
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[int(quarter) % 4]
    return math.cos(math.radians(degrees)), math.sin(math.radians(degrees))


def rotation(alpha, beta, gamma=0.0):
    """``R = Rz(gamma) Ry(beta) Rx(alpha)`` as three row tuples."""
    (ca, sa), (cb, sb), (cg, sg) = (_cos_sin(a) for a in (alpha, beta, gamma))
    rx = ((1, 0, 0), (0, ca, -sa), (0, sa, ca))
    ry = ((cb, 0, sb), (0, 1, 0), (-sb, 0, cb))
    rz = ((cg, -sg, 0), (sg, cg, 0), (0, 0, 1))

    def product(a, b):
        return tuple(tuple(sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)) for i in range(3))

    return product(rz, product(ry, rx))


def view_plane_normal(r):
    """The unit vector in object space that points at the viewer: ``-R[2]``."""
    return tuple(-v for v in r[2])


def pixel_centre(column, row, size, scale, centre=(0.0, 0.0)):
    """``(X', Y')`` of a pixel centre; ``centre`` is the image point at the middle of the picture."""
    height, width = size
    return (column + 0.5 - width / 2) / scale + centre[0], (row + 0.5 - height / 2) / scale + centre[1]


def to_image(r, point, centre):
    """``R (p - c)`` of one point."""
    d = [point[k] - centre[k] for k in range(3)]
    return tuple(r[i][0] * d[0] + r[i][1] * d[1] + r[i][2] * d[2] for i in range(3))


def ray_entry(r, x, y, box_centre, half, centre):
    """``Z'`` where the ray through image point ``(x, y)`` enters the closed box, or ``None``.

    In object space the ray is ``c + x R[0] + y R[1] + t R[2]``; ``t`` is its ``Z'``.
    """
    near, far = -math.inf, math.inf
    for k in range(3):
        origin = centre[k] + x * r[0][k] + y * r[1][k]
        low, high = box_centre[k] - half[k] - EPS, box_centre[k] + half[k] + EPS
        step = r[2][k]
        if abs(step) < 1e-12:
            if origin < low or origin > high:
                return None
            continue
        t1, t2 = (low - origin) / step, (high - origin) / step
        near, far = max(near, min(t1, t2)), min(far, max(t1, t2))
    return near if near <= far else None


def _corners(box_centre, half):
    return [tuple(box_centre[k] + (s[k] * 2 - 1) * (half[k] + EPS) for k in range(3))
            for s in ((i & 1, (i >> 1) & 1, (i >> 2) & 1) for i in range(8))]


def box_scanlines(r, box_centre, half, centre, size, scale, middle=(0.0, 0.0)):
    """First and last pixel row whose centre's scanline crosses the box's projection (may lie off the picture);
    ``middle`` is the image point at the middle of the picture.
    """
    ys = [to_image(r, corner, centre)[1] - middle[1] for corner in _corners(box_centre, half)]
    height = size[0]
    return (math.ceil(min(ys) * scale + height / 2 - 0.5 - EPS), math.floor(max(ys) * scale + height / 2 - 0.5 + EPS))


def box_scanline_span(r, box_centre, half, centre, y, size, scale, middle=(0.0, 0.0)):
    """Pixel columns ``(first, last)`` of the box's projection on the scanline ``Y' = y`` (``None``: empty).

    The box's 12 edges are projected and intersected with the scanline; the projection's cross-section
    runs from the leftmost to the rightmost crossing (a convex polygon's).  Columns are clipped to the picture.
    """
    corners = [to_image(r, corner, centre) for corner in _corners(box_centre, half)]
    crossings = []
    for a in range(8):
        for k in range(3):
            b = a | (1 << k)
            if b == a:
                continue
            (xa, ya, _), (xb, yb, _) = corners[a], corners[b]
            if min(ya, yb) - EPS <= y <= max(ya, yb) + EPS:
                if abs(yb - ya) < 1e-12:
                    crossings += [xa, xb]
                else:
                    t = min(1.0, max(0.0, (y - ya) / (yb - ya)))
                    crossings.append(xa + t * (xb - xa))
    if not crossings:
        return None
    width = size[1]
    first = max(math.ceil((min(crossings) - middle[0]) * scale + width / 2 - 0.5 - EPS), 0)
    last = min(math.floor((max(crossings) - middle[0]) * scale + width / 2 - 0.5 + EPS), width - 1)
    return (first, last) if first <= last else None


def box_pixels(r, box_centre, half, centre, size, scale, middle=(0.0, 0.0)):
    """``[(row, column, depth), ...]``: every pixel whose ray enters the box, with the entry depth, row by row."""
    first, last = box_scanlines(r, box_centre, half, centre, size, scale, middle)
    found = []
    for row in range(max(first, 0), min(last, size[0] - 1) + 1):
        y = pixel_centre(0, row, size, scale, middle)[1]
        span = box_scanline_span(r, box_centre, half, centre, y, size, scale, middle)
        if span is None:
            continue
        for column in range(max(span[0] - 1, 0), min(span[1] + 1, size[1] - 1) + 1):
            depth = ray_entry(r, pixel_centre(column, row, size, scale, middle)[0], y, box_centre, half, centre)
            if depth is not None:
                found.append((row, column, depth))
    return found


def clip_run(clip, r, z, y, start, end, centre):
    """The part ``(start, end)`` of run ``[start, end]`` of row ``(z, y)`` that the clip keeps, or ``None``,
    voxel by voxel: inside the limits, centre not nearer than the cut depth.
    """
    if clip is None:
        return start, end
    kept = []
    for x in range(int(start), int(end) + 1):
        inside = all(bounds is None or ((bounds[0] is None or v >= bounds[0]) and (bounds[1] is None or v < bounds[1]))
                     for bounds, v in ((clip.x, x), (clip.y, y), (clip.z, z)))
        if inside and clip.cut_depth is not None:
            inside = to_image(r, (x, y, z), centre)[2] >= clip.cut_depth - EPS
        if inside:
            kept.append(x)
    return (kept[0], kept[-1]) if kept else None    # a run's kept voxels are contiguous: Z' is linear in x


def clip_mask(mask, clip, r):
    """``mask[z, y, x]`` without the voxels the clip drops (a new array)."""
    mask = np.array(mask, dtype=bool)
    if clip is None:
        return mask
    nz, ny, nx = mask.shape
    centre = ((nx - 1) / 2, (ny - 1) / 2, (nz - 1) / 2)
    for z, y in zip(*np.nonzero(mask.any(axis=2)), strict=True):
        row = np.flatnonzero(mask[z, y])
        mask[z, y] = False
        for x in row:
            if clip_run(clip, r, int(z), int(y), int(x), int(x), centre) is not None:
                mask[z, y, x] = True
    return mask
