"""The slab arithmetic the in-memory and the streaming encode share: a volume a few slices at a time (``blocks``),
the range of its values without NaN, inf and padding (``kept_range``, ``kept_parts``), and its slices resampled to
cubic voxels, one at a time or those of a slab (``resampled_shape``, ``input_slice``, ``resample_slices``).

:mod:`voxrender.object.prep` selects the object with them, :mod:`voxrender.object.stream` slab by slab; both import
them here, so that neither takes the other's private names and a slab gives the slices the whole volume would.
"""

from __future__ import annotations

import math

import numpy as np


def blocks(values, voxels=1 << 24):
    """``values`` a few slices at a time (views)."""
    values = np.atleast_1d(values)
    step = max(1, voxels // max(1, values[0].size))
    return (values[start:start + step] for start in range(0, len(values), step))


def kept_range(values, padding):
    """:func:`value_range`, and whether it left nothing out (then the values are used as they are, uncopied)."""
    if not values.size:
        return None, None, False
    low, high = float(np.min(values)), float(np.max(values))
    if math.isfinite(low) and math.isfinite(high) and (padding is None or not low <= padding <= high):
        return low, high, True
    ranges = [(part.min(), part.max()) for part in kept_parts(values, padding) if part.size]
    if not ranges:
        return None, None, False
    return float(min(lo for lo, _ in ranges)), float(max(hi for _, hi in ranges)), False


def kept_parts(values, padding, voxels=1 << 24):
    """The values of a few slices at a time without their NaN, inf and ``padding`` voxels (each part a copy, so
    that no whole-volume one is made).
    """
    for block in blocks(values, voxels):
        keep = np.isfinite(block) if block.dtype.kind in "fc" else np.ones(block.shape, bool)
        if padding is not None:
            keep &= block != padding
        yield block[keep]


def _grid_count(n, spacing, voxel):
    """How many samples of size ``voxel`` fit between the first and last of ``n`` samples ``spacing`` apart."""
    return int(math.floor((n - 1) * spacing / voxel + 1e-9)) + 1


def resampled_shape(shape, spacing, voxel):
    """Shape ``(nz, ny, nx)`` after resampling to cubic voxels of size ``voxel``.

    Sample ``k`` of the new grid sits at ``k * voxel`` mm from the first sample,
    as far as the last input sample reaches (93 slices 1 mm apart at 0.64 mm give
    the paper's 144).

    >>> resampled_shape((93, 10, 10), (0.64, 0.64, 1.0), 0.64)
    (144, 10, 10)
    """
    return tuple(_grid_count(n, s, voxel) for n, s in zip(shape, spacing[::-1], strict=True))


def input_slice(k, voxel, spacing_z, nz):
    """The input slice ``i`` at or below slice ``k`` of the cubic grid, and the weight of slice ``i + 1``.

    >>> input_slice(3, 0.5, 1.0, 10)
    (1, 0.5)
    """
    position = k * voxel / spacing_z
    i = min(int(math.floor(position + 1e-9)), nz - 1)
    return i, position - i


def resample_slices(values, spacing, voxel, progress=None, ks=None):
    """Yield the slices of ``values`` resampled to cubic voxels of ``voxel`` mm (float32): all of them, or those
    numbered ``ks`` (a range), for which ``values[i]`` is asked only of the slices around them (a slab).

    Linear interpolation: in-plane by :func:`skimage.transform.warp`, across slices
    by blending the two neighbouring slices.  Only two in-plane slices are kept.
    """
    from skimage.transform import AffineTransform, warp

    sx, sy, sz = spacing
    nz, ny, nx = values.shape
    out_z, out_y, out_x = resampled_shape(values.shape, spacing, voxel)
    inplane_same = math.isclose(sx, voxel) and math.isclose(sy, voxel)
    to_input = AffineTransform(scale=(voxel / sx, voxel / sy))
    cache = {}

    def plane(i):
        if i not in cache:
            if len(cache) > 1:
                cache.pop(min(cache))
            data = np.asarray(values[i], dtype=np.float32)
            if not inplane_same:           # a float32 slice may be a read-only map of the file: warp takes no such
                # linear interpolation stays within its inputs: no clip (whose nanmin warns on an all-NaN slice)
                data = warp(np.require(data, requirements="W"), to_input, output_shape=(out_y, out_x), order=1,
                            mode="edge", preserve_range=True, clip=False).astype(np.float32)
            cache[i] = data
        return cache[i]

    ks = range(out_z) if ks is None else ks
    for k in (progress(ks, len(ks), "resampling") if progress else ks):
        i, weight = input_slice(k, voxel, sz, nz)
        if weight < 1e-6 or i == nz - 1:
            yield plane(i)
        else:
            yield (1 - weight) * plane(i) + weight * plane(i + 1)
