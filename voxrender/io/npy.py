"""A 3-D NumPy ``.npy`` array ``[z, y, x]``, memory-mapped (no spacing: 1 mm unless given)."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ._shared import Reader, Volume, first_line


def read_npy(path, progress):
    """Read a 3-D numeric ``.npy`` array (booleans become 0 and 1)."""
    from tokenize import TokenError

    try:
        values = np.load(path, mmap_mode="r", allow_pickle=False)
    except (ValueError, OSError, EOFError, TokenError) as exc:    # a garbled header can fail numpy's tokenizer
        raise InputError(f"cannot read {path} as a .npy array: {first_line(exc)}") from None
    if values.ndim != 3 or values.dtype.kind not in "uifb":
        raise InputError(f"{path} holds a {values.ndim}-D {values.dtype} array; voxrender needs a 3-D "
                         "numeric array [z, y, x]")
    if values.dtype.kind == "b":
        values = values.astype(np.uint8)
    return Volume(values, (1.0, 1.0, 1.0), {"spacing_from": "default (.npy carries no spacing)"})


READER = Reader(read_npy, (".npy",))
