"""Back-to-front display (Frieder, Gordon and Reynolds; the dynamic-screen paper's section 2.1).

Slices, rows and voxels are read starting from the corner farthest from the
viewer, and each voxel is painted over whatever is behind it.  A voxel is
painted as the projection of its cube (every pixel whose centre ray meets the
cube), not as one pixel, so no view at any scale has holes; each painted pixel
takes the depth where its ray enters the cube, so the result is the depth image
of the view contract.

:func:`render_btf` paints one slice at a time with array operations: the slice's
voxels are put in back-to-front order and, at every pixel, the last of them to
cover it wins, as if painted one by one; the slice is then painted over the
image.  :func:`~voxrender._render.literal.btf.render_btf_literal` paints voxel by
voxel, as the paper does; it is the test oracle.  Both are painters: the order
decides, and nothing compares depths.

Ties: in back-to-front order a later voxel is never farther along a ray than an earlier one,
except on a ray that only touches two closed cubes on a shared face or edge (pixel centres
exactly on voxel boundaries, in axis-aligned views): such cubes have no depth order, and the
painter keeps the one painted last, which may be the farther.  There the picture differs from
the contract's depth image (which takes the nearer); the tests check those pixels apart.
"""

from __future__ import annotations

import numpy as np

from ..object.segments import expand_runs
from .geometry import paint_boxes


def back_to_front(n, direction):
    """Indices ``0..n-1`` ordered from the farthest to the nearest, for a view direction component.

    >>> back_to_front(3, 0.5).tolist(), back_to_front(3, -0.5).tolist()
    ([2, 1, 0], [0, 1, 2])
    """
    order = np.arange(n)
    return order[::-1] if direction > 0 else order


def _slice_runs(segments, z, view, clip=None):
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
        Clip limits and cut plane (see :mod:`voxrender._render.clip`).

    Returns
    -------
    depth : ndarray of float32, (H, W)
    stats : dict
        ``slices``, ``rows``, ``voxels_projected``, ``pixel_writes``.

    Examples
    --------
    >>> from voxrender.object.segments import encode
    >>> from voxrender.space.view import View
    >>> depth, stats = render_btf(encode(np.ones((2, 2, 2), bool)), View(size=(4, 4), scale=1.0))
    >>> depth[1:3, 1:3].tolist(), stats["voxels_projected"]
    ([[-1.0, -1.0], [-1.0, -1.0]], 8)
    """
    direction = view.matrix[2]
    height, width = view.size
    image = np.full(height * width, np.inf)
    last = np.full(height * width, -1)
    stats = {"slices": 0, "rows": 0, "voxels_projected": 0, "pixel_writes": 0}
    order = back_to_front(segments.shape[0], direction[2])
    for z in (progress(order, len(order), "btf") if progress else order):
        y, x = expand_runs(*_slice_runs(segments, z, view, clip))
        if not len(x):
            continue
        # Rows, and voxels within a row, from the farthest: the order a painter would paint them in.
        painting = np.lexsort((-x if direction[0] > 0 else x, -y if direction[1] > 0 else y))
        pixels, depths, owner, _ = paint_boxes(view, segments.shape, x[painting], y[painting], z)
        np.maximum.at(last, pixels, owner)                # the voxel painted last at each pixel
        wins = owner == last[pixels]
        image[pixels[wins]] = depths[wins]                # painted over whatever earlier slices left
        last[pixels] = -1
        stats["slices"] += 1
        stats["rows"] += len(np.unique(y))
        stats["voxels_projected"] += len(x)
        stats["pixel_writes"] += len(pixels)
    return image.reshape(height, width).astype(np.float32), stats
