"""Encoding a stack larger than memory: its slices streamed into runs, a slab at a time.

The dynamic-screen paper stores its objects as slices read in order (its section 5); so does this encoder.  The
stack (:func:`voxrender.io.open_stack`) is read a slab of slices at a time in canonical z order; each slab is
cropped, binned, resampled to cubic voxels and thresholded (with the few slices beside it that resampling and the
normals' stencil reach), and its runs, labels and grey-level normals are appended to files beside the output.  The
``.vxs`` is then written from those files.  Nothing of the size of the volume is ever held, and the file is the
one :func:`voxrender.object.pipeline.load_segments` and :meth:`~voxrender.object.pipeline.Encoded.save` would write for
the same input, byte for byte: every step is local to a few slices, and done in the same arithmetic.

The slabs are independent, so the stack is cut into parts that worker processes (``jobs``) or a Dask cluster
(``scheduler``) encode, each reading its own slices from the shared path; the parts are joined in order.
"""

from __future__ import annotations

import contextlib
import errno
import math
import os
import shutil
import tempfile
import time
import uuid
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .. import io
from .._shared.memory import keep_freed_memory, memory_reused
from ..errors import InputError
from . import prep, segments, slabs, vxs
from .normals import stencil_radius, surface_normals
from .pipeline import (
    PrepOptions,
    ReadOptions,
    grey_sampler,
    grid_step,
    load_segments,
    machine_memory,
    on_input_grid,
    source_meta,
)

SLAB_VOXELS = 1 << 26          # input voxels read at a time (128 MB of 16-bit slices)
NORMAL_VOXELS = 1 << 24        # grid voxels whose band's normals are found at a time (their stencils are large)
SAMPLE_STEP = 7                # every 7th voxel tells whether the values are a binary mask (as encode_volume does)
WORKER_SLABS = 8               # the memory a worker holds, in slabs of input: 4 measured (a slab's grey values,
                               # layers, band, gradients), and room


class ByteCounts(list):
    """Progress items that are byte counts: a progress bar shows them as MB read, MB/s and the time left."""


@dataclass(frozen=True)
class Plan:
    """What every part of a streamed encode needs: where the stack is, how it is read, and the grid and selection
    of the object.  Picklable, so that a worker process or a Dask worker can encode its part.
    """

    source: str
    read: ReadOptions
    token: str              # this encode's: a worker that stays (Dask) opens the stack again for the next one
    region: tuple           # (z, y, x) slices of the canonical stack: the crop
    bin: int
    windows: tuple          # prep.Interval each: the object (one) or its tissues, numbered 1, 2, ...
    grid: tuple             # the object's grid (nz, ny, nx)
    voxel: float
    binned_spacing: tuple   # of the cropped, binned input
    resampled: bool
    on_grid: bool           # the normals take the grey values of the grid's own voxels (pipeline.on_input_grid)
    normals_from: str       # "grey values" or "the binary mask"
    fill: float | None      # the value NaN and inf voxels take for the normals (the lowest), when there are any
    slab: int               # grid slices per slab
    spool: str | None = None   # a raw file of the stored slices, inflated once (compressed, not in stored order)


