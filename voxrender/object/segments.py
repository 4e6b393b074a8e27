"""Run-length segments: every row ``(z, y)`` of a binary mask as sorted runs along x.

The runs of all rows live in two flat arrays, ``starts`` and ``ends`` (inclusive),
indexed by ``offsets``: the runs of row ``r = z * ny + y`` are
``starts[offsets[r]:offsets[r + 1]]``.  ``offsets[z * ny]`` is where slice ``z``
begins, so ``offsets`` is both the per-slice and the per-row index of the
paper's Fig. 7.

A multi-label object (:func:`encode_labels`) also has ``labels``, one label per run: a run ends where its
label changes, so runs of different labels may touch.  Renderers see only the runs; the label of what a pixel
shows is looked up afterwards (:mod:`voxrender.pictures.labels`).

The ``.vxs`` file (:mod:`voxrender.object.vxs`) is that structure on disk.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._shared.mapped import prefetch
from ..errors import InputError


@dataclass
class Segments:
    """A binary object as run-length segments: every row ``(z, y)`` of its mask as sorted runs along x.

    Parameters
    ----------
    shape : (nz, ny, nx)
        The mask's grid.
    starts, ends : ndarray of int32
        The first and last (inclusive) x of every run, row after row.
    offsets : ndarray
        ``nz * ny + 1`` indices into ``starts`` and ``ends``: the runs of row ``r = z * ny + y`` are
        ``starts[offsets[r]:offsets[r + 1]]``, and ``offsets[z * ny]`` is where slice ``z`` begins (the per-slice
        and per-row index of the dynamic-screen paper's Fig. 7).
    spacing : (x, y, z)
        Voxel spacing in mm.
    meta : dict
        Where the object came from (threshold, source, orientation ...); a multi-label object's names and
        colours in ``meta["label_table"]``.
    normals : SurfaceNormals, optional
        The grey-level normals of the surface band (:mod:`voxrender.object.normals`), kept in the ``.vxs``.
    labels : ndarray of uint16, optional
        One label per run, for a multi-label object (:func:`encode_labels`); ``None`` for a single object.
    levels : tuple of Segments
        The object at 2, 4 and 8 times coarser voxels, when kept (:mod:`voxrender.object.levels`):
        :meth:`at_level` gives one.

    Examples
    --------
    >>> mask = np.zeros((1, 2, 6), bool)
    >>> mask[0, 0, 1:3] = mask[0, 0, 4] = mask[0, 1, :] = True
    >>> s = encode(mask)
    >>> s.row(0, 0)
    (array([1, 4], dtype=int32), array([2, 4], dtype=int32))
    >>> s.segment_count, s.voxel_count
    (3, 9)
    >>> bool(np.array_equal(s.to_mask(), mask))
    True
    """

    shape: tuple[int, int, int]
    starts: np.ndarray
    ends: np.ndarray
    offsets: np.ndarray
    spacing: tuple[float, float, float] = (1.0, 1.0, 1.0)
    meta: dict = field(default_factory=dict)
    normals: object = field(default=None, repr=False, compare=False)   # SurfaceNormals, kept in the .vxs
    labels: np.ndarray | None = field(default=None, repr=False)      # uint16, one per run (multi-label objects)
    levels: tuple = field(default=(), repr=False, compare=False)      # coarser Segments (object.levels)
    unchecked: object = field(default=None, repr=False, compare=False)   # a file's check, made on first use

    def check(self):
        """Run the check a file's object was loaded with (that its runs lie on its grid), once: the renderers and
        builders call it before they index with the runs.  A file with levels defers it, so that a picture drawn
        from one level reads no other level's runs.
        """
        pending, self.unchecked = self.unchecked, None
        if pending is not None:
            pending()

    def prefetch(self):
        """Have a file's runs read from disk in the background (:func:`~voxrender._shared.mapped.prefetch`): a
        picture reads them all, and meanwhile there is work to do.
        """
        prefetch(self.offsets, self.starts, self.ends)

    @property
    def segment_count(self):
        """How many runs (segments) the object has."""
        return int(self.offsets[-1])

    @property
    def voxel_count(self):
        """How many voxels the object has."""
        # summed apart: no int64 copies of the runs, which are as large as the file for a big object
        return int(np.sum(self.ends, dtype=np.int64)) - int(np.sum(self.starts, dtype=np.int64)) + self.segment_count

    def at_level(self, level):
        """The object at ``level``: itself at 0, else the ``level``-th of its coarser :attr:`levels`.

        >>> encode(np.ones((2, 2, 2), bool)).at_level(0).shape
        (2, 2, 2)
        """
        if level == 0:
            return self
        if not (isinstance(level, (int, np.integer)) and 0 < level <= len(self.levels)):
            kept = f"levels 0 to {len(self.levels)}" if self.levels else "only level 0 (encode --levels adds more)"
            raise InputError(f"level {level!r}: the object keeps {kept}", parameter="level")
        return self.levels[level - 1]

    def label_voxels(self):
        """How many voxels each label has, ``{label: count}``, by label; ``{}`` for a single object.

        >>> encode_labels(np.array([[[0, 2, 2, 5]]])).label_voxels()
        {2: 2, 5: 1}
        """
        if self.labels is None:
            return {}
        counts = np.bincount(self.labels, weights=self.ends.astype(np.int64) - self.starts + 1)
        return {int(v): int(counts[v]) for v in np.flatnonzero(counts)}

    def run_rows(self):
        """The row ``r = z * ny + y`` of every run (int64).

        >>> encode(np.array([[[1, 0, 1], [0, 1, 0]]], bool)).run_rows().tolist()
        [0, 0, 1]
        """
        return np.repeat(np.arange(len(self.offsets) - 1, dtype=np.int64), np.diff(np.asarray(self.offsets)))

    def row(self, z, y):
        """``(starts, ends)`` of row ``y`` of slice ``z``."""
        r = z * self.shape[1] + y
        lo, hi = self.offsets[r], self.offsets[r + 1]
        return np.asarray(self.starts[lo:hi]), np.asarray(self.ends[lo:hi])

    def slice(self, z):
        """``(rows, starts, ends)`` of every run of slice ``z``; ``rows`` are y indices."""
        ny = self.shape[1]
        bounds = np.asarray(self.offsets[z * ny:(z + 1) * ny + 1])
        lo, hi = bounds[0], bounds[-1]
        rows = np.repeat(np.arange(ny, dtype=np.int32), np.diff(bounds))
        return rows, np.asarray(self.starts[lo:hi]), np.asarray(self.ends[lo:hi])

    def slice_mask(self, z):
        """Slice ``z`` decoded to a bool array ``[y, x]``."""
        rows, starts, ends = self.slice(z)
        line = np.zeros((self.shape[1], self.shape[2] + 1), np.int8)
        np.add.at(line, (rows, starts), 1)
        np.add.at(line, (rows, ends + 1), -1)
        return np.cumsum(line, axis=1)[:, :-1].astype(bool)

    def to_mask(self):
        """The whole mask ``[z, y, x]``."""
        return np.stack([self.slice_mask(z) for z in range(self.shape[0])]) if self.shape[0] else \
            np.zeros(self.shape, bool)

    def only(self, labels):
        """The runs of ``labels`` (a label or several) as a single object of the same grid.

        >>> s = encode_labels(np.array([[[0, 2, 2, 5, 0, 5]]]))
        >>> s.only(5).starts.tolist(), s.only(5).labels
        ([3, 5], None)
        """
        self.check()
        keep = np.isin(np.asarray(self.labels), np.atleast_1d(labels))
        kept_before = np.concatenate([[0], np.cumsum(keep)])      # runs kept before each run
        offsets = kept_before[np.asarray(self.offsets)]
        meta = {k: v for k, v in self.meta.items() if k != "label_table"}
        meta["labels"] = [int(v) for v in np.atleast_1d(labels)]
        return Segments(self.shape, np.asarray(self.starts)[keep], np.asarray(self.ends)[keep], offsets,
                        self.spacing, meta, self.normals)

    def bounding_box(self):
        """``((z0, z1), (y0, y1), (x0, x1))`` inclusive, or ``None`` for an empty object."""
        if not self.segment_count:
            return None
        nz, ny, _ = self.shape
        counts = np.diff(np.asarray(self.offsets)).reshape(nz, ny)
        zs, ys = np.nonzero(counts.sum(axis=1))[0], np.nonzero(counts.sum(axis=0))[0]
        return ((int(zs[0]), int(zs[-1])), (int(ys[0]), int(ys[-1])),
                (int(np.min(self.starts)), int(np.max(self.ends))))


def ranges(starts, counts, owners=False):
    """``starts[i], starts[i] + 1, ... (counts[i] numbers)`` for every ``i``, one after another; with ``owners``,
    also the ``i`` each number belongs to.  The voxels of runs, the pixels of spans, the rows of a CSR table.

    >>> ranges(np.array([5, 0]), np.array([2, 3])).tolist()
    [5, 6, 0, 1, 2]
    >>> ranges(np.array([5, 0]), np.array([2, 3]), owners=True)[1].tolist()
    [0, 0, 1, 1, 1]
    """
    starts, counts = np.asarray(starts, np.int64), np.asarray(counts, np.int64)
    ends = np.cumsum(counts)
    values = np.repeat(starts - ends + counts, counts) + np.arange(ends[-1] if len(ends) else 0)
    return (values, np.repeat(np.arange(len(counts)), counts)) if owners else values


def expand_runs(rows, starts, ends):
    """``(row, x)`` of every voxel of the runs ``[starts, ends]`` of rows ``rows``.

    >>> expand_runs(np.array([0, 3]), np.array([1, 4]), np.array([2, 4]))
    (array([0, 0, 3]), array([1, 2, 4]))
    """
    lengths = np.asarray(ends, np.int64) - starts + 1
    return np.repeat(rows, lengths), ranges(starts, lengths)


_BLOCK_VOXELS = 1 << 24       # voxels compared at a time when finding runs


def _row_changes(lines):
    """Where a voxel differs from the one before it along its row (``lines`` ``(rows, nx)``), each row with a
    clear voxel added at both ends: sorted places in rows of ``nx + 1`` (place ``c`` of a row is between its
    voxels ``c - 1`` and ``c``).  The rows are compared a block at a time in one buffer, with no padded copy
    of the volume (new memory is slow to touch).
    """
    count, nx = lines.shape
    block = max(1, _BLOCK_VOXELS // max(nx, 1))
    differ = np.empty((min(block, count), max(nx - 1, 0)), bool)
    inner = []
    for first in range(0, count, block):
        part = lines[first:first + block]
        found = np.not_equal(part[:, 1:], part[:, :-1], out=differ[:len(part)])
        inner.append(np.flatnonzero(found) + first * (nx - 1))
    inner = np.concatenate(inner) if inner else np.zeros(0, np.int64)
    changes = np.concatenate([inner + inner // (nx - 1) * 2 + 1 if nx > 1 else inner,
                              np.flatnonzero(lines[:, 0]) * (nx + 1), np.flatnonzero(lines[:, -1]) * (nx + 1) + nx])
    changes.sort()
    return changes


def encode(mask, spacing=(1.0, 1.0, 1.0), meta=None):
    """Run-length encode a bool mask ``[z, y, x]`` into :class:`Segments`.

    Vectorised over all rows: with a clear voxel added at both ends of every
    row, the places where a voxel differs from its left neighbour alternate
    between run starts and one-past-run ends, in row order.

    Parameters
    ----------
    mask : array_like of bool, ``[z, y, x]``
        The object.
    spacing : 3 floats
        Voxel spacing (x, y, z) in mm, kept with the segments.
    meta : dict, optional
        Where the object came from (source, threshold ...), kept with the segments.

    Returns
    -------
    Segments

    Examples
    --------
    >>> encode(np.array([[[0, 1, 1, 0, 1]]], bool)).starts
    array([1, 4], dtype=int32)
    """
    mask = np.asarray(mask, dtype=bool)
    if mask.ndim != 3:
        raise InputError(f"a mask must be 3-D [z, y, x], got shape {mask.shape}")
    nz, ny, nx = mask.shape
    changes = _row_changes(mask.reshape(nz * ny, nx))
    rows, columns = np.divmod(changes, nx + 1)
    starts, ends = columns[0::2], columns[1::2] - 1
    offsets = np.zeros(nz * ny + 1, np.int64)
    np.cumsum(np.bincount(rows[0::2], minlength=nz * ny), out=offsets[1:])
    return Segments((nz, ny, nx), starts.astype(np.int32), ends.astype(np.int32), offsets,
                    tuple(float(s) for s in spacing), dict(meta or {}))


def encode_labels(label_map, spacing=(1.0, 1.0, 1.0), meta=None):
    """Run-length encode a label map ``[z, y, x]`` (0: background) into :class:`Segments` with one label per run.

    A run is a maximal stretch of one non-zero label along x, so that runs of different labels may touch.

    Examples
    --------
    >>> s = encode_labels(np.array([[[0, 2, 2, 5, 0, 5]]]))
    >>> s.starts.tolist(), s.ends.tolist(), s.labels.tolist()
    ([1, 3, 5], [2, 3, 5], [2, 5, 5])
    """
    values = np.asarray(label_map)
    if values.ndim != 3:
        raise InputError(f"a label map must be 3-D [z, y, x], got shape {values.shape}")
    nz, ny, nx = values.shape
    lines = values.reshape(nz * ny, nx)
    # every place where a voxel differs from its left neighbour begins a stretch that lasts to the next one
    bounds = _row_changes(lines)
    rows, columns = np.divmod(bounds, nx + 1)
    labels = np.where(columns < nx, lines[rows, np.minimum(columns, nx - 1)], 0)     # column nx: the clear end
    ends = np.append(bounds[1:], bounds[-1] + 1 if len(bounds) else 0) - 1 - rows * (nx + 1)
    kept = labels != 0                      # a non-zero stretch always ends within its row (the padding is 0)
    offsets = np.zeros(nz * ny + 1, np.int64)
    np.cumsum(np.bincount(rows[kept], minlength=nz * ny), out=offsets[1:])
    result = Segments((nz, ny, nx), columns[kept].astype(np.int32), ends[kept].astype(np.int32), offsets,
                      tuple(float(s) for s in spacing), dict(meta or {}))
    result.labels = labels[kept].astype(np.uint16)
    return result


def label_at(segments, x, y, z):
    """The label of the voxels at integer ``(x, y, z)`` (arrays of one shape): 0 outside the object.

    A single-object ``segments`` (no ``labels``) gives 1 inside the object.

    Examples
    --------
    >>> s = encode_labels(np.array([[[0, 2, 2, 5]]]))
    >>> label_at(s, np.arange(5), np.zeros(5, int), np.zeros(5, int)).tolist()
    [0, 2, 2, 5, 0]
    """
    nz, ny, nx = segments.shape
    x, y, z = (np.asarray(v, dtype=np.int64) for v in (x, y, z))
    if not segments.segment_count:
        return np.zeros(x.shape, np.uint16)
    inside = (x >= 0) & (x < nx) & (y >= 0) & (y < ny) & (z >= 0) & (z < nz)
    runs_row = segments.run_rows()
    # runs sorted by row and then start: one key orders them all
    keys = runs_row * (nx + 1) + np.asarray(segments.starts)
    row = np.where(inside, z * ny + y, 0)
    run = np.searchsorted(keys, row * (nx + 1) + x, side="right") - 1
    safe = np.maximum(run, 0)
    hit = inside & (run >= 0) & (runs_row[safe] == row) & (np.asarray(segments.ends)[safe] >= x)
    labels = np.ones(len(keys), np.uint16) if segments.labels is None else np.asarray(segments.labels)
    return np.where(hit, labels[safe], 0).astype(np.uint16)
