"""Headerless slices: a folder of files or one file of ``width`` x ``height`` values, laid out by a
:class:`~voxrender.io.RawLayout` (files may hold several slices each; headers and notes beside them are skipped).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ._shared import NOTE_SUFFIXES, Reader, Volume, check_fits, files_in

# Files that sit beside raw slices but are not slices: headers, and notes.
NOT_SLICES = {".nhdr", ".nrrd", ".mhd", ".hdr"} | NOTE_SUFFIXES


def read_raw(path, progress, raw):
    """Read headerless slices laid out by ``raw``, files in natural order of names."""
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
    check_fits((sum(counts), height, width), dtype, path)
    values = np.empty((sum(counts), height, width), dtype.newbyteorder("="))
    z = 0
    for f, count in progress(list(zip(files, counts, strict=True)), len(files), "reading raw slices"):
        values[z:z + count] = np.fromfile(f, dtype).reshape(count, height, width)
        z += count
    return Volume(values, (1.0, 1.0, 1.0), {"spacing_from": "default (raw slices carry no spacing)",
                                            "slices": int(sum(counts))})


# Never detected: headerless slices are read when their layout is given.
READER = Reader(read_raw, options=("raw",))
