"""What a streamed encode reads of a stack (:mod:`voxrender.object.stream`): how many slices make a slab, the
cropped and binned slices, and the survey that must be made of the whole stack before its first slab.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from . import prep, slabs

SAMPLE_STEP = 7                # every 7th voxel tells whether the values are a binary mask (as encode_volume does)


def slab_slices(stack, cropped, grid, bin, slab_voxels):
    """Grid slices per slab: about ``slab_voxels`` input voxels or grid voxels (a finer grid holds more), and four
    times that for a stack read across its stored slices, which each slab reads whole again.
    """
    if stack.how == "across the stored slices":
        slab_voxels *= 4
    plane = max(cropped[1] * cropped[2] * bin, grid[1] * grid[2], 1)
    return max(1, min(grid[0], slab_voxels // plane))


def survey(stack, region, bin, prepare, slab_voxels):
    """What must be known of the whole stack before its first slab is encoded, as :func:`encode_volume` learns it
    from the whole array: whether it holds only two values (then the normals come from the mask), the lowest value
    (what NaN and inf voxels take for the normals) and Otsu's threshold.  With a threshold given, integers need
    only every 7th slice, and only until a third value is met (a scan's first slab has many: the rest of a cold
    read of a seventh of the stack, 7 s of the 2048³ one's, is saved); Otsu's threshold needs a pass over every
    slice (16-bit integers are counted value by value, which is all it needs), and float values a second one for
    its histogram.
    """
    count = (region[0].stop - region[0].start) // bin
    otsu = prepare.selecting is prep.otsu_threshold and not prepare.tissues
    # the padding of the volume binarize sees: the whole one, or the cropped one binned
    whole = (slice(0, stack.shape[0]), slice(None), slice(None))
    padding = prep.padding_value(_Sampled(stack, *((region, bin) if bin > 1 else (whole, 1)))) if otsu else None
    counted = otsu and stack.dtype.kind in "iu" and stack.dtype.itemsize <= 2 and bin == 1
    sample, low, high, lowest, finite = [], None, None, None, True
    counts = np.zeros(1 << (8 * stack.dtype.itemsize), np.int64) if counted else None
    offset = -int(np.iinfo(stack.dtype).min) if counted else 0
    if otsu or stack.dtype.kind == "f":
        for numbers in _runs(stack, count, bin, region, slab_voxels):
            values = binned_slices(stack, region, bin, numbers)
            sample += [_thinned(plane) for k, plane in zip(numbers, values, strict=True) if k % SAMPLE_STEP == 0]
            if counted:
                for part in slabs.blocks(values, 1 << 23):
                    counts += np.bincount(part.ravel().astype(np.int32) + offset, minlength=len(counts))
                continue
            lo, hi, _ = slabs.kept_range(values, padding)
            if lo is not None:
                low, high = (lo, hi) if low is None else (min(low, lo), max(high, hi))
            least, _, all_finite = slabs.kept_range(values, None)
            finite &= all_finite
            if least is not None:
                lowest = least if lowest is None else min(lowest, least)
    else:                                   # every 7th (binned) slice, a slab's worth of them at a time
        for numbers in _runs(stack, count, bin, region, slab_voxels, SAMPLE_STEP):
            sample += [np.unique(_thinned(plane)) for plane in binned_slices(stack, region, bin, numbers)]
            sample = [np.unique(np.concatenate(sample))]          # the distinct values so far
            if len(sample[0]) > 2:
                break                       # not binary, whatever the rest holds: no need to read it
    threshold = None
    if otsu:
        if counted:                            # the values held, and how often: Otsu's histogram of them
            held = np.flatnonzero(counts) - offset
            kept = held[held != padding] if padding is not None else held
            low, high = (float(kept.min()), float(kept.max())) if len(kept) else (None, None)
        try:
            prep.check_range(low, high, padding)
        except InputError as exc:                      # a constant or all-NaN stack: name it
            raise InputError(f"{stack.meta.get('source', 'the stack')}: {exc.message}", exc.parameter) from None
        edges = prep.otsu_bins(low, high, np.float32 if bin > 1 else stack.dtype)       # binned values: float32
        if counted:
            histogram = np.histogram(kept, bins=edges, weights=counts[kept + offset])[0].astype(np.int64)
        else:
            histogram = np.zeros(len(edges) - 1, np.int64)
            for numbers in _runs(stack, count, bin, region, slab_voxels):
                values = binned_slices(stack, region, bin, numbers)
                for part in slabs.kept_parts(values, padding):
                    histogram += np.histogram(part, bins=edges)[0]
        threshold = prep.otsu_of_histogram(histogram, edges)
    sample = np.concatenate([np.asarray(s).ravel() for s in sample])
    fill = None
    if not finite:
        fill = lowest if lowest is not None else 0.0
        sample = np.where(np.isfinite(sample), sample, fill)
    return {"binary": len(np.unique(sample)) <= 2, "fill": fill, "otsu": threshold}


def _runs(stack, count, bin, region, slab_voxels, step=1):
    """The binned slices ``0 .. count - 1`` (every ``step``-th of them) in runs of as many as a slab holds
    (:func:`_slab_slices`), for a pass over them.
    """
    cropped = tuple(r.stop - r.start for r in region)
    per = slab_slices(stack, cropped, cropped, bin, slab_voxels)
    return [range(first, min(first + per * step, count), step) for first in range(0, count, per * step)]


def _thinned(plane):
    """Every 7th value of every 7th row of a slice, as the binary check samples the volume: a copy, so that the
    slab it is a view of is not kept (the kept views of a 16 GiB stack held 5 GB).
    """
    return plane[::SAMPLE_STEP, ::SAMPLE_STEP].copy()


class _Sampled:
    """The cropped, binned stack seen as a :class:`~voxrender.io.Volume` by :func:`voxrender.object.prep.padding_value`,
    which reads a few of its slices (``values[::step]``).
    """

    ndim = 3

    def __init__(self, stack, region, bin):
        self.stack, self.region, self.bin, self.meta, self.values = stack, region, bin, stack.meta, self
        self.shape = tuple((r.stop - r.start) // bin if r.stop is not None else n
                           for r, n in zip(region, stack.shape, strict=True))

    def __getitem__(self, key):
        return binned_slices(self.stack, self.region, self.bin, range(*key.indices(self.shape[0])))


def binned_slices(stack, region, bin, numbers):
    """The cropped, binned slices ``numbers`` (a range) of the stack: ``bin`` canonical slices each, read in one
    go when they follow one another.
    """
    first = region[0].start + numbers.start * bin
    if numbers.step == 1:
        values = stack.read_slices(first, first + len(numbers) * bin)
    else:
        values = stack.read_numbers([first + k * numbers.step * bin + j for k in range(len(numbers))
                                     for j in range(bin)])
    values = values[:, region[1], region[2]]
    return prep.bin_slices(values, bin) if bin > 1 else values
