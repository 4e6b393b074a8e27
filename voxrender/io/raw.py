"""Headerless slices: a folder of files or one file of ``width`` x ``height`` values, laid out by a
:class:`~voxrender.io.RawLayout` (files may hold several slices each; headers and notes beside them are skipped).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ._shared import NOTE_SUFFIXES, Reader, Volume, check_fits, files_in, stack_type
from ._stack import Stack

# Files that sit beside raw slices but are not slices: headers, and notes.
NOT_SLICES = {".nhdr", ".nrrd", ".mhd", ".hdr"} | NOTE_SUFFIXES


def read_raw(path, progress, raw):
    """Read headerless slices laid out by ``raw``, files in natural order of names."""
    files, counts = _slice_files(path, raw)
    check_fits((sum(counts), raw.height, raw.width), raw.dtype, path)
    values = np.empty((sum(counts), int(raw.height), int(raw.width)), np.dtype(raw.dtype).newbyteorder("="))
    z = 0
    for f, count in progress(list(zip(files, counts, strict=True)), len(files), "reading raw slices"):
        values[z:z + count] = _slices_of(f, raw, 0, count)
        z += count
    return Volume(values, (1.0, 1.0, 1.0), _meta(counts))


def open_raw(path, raw):
    """Headerless slices laid out by ``raw`` as a :class:`~voxrender.io._stack.Stack`: a slab is read from the
    files that hold it, at its byte offsets.
    """
    files, counts = _slice_files(path, raw)
    starts = np.cumsum([0, *counts])                  # the first slice of each file, and the end of the last
    shape = (int(starts[-1]), int(raw.height), int(raw.width))
    dtype = stack_type(raw.dtype, path)                # 16-bit floats become 32-bit ones, as in read_volume

    def read_slices(z0, z1):
        out = np.empty((z1 - z0, *shape[1:]), dtype)
        first, last = np.searchsorted(starts, z0, "right") - 1, np.searchsorted(starts, z1, "left")
        for k in range(first, max(first, last)):      # the files that hold part of the slab
            lo, hi = max(z0, starts[k]), min(z1, starts[k + 1])
            out[lo - z0:hi - z0] = _slices_of(files[k], raw, lo - starts[k], hi - lo)
        return out

    return Stack(shape, dtype, read_slices, (1.0, 1.0, 1.0), None, _meta(counts), shape[0] * raw.slice_bytes)


def _slice_files(path, raw):
    """The files of slices at ``path`` (a folder or one file) and how many slices each holds, checked against the
    layout ``raw``.
    """
    if raw is None:
        raise InputError("raw slices need their layout: width, height, dtype and byte order", parameter="raw")
    width, height, dtype, slice_bytes = int(raw.width), int(raw.height), np.dtype(raw.dtype), raw.slice_bytes
    files = [f for f in files_in(path) if f.suffix.lower() not in NOT_SLICES] if path.is_dir() else [path]
    counts = []
    for f in files:
        size = f.stat().st_size
        if size == 0 or size % slice_bytes:
            raise InputError(f"{f} is {size} bytes, not a multiple of one {width}x{height} {dtype.name} slice "
                             f"({slice_bytes} bytes); check the raw layout", parameter="raw")
        counts.append(size // slice_bytes)
    return files, counts


def _slices_of(f, raw, first, count):
    """Slices ``first .. first + count - 1`` of file ``f``, read at their offset in one call (no memory map, whose
    touched pages would stay resident), in native byte order; a file cut short since it was listed is bad input.
    """
    dtype, plane = np.dtype(raw.dtype), int(raw.width) * int(raw.height)
    values = np.fromfile(f, dtype, count=count * plane, offset=first * raw.slice_bytes)
    if values.size != count * plane:
        raise InputError(f"{f} ends within its slice {first + values.size // plane} (of {raw.width}x{raw.height} "
                         f"{dtype.name} values); the file is truncated")
    return values.reshape(count, int(raw.height), int(raw.width)).astype(dtype.newbyteorder("="), copy=False)


def _meta(counts):
    return {"spacing_from": "default (raw slices carry no spacing)", "slices": int(sum(counts))}


# Never detected: headerless slices are read when their layout is given.
READER = Reader(read_raw, options=("raw",), open=open_raw)
