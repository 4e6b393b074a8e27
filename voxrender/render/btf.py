"""Back-to-front display (Frieder, Gordon and Reynolds; the dynamic-screen paper's section 2.1).

Slices, rows and voxels are read starting from the corner farthest from the
viewer, and each voxel is painted over whatever is behind it.  A voxel is
painted as the projection of its cube (every pixel whose centre ray meets the
cube), not as one pixel, so no view at any scale has holes; each painted pixel
takes the depth where its ray enters the cube, so the result is the depth image
of the view contract.

:func:`render_btf` paints one slice at a time with array operations: inside one
slice the last voxel painted at a pixel is the nearest one, so the slice's
paint is its per-pixel minimum depth, and that is painted over the image.
:func:`render_btf_literal` paints voxel by voxel, as the paper does; it is the
test oracle.

Ties: in back-to-front order a later voxel is never farther along a ray than an earlier one,
except on a ray that only touches two closed cubes on a shared face or edge (pixel centres
exactly on voxel boundaries, in axis-aligned views): slices side by side have no depth order
there.  Both versions keep the nearer depth when painting, which changes nothing elsewhere and
keeps the contract there (painting over gave the farther voxel on a third of such a view's pixels).
"""

from __future__ import annotations

import numpy as np

from .geometry import EPS, paint_boxes, ray_box_entry, reach

__all__ = ["render_btf", "render_btf_literal", "back_to_front", "expand_runs", "slice_runs"]


def back_to_front(n, direction):
    """Indices ``0..n-1`` ordered from the farthest to the nearest, for a view direction component.

    >>> back_to_front(3, 0.5).tolist(), back_to_front(3, -0.5).tolist()
    ([2, 1, 0], [0, 1, 2])
    """
    order = np.arange(n)
    return order[::-1] if direction > 0 else order


def expand_runs(rows, starts, ends):
    """``(y, x)`` of every voxel of the runs ``[starts, ends]`` of rows ``rows``.

    >>> expand_runs(np.array([0, 3]), np.array([1, 4]), np.array([2, 4]))
    (array([0, 0, 3]), array([1, 2, 4]))
    """
    lengths = ends.astype(np.int64) - starts + 1
    first = np.cumsum(lengths) - lengths
    x = np.repeat(starts.astype(np.int64) - first, lengths) + np.arange(int(lengths.sum()))
    return np.repeat(rows, lengths), x


def slice_runs(segments, z, view, clip=None):
    """``(rows, starts, ends)`` of slice ``z``, clipped when ``clip`` is given."""
    rows, starts, ends = segments.slice(z)
    if clip is not None and clip.active:
        keep, starts, ends = clip.apply_runs(z, rows, starts, ends, view, segments.shape)
        rows, starts, ends = rows[keep], starts[keep], ends[keep]
    return rows, starts, ends


def render_btf(segments, view, progress=None, clip=None):
    """Back-to-front rendering, vectorised over the voxels of each slice.

    Parameters
    ----------
    segments : Segments
    view : View
        With ``scale`` set.
    progress : callable, optional
        ``progress(iterable, length, label)``.
    clip : Clip, optional
        Clip limits and cut plane (see :mod:`voxrender.render.clip`).

    Returns
    -------
    depth : ndarray of float32, (H, W)
    stats : dict
        ``slices``, ``rows``, ``voxels_projected``, ``pixel_writes``.

    Examples
    --------
    >>> from voxrender.segments import encode
    >>> from voxrender.view import View
    >>> depth, stats = render_btf(encode(np.ones((2, 2, 2), bool)), View(size=(4, 4), scale=1.0))
    >>> depth[1:3, 1:3].tolist(), stats["voxels_projected"]
    ([[-1.0, -1.0], [-1.0, -1.0]], 8)
    """
    matrix = view.matrix
    height, width = view.size
    image = np.full(height * width, np.inf)
    buffer = np.full(height * width, np.inf)
    stats = {"slices": 0, "rows": 0, "voxels_projected": 0, "pixel_writes": 0}
    order = back_to_front(segments.shape[0], matrix[2, 2])
    for z in (progress(order, len(order), "btf") if progress else order):
        y, x = expand_runs(*slice_runs(segments, z, view, clip))
        if not len(x):
            continue
        pixels, depths, _, _ = paint_boxes(view, segments.shape, x, y, z)
        np.minimum.at(buffer, pixels, depths)
        image[pixels] = np.minimum(image[pixels], buffer[pixels])   # nearer, or a tie: see the module
        buffer[pixels] = np.inf
        stats["slices"] += 1
        stats["rows"] += len(np.unique(y))
        stats["voxels_projected"] += len(x)
        stats["pixel_writes"] += len(pixels)
    return image.reshape(height, width).astype(np.float32), stats


def render_btf_literal(segments, view, clip=None):
    """Back-to-front rendering one voxel at a time, as the paper describes it (the test oracle).

    Slices, rows within a slice and voxels within a row are visited from the
    farthest to the nearest; each voxel overwrites the pixels its cube covers.
    """
    matrix = view.matrix
    height, width = view.size
    nz, ny, nx = segments.shape
    columns, rows = view.pixel_centres()
    rx, ry = reach(matrix, (0.5, 0.5, 0.5))
    image = np.full((height, width), np.inf)
    stats = {"slices": 0, "rows": 0, "voxels_projected": 0, "pixel_writes": 0}
    for z in back_to_front(nz, matrix[2, 2]):
        slice_has_voxels = False
        for y in back_to_front(ny, matrix[2, 1]):
            starts, ends = segments.row(z, y)
            if clip is not None and clip.active:
                keep, starts, ends = clip.apply_runs(z, y, starts, ends, view, segments.shape)
                starts, ends = starts[keep], ends[keep]
            if not len(starts):
                continue
            slice_has_voxels = True
            stats["rows"] += 1
            voxels = [x for s, e in zip(starts, ends) for x in range(s, e + 1)]
            for x in (reversed(voxels) if matrix[2, 0] > 0 else voxels):
                xc, yc, zc = (float(c) for c in view.to_image(x, y, z, segments.shape))
                stats["voxels_projected"] += 1
                for j in range(height):
                    if abs(rows[j] - yc) > ry + EPS:
                        continue
                    for i in range(width):
                        if abs(columns[i] - xc) > rx + EPS:
                            continue
                        hit, entry = ray_box_entry(columns[i] - xc, rows[j] - yc, matrix)
                        if hit:
                            image[j, i] = min(image[j, i], zc + entry)
                            stats["pixel_writes"] += 1
        stats["slices"] += slice_has_voxels
    return image.astype(np.float32), stats
