"""Slice stacks read a slab at a time: what a reader gives for a stack larger than memory.

A :class:`Stack` is a volume not yet read: its shape, type, spacing, direction and meta as :func:`read_volume` would
give them, and ``read_slices(z0, z1)``, which reads the stored slices ``z0 .. z1 - 1`` only.  A reader that can
stream gives one through its record's ``open`` function (``open_FORMAT(path, **options) -> Stack``);
:func:`voxrender.io.open_stack` finds the reader and brings the stack to the canonical frame (:class:`Canonical`),
still unread.  The streaming encoder (:mod:`voxrender.object.stream`) then reads it slab by slab in canonical z order.

How a canonical slab is read depends on the stored order:

* the stored slices are the canonical ones (``"stored order"``), or the same from the far end (``"from the far
  end"``, a z flip): each slab is one read of consecutive stored slices, flipped and turned in memory;
* a permutation moves the stored slice axis (a sagittal series): a canonical slab takes a few rows or columns of
  every stored slice, so every stored slice is read again for each slab, a few at a time (``"across the stored
  slices"``): bounded memory, slower.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..space import orient


@dataclass
class Stack:
    """A slice stack, unread: the stored slices ``[z0, z1)`` come from ``read_slices(z0, z1)`` as an array
    ``[z1 - z0, ny, nx]`` of ``dtype``, the values :func:`~voxrender.io.read_volume` would hold there (scaled,
    in native byte order, booleans as 0 and 1).

    Parameters
    ----------
    shape : (nz, ny, nx)
        As stored.
    dtype : numpy dtype
    read_slices : callable
        ``read_slices(z0, z1) -> ndarray``; raises :class:`~voxrender.errors.InputError` for a damaged or
        inconsistent slice (a slice of another size, named), as the reader would.
    spacing, direction, meta
        As in :class:`~voxrender.io.Volume` (``meta`` has ``format`` and ``source``).
    stored_bytes : int
        The bytes read from disk for the whole stack (for progress in MB/s); the voxels' bytes when unknown.
    sequential : bool
        The slices come from one stream (compressed data): reading them out of order costs a rewind.
    """

    shape: tuple
    dtype: np.dtype
    read_slices: Callable
    spacing: tuple = (1.0, 1.0, 1.0)
    direction: np.ndarray | None = None
    meta: dict = field(default_factory=dict)
    stored_bytes: int = 0
    sequential: bool = False

    def __post_init__(self):
        self.shape = tuple(int(n) for n in self.shape)
        self.dtype = np.dtype(self.dtype)
        self.stored_bytes = int(self.stored_bytes or np.prod(self.shape, dtype=np.int64) * self.dtype.itemsize)

    @property
    def nbytes(self):
        """The voxels' bytes in memory (what reading the whole stack would allocate)."""
        return int(np.prod(self.shape, dtype=np.int64)) * self.dtype.itemsize

    def read(self):
        """The whole stack as one array (a small stack, or a test)."""
        return self.read_slices(0, self.shape[0])


