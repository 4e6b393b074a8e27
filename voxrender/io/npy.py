"""A 3-D NumPy ``.npy`` array ``[z, y, x]``, memory-mapped (no spacing: 1 mm unless given)."""

from __future__ import annotations

import numpy as np

from .._shared.text import first_line
from ..errors import InputError
from ._shared import Reader, Volume, check_holds, promised_bytes, slices_at, stack_type
from ._stack import Stack


def read_npy(path, progress):
    """Read a 3-D numeric ``.npy`` array (booleans become 0 and 1 in :func:`~voxrender.io.read_volume`)."""
    from tokenize import TokenError

    # a garbled header can fail numpy's tokenizer, and a shape numpy's mapping cannot take ends in OverflowError
    damaged = (ValueError, OSError, EOFError, TokenError, OverflowError)
    try:
        shape, dtype, offset = _header(path)
        if dtype is not None:                                  # mapped, not read: only the file must hold them
            check_holds(path, promised_bytes(shape, dtype), path.stat().st_size - offset)
        values = np.load(path, mmap_mode="r", allow_pickle=False)
    except InputError:
        raise
    except damaged as exc:
        raise InputError(f"cannot read {path} as a .npy array: {first_line(exc)}") from None
    if values.ndim != 3 or values.dtype.kind not in "uifb":
        raise InputError(f"{path} holds a {values.ndim}-D {values.dtype} array; voxrender needs a 3-D "
                         "numeric array [z, y, x]")
    return Volume(values, (1.0, 1.0, 1.0), {"spacing_from": "default (.npy carries no spacing)"})


def open_npy(path):
    """The array of a ``.npy`` file as a :class:`~voxrender.io._stack.Stack`: slices read at their offset."""
    volume = read_npy(path, None)                     # checked and mapped, not read
    values = volume.values
    stored, offset, dtype = values.dtype, values.offset, stack_type(values.dtype, path)
    del volume
    if np.isfortran(values) and min(values.shape) > 1:            # slices are not contiguous: read through a map
        def read_stored(z0, z1):
            return np.array(np.load(path, mmap_mode="r", allow_pickle=False)[z0:z1])
    else:
        def read_stored(z0, z1):
            return slices_at(path, offset, values.shape, stored, z0, z1)

    def read_slices(z0, z1):                # booleans as 0 and 1, 16-bit floats as 32-bit ones: read_volume's
        part = read_stored(z0, z1)
        return part.view(np.uint8) if part.dtype.kind == "b" else part.astype(dtype, copy=False)

    return Stack(values.shape, dtype, read_slices, (1.0, 1.0, 1.0), None,
                 {"spacing_from": "default (.npy carries no spacing)"})


def _header(path):
    """The shape, dtype and data offset a ``.npy`` header promises, by numpy's own header readers (``None`` for the
    dtype of a format version they do not read).
    """
    from numpy.lib import format

    # version 3.0 is 2.0 with a UTF-8 header: an ASCII one (every dtype but one with non-ASCII field names) reads alike
    readers = {(1, 0): format.read_array_header_1_0, (2, 0): format.read_array_header_2_0,
               (3, 0): format.read_array_header_2_0}
    with open(path, "rb") as f:
        version = format.read_magic(f)
        if version not in readers:
            return None, None, None
        shape, _, dtype = readers[version](f)
        return shape, dtype, f.tell()


READER = Reader(read_npy, (".npy",), open=open_npy)