def encode_stack(path, output, read=None, prepare=None, *, jobs=1, scheduler=None, progress=None,
                 slab_voxels=SLAB_VOXELS):
    """Encode the stack at ``path`` into the ``.vxs`` file ``output`` a slab at a time, in bounded memory.

    Parameters
    ----------
    path : str or Path
        A slice stack whose reader reads slabs (:func:`voxrender.io.open_stack`).
    output : str or Path
        The ``.vxs`` file to write (atomically; the parts are made beside it and removed).
    read : ReadOptions, optional
    prepare : PrepOptions, optional
        A threshold, window or tissues (presets) select the object, with the crop, binning and cubic voxels, as
        for :func:`voxrender.object.pipeline.load_segments`; ``min_object`` and label maps need the whole volume and are
        refused.
    jobs : int
        Worker processes encoding parts of the stack at once.
    scheduler : str, optional
        A Dask scheduler's address (or ``"local"``) to encode the parts on.
    progress : callable, optional
        ``progress(iterable, length, label)``; its items are :class:`ByteCounts`, the bytes read.
    slab_voxels : int
        Input voxels read at a time (smaller: less memory).

    Returns
    -------
    dict
        ``shape``, ``spacing``, ``meta``, ``segment_count``, ``voxel_count``, ``normal_count`` and ``how`` (how
        the stack was read: :class:`voxrender.io._stack.Canonical`).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> np.save(folder / "v.npy", np.pad(np.full((2, 2, 2), 100, np.int16), 1))
    >>> encode_stack(folder / "v.npy", folder / "v.vxs", prepare=PrepOptions(threshold=50))["voxel_count"]
    8
    """
    read = read or ReadOptions()
    prepare = prepare or PrepOptions()
    if prepare.labels is not None:
        raise InputError("a label map is read whole; select the object by a threshold, a window or tissues to "
                         "stream the stack", parameter="labels")
    if prepare.min_object > 1:
        raise InputError("removing small pieces needs the whole object at once; drop it to stream the stack",
                         parameter="min_object")
    output = Path(output)
    token = uuid.uuid4().hex
    stack = _open(str(path), read, token)
    folder = Path(tempfile.mkdtemp(prefix=f".{output.name}.parts-", dir=output.parent))
    try:
        with room_for(output):
            spool = None
            if stack.stack.sequential and stack.how != "stored order":
                spool = str(folder / "stack.raw")
                _spool(stack.stack, spool, progress)
                stack = _open(str(path), read, token, spool)
            plan, meta = _plan(stack, str(path), read, prepare, slab_voxels, token, spool)
            parts = [(a, min(a + plan.slab, plan.grid[0])) for a in range(0, plan.grid[0], plan.slab)]  # a slab each
            results = _run(plan, parts, folder, jobs, scheduler, progress, stack)
            counts = np.concatenate([r["rows"] for r in results])
            if not counts.any():
                raise InputError(f"the {'windows' if len(plan.windows) > 1 else 'threshold'} "
                                 f"{', '.join(w.words() for w in plan.windows)} holds no voxel of {meta['source']}; "
                                 "choose a threshold or window within its values (info tells them)",
                                 parameter="preset" if prepare.tissues else "threshold")
            written = _write(output, plan, meta, prepare, results, counts)
        return written | {"how": stack.how + " (inflated once)" * bool(spool)}
    finally:
        shutil.rmtree(folder, ignore_errors=True)
        _STACKS.clear()


# ------------------------------------------------------------------ the plan

_STACKS = {}        # the stack each process has open, by source: a worker encodes several parts of one


def _open(source, read, token=None, spool=None):
    """The stack at ``source`` in the canonical frame, unread, kept for the encode ``token`` names; with
    ``spool``, its stored slices read from that raw file (:func:`_spool`) instead of its own.
    """
    key = (source, read, token, spool)
    if key not in _STACKS:
        _STACKS.clear()
        stack = stack_of(source, read)
        if spool:
            stored = stack.stack

            def read_slices(z0, z1):
                return io.slices_at(spool, 0, stored.shape, stored.dtype, z0, z1)

            stack.stack = replace(stored, read_slices=read_slices, sequential=False)
        _STACKS[key] = stack
    return _STACKS[key]