@dataclass
class Canonical:
    """A :class:`Stack` in the canonical patient frame, still unread: ``read_slices(z0, z1)`` gives canonical
    slices, and ``how`` says how they are read (see the module's notes).  Built by :func:`canonical`.
    """

    stack: Stack
    shape: tuple
    spacing: tuple
    direction: np.ndarray | None
    meta: dict
    order: tuple = (0, 1, 2)         # np.transpose order from the stored array to the canonical one
    flips: tuple = ()                # canonical numpy axes flipped after the transpose
    how: str = "stored order"
    slab_bytes: int = 64 << 20       # stored slices read at a time when the slice axis is moved

    @property
    def dtype(self):
        return self.stack.dtype

    @property
    def nbytes(self):
        return self.stack.nbytes

    @property
    def stored_bytes(self):
        return self.stack.stored_bytes

    def read_slices(self, z0, z1):
        """Canonical slices ``[z0, z1)`` as an array ``[z1 - z0, ny, nx]``."""
        nz = self.shape[0]
        if not 0 <= z0 <= z1 <= nz:
            raise IndexError(f"slices {z0}:{z1} of {nz}")
        if self.order[0] != 0:
            return self.read_numbers(range(z0, z1))
        flipped_z = 0 in self.flips
        lo, hi = (nz - z1, nz - z0) if flipped_z else (z0, z1)      # in the canonical axis before its flip
        part = np.transpose(self.stack.read_slices(lo, hi), self.order)
        for axis in self.flips:
            part = np.flip(part, axis)
        return np.ascontiguousarray(part)

    def read_numbers(self, numbers):
        """The canonical slices ``numbers`` (any of them, in any order) as one array: a stack read across its
        stored slices reads each stored slice once for all of them, a few stored slices at a time, keeping the
        rows or columns asked for; any other reads them slice by slice.
        """
        numbers = np.asarray(numbers, np.int64)
        if self.order[0] == 0:
            return np.concatenate([self.read_slices(z, z + 1) for z in numbers]) if len(numbers) else \
                np.empty((0,) + self.shape[1:], self.dtype)
        unflipped = self.shape[0] - 1 - numbers if 0 in self.flips else numbers
        stored = self.stack.shape
        moved = self.order[0]                                       # the stored axis that becomes canonical z
        out = np.empty((len(numbers),) + tuple(stored[a] for a in self.order[1:]), self.dtype)
        step = max(1, self.slab_bytes // max(1, stored[1] * stored[2] * self.dtype.itemsize))
        take = [slice(None)] * 3
        take[moved] = unflipped
        for first in range(0, stored[0], step):
            last = min(first + step, stored[0])
            part = self.stack.read_slices(first, last)[tuple(take)]
            where = [slice(None)] * 3
            where[self.order.index(0)] = slice(first, last)
            out[tuple(where)] = np.transpose(part, self.order)     # canonical axes; stored z now at its place
        for axis in self.flips:
            if axis:                                                # z's flip is in the numbers
                out = np.flip(out, axis)
        return np.ascontiguousarray(out)


def canonical(stack, reorient=True):
    """``stack`` in the canonical frame (see :func:`voxrender.space.orient.to_canonical`), unread: the transpose and
    flips that ``to_canonical`` would apply to the whole array, applied to each slab as it is read.
    """
    meta = dict(stack.meta)
    if stack.direction is None or not reorient:
        return Canonical(stack, stack.shape, tuple(stack.spacing), stack.direction, meta)
    order, flips, spacing, direction, note = _transform(stack.spacing, stack.direction,
                                                        meta.get("orientation_from", "the header"))
    meta["reoriented"] = note
    shape = tuple(stack.shape[a] for a in order)
    how = "stored order" if order[0] == 0 and 0 not in flips else \
        "from the far end" if order[0] == 0 else "across the stored slices"
    return Canonical(stack, shape, spacing, direction, meta, tuple(order), tuple(flips), how)


def _transform(spacing, direction, source):
    """The transpose order and flipped axes :func:`voxrender.space.orient.to_canonical` applies, read off what it does
    to an array of index numbers the size of two voxels a side (cheap), with its spacing, direction and note.
    """
    small = np.arange(8).reshape(2, 2, 2)
    out, spacing, direction, note = orient.to_canonical(small, spacing, direction, source)
    # which stored axis each canonical axis is, and whether it runs backwards, from the corner values
    strides = {4: 0, 2: 1, 1: 2}                                     # index step -> stored numpy axis
    corner = int(out[0, 0, 0])
    order, flips = [], []
    for axis in range(3):
        step = [0, 0, 0]
        step[axis] = 1
        change = int(out[tuple(step)]) - corner
        order.append(strides[abs(change)])
        if change < 0:
            flips.append(axis)
    return order, flips, spacing, direction, note
