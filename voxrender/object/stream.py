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

import collections
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
from .levels import FACTORS, build_levels, coarse_meta, coarse_shape, summed_normals
from .normals import SurfaceNormals, stencil_radius, surface_normals
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
from .survey import binned_slices, slab_slices, survey

SLAB_VOXELS = 1 << 26          # input voxels read at a time (128 MB of 16-bit slices)
NORMAL_VOXELS = 1 << 24        # grid voxels whose band's normals are found at a time (their stencils are large)
LEVEL_FACTOR = FACTORS[0]      # the level made as the slabs pass; the coarser ones are made from it
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
    levels: bool = False       # also the object at 2 x coarser voxels, made as the slabs pass (levels.FACTORS)


def encode_stack(path, output, read=None, prepare=None, *, jobs=1, scheduler=None, progress=None,
                 slab_voxels=SLAB_VOXELS, levels=False):
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
    levels : bool
        Also keep the object at 2, 4 and 8 times coarser voxels (:mod:`voxrender.object.levels`): the 2 x level
        made from each slab as it passes, the others from it; the file is the one ``Encoded.save(levels=True)``
        writes, without reading the object again.

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
            if levels:                  # slabs of whole coarse slices
                slab = max(LEVEL_FACTOR, plan.slab // LEVEL_FACTOR * LEVEL_FACTOR)
                plan = replace(plan, levels=True, slab=min(plan.grid[0], slab))
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
    surveyed = survey(stack, region, bin, prepare, slab_voxels)
    if prepare.tissues:
        windows = tuple(window for _, window, _ in prepare.tissues)
        threshold = ", ".join(str(w) for w in windows)
    else:
        found = prepare.selecting
        if found is prep.otsu_threshold:
            found = surveyed["otsu"]
        elif callable(found):
            raise InputError("a threshold found by a function needs the whole volume; give a number or a window "
                             "to stream the stack", parameter="threshold")
        windows = (found if isinstance(found, prep.Interval) else prep.Interval(float(found)),)
        threshold = str(found) if isinstance(found, prep.Interval) else windows[0].lo
    slab = slab_slices(stack, cropped, grid, bin, slab_voxels)
    step = grid_step(spacing, voxel, prepare.resample)
    plan = Plan(source, read, token, region, bin, windows, grid, voxel, spacing, resampled,
                on_input_grid(step, shape, grid), "the binary mask" if surveyed["binary"] else "grey values",
                surveyed["fill"], slab, spool)
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
        # this encode's own workers keep the memory their slabs free; a Dask cluster's serve others after it
        futures = {pool.submit(encode_part, plan, a, b, str(folder), not scheduler): n
                   for n, (a, b) in enumerate(parts)}
        results = [None] * len(parts)
        for future in pool.as_completed(list(futures)):      # as they end on the workers
            results[futures[future]] = future.result()
            next(ticks, None)
        return results
    finally:
        pool.close()


def encode_part(plan, first, last, folder, keep_memory=True):
    """Encode the grid's slices ``first .. last - 1`` of a :class:`Plan`, a slab at a time, into files in
    ``folder``: their runs, labels and normals.  Returns the runs each row has and the files.  With
    ``keep_memory``, the process keeps the memory its slabs free from then on, for the next slab
    (:func:`~voxrender._shared.memory.keep_freed_memory`).
    """
    stack = _open(plan.source, plan.read, plan.token, plan.spool)
    names = ("starts", "ends", "labels", "normal_index", "normal_packed")
    names += tuple(f"level1.{name}" for name in names) if plan.levels else ()
    files = {name: Path(folder) / f"{first:08d}.{name}" for name in names}
    rows, normal_count, coarse_rows, label_voxels = [], 0, [], collections.Counter()
    if keep_memory:                     # in this process, _run gives the memory back when the encode ends
        keep_freed_memory()
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
            found = []                  # the slab's normals, kept for its coarse level
            for index, packed in _normals(plan, layers, grey, grey_first, mask_first, a, b):
                out.add(normal_index=index, normal_packed=packed)
                normal_count += len(index)
                if plan.levels:
                    found.append((index, packed))
            if plan.levels:
                label_voxels.update(runs.label_voxels())
                coarse, (index, packed) = _coarse_slab(plan, layers, mask_first, a, b, found)
                coarse_rows.append(np.diff(coarse.offsets))
                out.add(**{"level1.starts": np.asarray(coarse.starts, "<i4"),
                           "level1.ends": np.asarray(coarse.ends, "<i4"),
                           "level1.normal_index": np.asarray(index, f"<i{index.dtype.itemsize}"),
                           "level1.normal_packed": np.asarray(packed, "<i2").ravel()})
                if coarse.labels is not None:
                    out.add(**{"level1.labels": np.asarray(coarse.labels, "<u2")})
    result = {"first": first, "rows": np.concatenate(rows), "files": {k: str(v) for k, v in files.items()},
              "normals": normal_count}
    if plan.levels:
        result.update(coarse_rows=np.concatenate(coarse_rows), label_voxels=label_voxels)
    return result


def _coarse_slab(plan, layers, mask_first, a, b, normals):
    """The 2 x coarser level of the grid's slices ``a .. b - 1`` (``a`` even; ``b`` too, or the grid's end), as
    :func:`voxrender.object.levels.coarser` makes it from the whole object: its runs (a :class:`Segments` of the
    coarse slices), and its normals ``(index, packed)`` from the slab's fine ``normals`` (``(index, packed)``
    pieces).  ``layers`` hold the grid's slices from ``mask_first`` on, two beside the slab on either side where
    the grid has them: the coarse slice beside, which decides its surface.
    """
    factor, nz = LEVEL_FACTOR, plan.grid[0]
    lo, hi = max(a - factor, 0), min(b + factor, nz)
    coarse = _max_binned(layers[lo - mask_first:hi - mask_first], factor)     # coarse slices lo / 2 ..
    below = lo // factor
    own = coarse[a // factor - below:-(-b // factor) - below]
    runs = segments.encode_labels(own) if len(plan.windows) > 1 else segments.encode(own.view(bool))
    index = np.concatenate([index for index, _ in normals]).astype(np.int64)
    packed = np.concatenate([packed for _, packed in normals]).reshape(-1, 2)
    return runs, summed_normals(index, packed, plan.grid, a, b, factor, coarse > 0, below)


def _max_binned(layers, factor):
    """The largest value of each ``factor``³ block of ``layers`` (beyond its edges, zeros): its coarse voxels.
    scikit-image's ``block_reduce(layers, (2, 2, 2), np.max)`` gives the same, 14 times slower (0.84 s against
    0.06 s for a slab of 20 slices of 2048²): its maximum runs over the trailing axes of a strided view.
    """
    coarse = layers
    if any(n % factor for n in layers.shape):
        coarse = np.zeros(tuple(-(-n // factor) * factor for n in layers.shape), layers.dtype)
        coarse[tuple(slice(0, n) for n in layers.shape)] = layers
    for axis in range(3):
        take = [slice(None)] * 3
        take[axis] = slice(0, None, factor)
        largest = coarse[tuple(take)].copy()
        for k in range(1, factor):
            take[axis] = slice(k, None, factor)
            np.maximum(largest, coarse[tuple(take)], out=largest)
        coarse = largest
    return coarse


def _slab(plan, stack, a, b):
    """The object's grid slices ``a .. b - 1`` with those beside them that the normals' stencil reaches, as
    window numbers (uint8 layers), and the grey values they come from: ``(layers, grey, grey_first,
    mask_first)``, the last two being the input (binned) slice and the grid slice the arrays begin at.
    """
    # the band needs one slice beside it, the stencil more, the coarse surface two (a coarse slice beside)
    halo = max(stencil_radius(plan.normals_from), LEVEL_FACTOR if plan.levels else 0)
    mask_first, mask_last = max(0, a - halo), min(plan.grid[0], b + halo)
    nz = (plan.region[0].stop - plan.region[0].start) // plan.bin
    if plan.resampled:
        # the input slices the layers blend, and those the normals' B-spline reaches (grey_sampler), with room
        lo = slabs.input_slice(max(0, mask_first - 1), plan.voxel, plan.binned_spacing[2], nz)[0]
        hi = slabs.input_slice(min(plan.grid[0] - 1, mask_last), plan.voxel, plan.binned_spacing[2], nz)[0]
        grey_first, grey_last = max(0, lo - 2), min(nz, hi + 4)
    else:
        grey_first, grey_last = mask_first, mask_last
    grey = binned_slices(stack, plan.region, plan.bin, range(grey_first, grey_last))
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
    """Write the ``.vxs`` of the parts' files: as :func:`voxrender.object.vxs.save` writes the object in memory;
    with the plan's ``levels``, its coarser levels too (:func:`_levels`).
    """
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
    if plan.levels:
        vxs.add_levels(meta, arrays, _levels(plan, meta, spacing, results))
    vxs.write_sections(output, plan.grid, spacing, meta, arrays)
    voxels = _voxel_count(arrays["starts"], arrays["ends"])
    return {"shape": plan.grid, "spacing": spacing, "meta": meta, "segment_count": total, "voxel_count": voxels,
            "normal_count": normals}


def _levels(plan, meta, spacing, results):
    """The object's coarser levels, as :func:`voxrender.object.levels.build_levels` makes them from the whole
    object: the 2 x level from the parts' files (made as the slabs passed), the coarser ones from it.
    """
    factor = LEVEL_FACTOR
    shape = coarse_shape(plan.grid, factor)

    def joined(name, dtype):
        return np.concatenate([np.fromfile(r["files"][f"level1.{name}"], dtype) for r in results])

    counts = np.concatenate([r["coarse_rows"] for r in results])
    offsets = np.zeros(len(counts) + 1, np.int64)
    np.cumsum(counts, out=offsets[1:])
    labelled = len(plan.windows) > 1
    own = dict(sorted(sum((r["label_voxels"] for r in results), collections.Counter()).items()))   # as label_voxels()
    level_meta = coarse_meta(meta, factor, (lambda: own) if labelled else None, spacing)
    index_type = "<i4" if math.prod(shape) < 2 ** 31 else "<i8"
    normals = SurfaceNormals(shape, joined("normal_index", index_type), joined("normal_packed", "<i2").reshape(-1, 2),
                             f"{plan.normals_from}, summed over {factor}x{factor}x{factor} voxels")
    first = segments.Segments(shape, joined("starts", "<i4"), joined("ends", "<i4"), offsets,
                              tuple(float(s) * factor for s in spacing), level_meta, normals,
                              joined("labels", "<u2") if labelled else None)
    return (first,) + build_levels(first, tuple(f // factor for f in FACTORS[1:]))


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
    # a streamed stack's levels are made as its slabs pass; the octrees are built from the streamed .vxs, which is
    # kept beside the output only until then
    passing = streamed and levels and not octree
    added = octree or (levels and not passing)
    objects = output.with_name(f".{output.name}.streamed.vxs") if streamed and added else output
    try:
        if streamed:
            how = encode_stack(path, objects, read, prepare, jobs=jobs, scheduler=scheduler, progress=progress,
                               levels=passing)["how"]
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