def _spool(stored, path, progress, slab_bytes=SLAB_VOXELS * 2):
    """Write the stored slices of a compressed stack, inflated in one pass, into the raw file ``path``: read from
    the far end or across its slices, each slab would inflate the stream again from its start.
    """
    per = max(1, slab_bytes // max(1, stored.nbytes // stored.shape[0]))
    starts = range(0, stored.shape[0], per)
    sizes = ByteCounts(stored.stored_bytes * min(per, stored.shape[0] - z) // stored.shape[0] for z in starts)
    with open(path, "wb") as f:
        for z, _ in zip(starts, progress(sizes, sum(sizes), "inflating") if progress else sizes, strict=True):
            f.write(np.ascontiguousarray(stored.read_slices(z, min(z + per, stored.shape[0]))).data)


def _plan(stack, source, read, prepare, slab_voxels, token, spool=None):
    """The :class:`Plan` of a stack and the meta its object will have (as :func:`encode_volume` makes it)."""
    bin = prepare.bin
    prep.crop(np.broadcast_to(np.zeros(1, np.int8), stack.shape), prepare.crop)         # checks the crop
    region = tuple(slice(r.start or 0, r.stop if r.stop is not None else n)
                   for r, n in zip(prepare.crop or (slice(None),) * 3, stack.shape, strict=True))
    cropped = tuple(r.stop - r.start for r in region)
    prep.check_bin(bin, cropped)
    shape, spacing, voxel, grid, resampled = _grid(cropped, stack.spacing, prepare)
    survey = _survey(stack, region, bin, prepare, slab_voxels)
    if prepare.tissues:
        windows = tuple(window for _, window, _ in prepare.tissues)
        threshold = ", ".join(str(w) for w in windows)
    else:
        found = prepare.selecting
        if found is prep.otsu_threshold:
            found = survey["otsu"]
        elif callable(found):
            raise InputError("a threshold found by a function needs the whole volume; give a number or a window "
                             "to stream the stack", parameter="threshold")
        windows = (found if isinstance(found, prep.Interval) else prep.Interval(float(found)),)
        threshold = str(found) if isinstance(found, prep.Interval) else windows[0].lo
    slab = _slab_slices(stack, cropped, grid, bin, slab_voxels)
    step = grid_step(spacing, voxel, prepare.resample)
    plan = Plan(source, read, token, region, bin, windows, grid, voxel, spacing, resampled,
                on_input_grid(step, shape, grid), "the binary mask" if survey["binary"] else "grey values",
                survey["fill"], slab, spool)
    meta = source_meta(stack, source)
    if bin > 1:
        meta["binned"] = bin
    meta.update(threshold=threshold, voxel_mm=voxel)
    return plan, meta


def _grid(cropped, spacing, prepare):
    """The cropped input's shape after binning, its spacing, and the object's cubic voxel, grid and whether it
    is resampled (:func:`voxrender.object.prep.cubic_grid`).
    """
    shape = tuple(n // prepare.bin for n in cropped)
    spacing = tuple(float(s) * prepare.bin for s in spacing)
    voxel, out_shape = prep.cubic_grid(shape, spacing, prepare.voxel, prepare.resample)
    return shape, spacing, voxel, out_shape or shape, out_shape is not None


def _slab_slices(stack, cropped, grid, bin, slab_voxels):
    """Grid slices per slab: about ``slab_voxels`` input voxels or grid voxels (a finer grid holds more), and four
    times that for a stack read across its stored slices, which each slab reads whole again.
    """
    if stack.how == "across the stored slices":
        slab_voxels *= 4
    plane = max(cropped[1] * cropped[2] * bin, grid[1] * grid[2], 1)
    return max(1, min(grid[0], slab_voxels // plane))


def _survey(stack, region, bin, prepare, slab_voxels=SLAB_VOXELS):
    """What must be known of the whole stack before its first slab is encoded, as :func:`encode_volume` learns it
    from the whole array: whether it holds only two values (then the normals come from the mask), the lowest value
    (what NaN and inf voxels take for the normals) and Otsu's threshold.  With a threshold given, integers need
    only every 7th slice, and only until a third value is met (a scan's first slab has many: the rest of a cold
    read of a seventh of the stack, 7 s of the 2048³ one's, is saved); Otsu's threshold needs a pass over every
    slice (16-bit integers are counted value by value, which is all it needs), and float values a second one for
    its histogram.
    """
    binned_slices = (region[0].stop - region[0].start) // bin
    otsu = prepare.selecting is prep.otsu_threshold and not prepare.tissues
    # the padding of the volume binarize sees: the whole one, or the cropped one binned
    whole = (slice(0, stack.shape[0]), slice(None), slice(None))
    padding = prep.padding_value(_Sampled(stack, *((region, bin) if bin > 1 else (whole, 1)))) if otsu else None
    counted = otsu and stack.dtype.kind in "iu" and stack.dtype.itemsize <= 2 and bin == 1
    sample, low, high, lowest, finite = [], None, None, None, True
    counts = np.zeros(1 << (8 * stack.dtype.itemsize), np.int64) if counted else None
    offset = -int(np.iinfo(stack.dtype).min) if counted else 0
    if otsu or stack.dtype.kind == "f":
        for numbers in _runs(stack, binned_slices, bin, region, slab_voxels):
            values = _binned(stack, region, bin, numbers)
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
        for numbers in _runs(stack, binned_slices, bin, region, slab_voxels, SAMPLE_STEP):
            sample += [np.unique(_thinned(plane)) for plane in _binned(stack, region, bin, numbers)]
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
            for numbers in _runs(stack, binned_slices, bin, region, slab_voxels):
                values = _binned(stack, region, bin, numbers)
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
    per = _slab_slices(stack, cropped, cropped, bin, slab_voxels)
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
        return _binned(self.stack, self.region, self.bin, range(*key.indices(self.shape[0])))


def _binned(stack, region, bin, numbers):
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


# ------------------------------------------------------------------ the parts

def _run(plan, parts, folder, jobs, scheduler, progress, stack):
    """Encode the parts, in this process or on workers; their results in order."""
    from .._shared.executors import executor

    # about the bytes each part reads: its share of the crop's slices
    read = stack.stored_bytes * (plan.region[0].stop - plan.region[0].start) / stack.shape[0]
    sizes = ByteCounts(int(read * (b - a) / plan.grid[0]) for a, b in parts)
    ticks = iter(progress(sizes, sum(sizes), "encoding") if progress else sizes)
    next(ticks, None)                                         # the bar and its clock start
    if jobs <= 1 and not scheduler:
        results = []
        with memory_reused():
            for part in parts:
                results.append(encode_part(plan, *part, str(folder)))
                next(ticks, None)                             # a part done: the bar moves by its bytes
        return results
    pool = executor(jobs, scheduler)
    try:
        futures = {pool.submit(encode_part, plan, a, b, str(folder)): n for n, (a, b) in enumerate(parts)}
        results = [None] * len(parts)
        for future in pool.as_completed(list(futures)):      # as they end on the workers
            results[futures[future]] = future.result()
            next(ticks, None)
        return results
    finally:
        pool.close()


def encode_part(plan, first, last, folder):
    """Encode the grid's slices ``first .. last - 1`` of a :class:`Plan`, a slab at a time, into files in
    ``folder``: their runs, labels and normals.  Returns the runs each row has and the files.
    """
    stack = _open(plan.source, plan.read, plan.token, plan.spool)
    names = ("starts", "ends", "labels", "normal_index", "normal_packed")
    files = {name: Path(folder) / f"{first:08d}.{name}" for name in names}
    rows, normal_count = [], 0
    keep_freed_memory()                 # a worker's slabs reuse the pages of the last (ended by _run in this process)
    with _Appender(files) as out:
        for a in range(first, last, plan.slab):
            b = min(a + plan.slab, last)
            layers, grey, grey_first, mask_first = _slab(plan, stack, a, b)
            own = layers[a - mask_first:b - mask_first]
            if len(plan.windows) > 1:
                runs = segments.encode_labels(own)
                out.add(labels=np.asarray(runs.labels, "<u2"))
            else:
                runs = segments.encode(own.view(bool))
            rows.append(np.diff(runs.offsets))
            out.add(starts=np.asarray(runs.starts, "<i4"), ends=np.asarray(runs.ends, "<i4"))
            for index, packed in _normals(plan, layers, grey, grey_first, mask_first, a, b):
                out.add(normal_index=index, normal_packed=packed)
                normal_count += len(index)
    return {"first": first, "rows": np.concatenate(rows), "files": {k: str(v) for k, v in files.items()},
            "normals": normal_count}


def _slab(plan, stack, a, b):
    """The object's grid slices ``a .. b - 1`` with those beside them that the normals' stencil reaches, as
    window numbers (uint8 layers), and the grey values they come from: ``(layers, grey, grey_first,
    mask_first)``, the last two being the input (binned) slice and the grid slice the arrays begin at.
    """
    halo = stencil_radius(plan.normals_from)             # the band needs one slice beside it, the stencil more
    mask_first, mask_last = max(0, a - halo), min(plan.grid[0], b + halo)
    nz = (plan.region[0].stop - plan.region[0].start) // plan.bin
    if plan.resampled:
        # the input slices the layers blend, and those the normals' B-spline reaches (grey_sampler), with room
        lo = slabs.input_slice(max(0, mask_first - 1), plan.voxel, plan.binned_spacing[2], nz)[0]
        hi = slabs.input_slice(min(plan.grid[0] - 1, mask_last), plan.voxel, plan.binned_spacing[2], nz)[0]
        grey_first, grey_last = max(0, lo - 2), min(nz, hi + 4)
    else:
        grey_first, grey_last = mask_first, mask_last
    grey = _binned(stack, plan.region, plan.bin, range(grey_first, grey_last))
    if plan.resampled:
        shifted = _Shifted(grey, grey_first, nz)
        planes = slabs.resample_slices(shifted, plan.binned_spacing, plan.voxel, ks=range(mask_first, mask_last))
    else:
        planes = grey
    layers = np.empty((mask_last - mask_first,) + plan.grid[1:], np.uint8)
    for layer, plane in zip(layers, planes, strict=True):
        prep.select_layer(plane, plan.windows, layer)
    if plan.fill is not None:                       # NaN and inf take the lowest value, for the normals
        grey = np.where(np.isfinite(grey), grey, grey.dtype.type(plan.fill))
    return layers, grey, grey_first, mask_first


class _Shifted:
    """Slices of the binned input from ``first`` on, indexed as the whole input's (for the resampler)."""

    def __init__(self, values, first, nz):
        self.values, self.first = values, first
        self.shape = (nz,) + values.shape[1:]

    def __getitem__(self, i):
        return self.values[i - self.first]


def _normals(plan, layers, grey, grey_first, mask_first, a, b):
    """The normals of the grid's slices ``a .. b - 1``, a few slices at a time: ``(index, packed)`` each."""
    mask = layers.view(bool) if len(plan.windows) == 1 else layers > 0
    binary = plan.normals_from == "the binary mask"
    per = max(1, NORMAL_VOXELS // max(1, plan.grid[1] * plan.grid[2]))
    for first in range(a, b, per):
        last = min(first + per, b)
        own = (first - mask_first, last - mask_first)
        if binary:
            found = surface_normals(mask, own=own, offset=mask_first, shape=plan.grid)
        elif plan.on_grid:                  # the grid's own voxels, beside its mask's
            on_mask = grey[mask_first - grey_first:mask_first - grey_first + len(mask)]
            found = surface_normals(mask, on_mask, own=own, offset=mask_first, shape=plan.grid)
        else:
            sample = grey_sampler(grey, grid_step(plan.binned_spacing, plan.voxel), mask_first, grey_first)
            found = surface_normals(mask, sample, own=own, offset=mask_first, shape=plan.grid)
        index = np.asarray(found.index)
        yield np.asarray(index, f"<i{index.dtype.itemsize}"), np.asarray(found.packed, "<i2").ravel()


class _Appender:
    """Files that arrays are appended to, one per name (created empty)."""

    def __init__(self, files):
        self.files = files

    def __enter__(self):
        self.handles = {name: open(path, "wb") for name, path in self.files.items()}
        return self

    def add(self, **arrays):
        for name, array in arrays.items():
            self.handles[name].write(np.ascontiguousarray(array).data)

    def __exit__(self, *exc):
        for handle in self.handles.values():
            handle.close()


# ------------------------------------------------------------------ the file

def _write(output, plan, meta, prepare, results, counts):
    """Write the ``.vxs`` of the parts' files: as :func:`voxrender.object.vxs.save` writes the object in memory."""
    offsets = np.zeros(len(counts) + 1, "<i8")
    np.cumsum(counts, out=offsets[1:])
    total = int(offsets[-1])
    size = math.prod(plan.grid)
    index_type = np.dtype("<i4" if size < 2 ** 30 else "<i8")
    normals = sum(r["normals"] for r in results)

    def spilled(name, dtype, count):
        return vxs.Spilled(tuple(r["files"][name] for r in results), count, np.dtype(dtype))

    arrays = {"offsets": offsets, "starts": spilled("starts", "<i4", total), "ends": spilled("ends", "<i4", total)}
    meta = dict(meta)
    if len(plan.windows) > 1:
        arrays["labels"] = spilled("labels", "<u2", total)
        present = _labels_present(arrays["labels"])
        meta.update(labels=present, label_table={
            str(k): {"name": name, "colour": list(colour)}
            for k, (name, _, colour) in enumerate(prepare.tissues, 1) if k in present})
    arrays.update(normal_index=spilled("normal_index", index_type, normals),
                  normal_packed=spilled("normal_packed", "<i2", 2 * normals))
    meta["normals_from"] = plan.normals_from
    spacing = (plan.voxel,) * 3 if plan.resampled else plan.binned_spacing
    vxs.write_sections(output, plan.grid, spacing, meta, arrays)
    voxels = _voxel_count(arrays["starts"], arrays["ends"])
    return {"shape": plan.grid, "spacing": spacing, "meta": meta, "segment_count": total, "voxel_count": voxels,
            "normal_count": normals}


def _chunks(spilled, count=1 << 24):
    """The values of a spilled array, ``count`` at a time."""
    for name in spilled.files:
        with open(name, "rb") as f:
            while chunk := f.read(count * spilled.dtype.itemsize):
                yield np.frombuffer(chunk, spilled.dtype)


def _labels_present(labels):
    present = np.zeros(1 << 16, bool)
    for chunk in _chunks(labels):
        present[chunk] = True
    return np.flatnonzero(present).tolist()


def _voxel_count(starts, ends):
    return sum(int(np.sum(e, dtype=np.int64)) - int(np.sum(s, dtype=np.int64)) + len(s)
               for s, e in zip(_chunks(starts), _chunks(ends), strict=True))


def encode_file(path, output, read=None, prepare=None, *, octree=False, levels=False, jobs=None, scheduler=None,
                max_memory=None, progress=None):
    """Encode the input at ``path`` into ``output`` (``.vxs``; ``.vxo`` with the octrees, ``octree=True``): a slab
    at a time (:func:`encode_stack`) when reading it whole would take more than ``max_memory`` bytes (default: half
    the machine's memory) or when ``jobs`` or ``scheduler`` share the work out, else in memory.  Either way the
    file is the same.  With ``levels``, the file also keeps the object at 2, 4 and 8 times coarser voxels
    (:mod:`voxrender.object.levels`), made from its runs.  An input that is a ``.vxs`` already gets what is asked
    added.

    ``jobs`` worker processes encode a streamed stack's slabs (default: one for each of the machine's cores, as
    many as ``max_memory`` holds); an input read whole is encoded in this process.

    Returns
    -------
    encoded : Encoded
        The object, memory-mapped from ``output``; ``seconds["encode"]`` the time it took.
    how : str or None
        How a streamed stack was read (:class:`voxrender.io._stack.Canonical`), ``None`` when it was read whole.
    """
    from .pipeline import is_segments_file

    read, prepare = read or ReadOptions(), prepare or PrepOptions()
    max_memory = max_memory or machine_memory() // 2
    started = time.perf_counter()
    output, how = Path(output), None
    streamed = not is_segments_file(path) and _streams(path, read, prepare, max_memory, (jobs or 1) > 1 or scheduler)
    if jobs is None:
        jobs = default_jobs(max_memory) if streamed else 1
    # the octrees and levels are built from the streamed .vxs, which is kept beside the output only until then
    added = octree or levels
    objects = output.with_name(f".{output.name}.streamed.vxs") if streamed and added else output
    try:
        if streamed:
            how = encode_stack(path, objects, read, prepare, jobs=jobs, scheduler=scheduler, progress=progress)["how"]
        loaded = load_segments(objects) if streamed else load_segments(path, read, prepare, progress)
        if octree:
            loaded.octree(max_memory)                       # refused here if its build would pass max_memory
        if added or not streamed:
            with room_for(output):
                loaded.save(output, octree=octree, levels=levels)
            loaded = load_segments(output)                  # mapped from the file, as a renderer will take it
    finally:
        if objects != output:
            objects.unlink(missing_ok=True)
    loaded.seconds = {"encode": time.perf_counter() - started}
    return loaded, how


def default_jobs(max_memory, slab_voxels=None):
    """The worker processes a streamed encode takes by default: one for each core, as many as ``max_memory``
    bytes hold (each holds about ``WORKER_SLABS`` slabs of 16-bit input).

    >>> default_jobs(1 << 20)
    1
    """
    return max(1, min(os.cpu_count() or 1, max_memory // (WORKER_SLABS * 2 * (slab_voxels or SLAB_VOXELS))))


def _streams(path, read, prepare, max_memory, shared):
    """Whether to encode the input at ``path`` a slab at a time: its reader reads slabs, and the work is shared
    out or reading it whole would pass ``max_memory`` (the volume, its mask, and the float slices of resampling).
    """
    if not shared and _disk_bytes(path) * 20 < max_memory:       # surely small (even compressed): no need to open it
        return False
    stack = stack_of(path, read)
    if stack is None:
        return False
    grid = _grid(stack.shape, stack.spacing, prepare)[3] if prepare.labels is None else stack.shape
    needed = stack.nbytes + math.prod(grid) * (5 if grid != stack.shape else 1)    # the mask, float slices
    if (shared or needed > max_memory) and prepare.labels is None and prepare.min_object <= 1:
        return True
    if needed > max_memory:
        what = "a label map" if prepare.labels is not None else "removing small pieces (min_object)"
        raise InputError(f"{path} takes {needed / 1e9:.1f} GB in memory, more than the {max_memory / 1e9:.1f} GB "
                         f"allowed, and {what} needs it whole; allow more memory", parameter="max_memory")
    return False


def _disk_bytes(path):
    """The bytes the file or the files under the folder ``path`` take on disk."""
    path = Path(path)
    if path.is_file():
        return path.stat().st_size
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())


_SLABBED = tuple(name for name, reader in io.READERS.items() if reader.open is not None)

# how a streamed stack is read, in words (:class:`voxrender.io._stack.Canonical`'s ``how``)
HOW = {"stored order": "a slab of slices at a time, in stored order",
       "from the far end": "a slab of slices at a time, from the far end (the stored z axis is flipped)",
       "across the stored slices": "every stored slice again for each slab, as the stored slice axis is not z: "
                                   "bounded memory, slower"}


def stack_of(path, read):
    """The stack at ``path`` unread, when its reader reads slabs; else ``None``."""
    format = io.detect_format(path, read.raw) if read.format == "auto" else read.format
    return io.open_stack(path, format=read.format, raw=read.raw, spacing=read.spacing, series=read.series,
                         frame=read.frame, level=read.level, orientation=read.orientation,
                         reorient=read.reorient, run=read.run) if format in _SLABBED else None


@contextlib.contextmanager
def room_for(output):
    """Turn a full disk (or a file size limit) met while writing ``output`` or its parts into bad input: one line
    that says so; the writers leave nothing behind.
    """
    try:
        yield
    except OSError as exc:
        if exc.errno not in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
            raise
        raise InputError(f"no room to write {output}: {exc.strerror}; free some space or write it elsewhere",
                         parameter="output") from None
