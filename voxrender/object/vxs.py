"""The ``.vxs`` file: an object's run-length segments (:mod:`voxrender.object.segments`) on disk, with its surface
normals and further named sections (the region octree's).

A magic line, a JSON header, then the arrays at 64-byte aligned offsets.  :func:`load` memory-maps it, so a
slice or a row is read without reading the rest; :func:`write_sections` writes it from arrays held in memory
(:func:`save`) or spilled to files a slab at a time (:class:`Spilled`, :mod:`voxrender.object.stream`).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._shared.files import atomic_output
from .._shared.mapped import block_reads, blocks, file_span
from .._shared.threads import on_threads
from ..errors import InputError
from .normals import SurfaceNormals
from .segments import Segments

MAGIC = b"VOXRENDER-SEGMENTS 1\n"


_ALIGN = 64


def save(segments, path, sections=None):
    """Write ``segments`` to a ``.vxs`` file (atomically), with further named arrays ``sections`` (e.g. the
    region octree's, :func:`voxrender.object.octree.sections`), memory-mapped again by :func:`read_sections`.
    Its coarser :attr:`~voxrender.object.segments.Segments.levels` go with it, their arrays named ``level1.starts``
    and so on, their grids and what their meta adds in ``meta["levels"]``.
    """
    own = _object_arrays(segments)
    # the runs, the further sections, then labels and normals: the order files have always had
    arrays = {name: own.pop(name) for name in ("offsets", "starts", "ends")}
    arrays.update({name: np.asarray(array).ravel() for name, array in (sections or {}).items()})
    arrays.update(own)
    meta = dict(segments.meta)
    if segments.normals is not None:
        meta["normals_from"] = segments.normals.source
    add_levels(meta, arrays, segments.levels)
    write_sections(path, segments.shape, segments.spacing, meta, arrays)


def add_levels(meta, arrays, levels):
    """Add coarser ``levels`` (:mod:`voxrender.object.levels`) to the ``meta`` and ``arrays`` of a file's object:
    their grids, and what their meta adds to the object's, in ``meta["levels"]``; their arrays named
    ``level1.starts`` and so on.
    """
    if not levels:
        return
    meta["levels"] = []
    for k, level in enumerate(levels, 1):
        own = {**level.meta, **({"normals_from": level.normals.source} if level.normals is not None else {})}
        meta["levels"].append({"shape": list(level.shape), "spacing": list(level.spacing),
                               "meta": {key: value for key, value in own.items() if meta.get(key) != value}})
        arrays.update({f"level{k}.{name}": array for name, array in _object_arrays(level).items()})


def _object_arrays(segments):
    """The arrays of one object: its runs, their labels, and its normals."""
    arrays = {"offsets": np.asarray(segments.offsets, "<i8"), "starts": np.asarray(segments.starts, "<i4"),
              "ends": np.asarray(segments.ends, "<i4")}
    if segments.labels is not None:
        arrays["labels"] = np.asarray(segments.labels, "<u2")
    if segments.normals is not None:
        index = np.asarray(segments.normals.index)          # int32 when the volume allows (surface_normals)
        arrays.update(normal_index=np.asarray(index, f"<i{index.dtype.itemsize}"),
                      normal_packed=np.asarray(segments.normals.packed, "<i2").ravel())
    return arrays


@dataclass(frozen=True)
class Spilled:
    """An array too large to hold, kept as files of its raw bytes written one after another (the parts a slab
    at a time made): ``count`` values of ``dtype`` in all.  :func:`write_sections` copies them into the file.
    """

    files: tuple
    count: int
    dtype: np.dtype

    @property
    def nbytes(self):
        """The bytes of the array."""
        return self.count * np.dtype(self.dtype).itemsize


def write_sections(path, shape, spacing, meta, arrays):
    """Write a ``.vxs`` file (atomically): its header and ``arrays`` (``{name: ndarray or Spilled}``, little-endian),
    each at a 64-byte aligned offset.  :func:`save` writes an object held in memory, :mod:`voxrender.object.stream` one
    made a slab at a time; both give the same bytes for the same object.
    """
    layout, position = {}, 0
    for name, array in arrays.items():
        count = array.count if isinstance(array, Spilled) else int(array.size)
        layout[name] = {"offset": position, "count": count, "dtype": np.dtype(array.dtype).str}
        position += -(-array.nbytes // _ALIGN) * _ALIGN
    header = json.dumps({"shape": list(shape), "spacing": list(spacing), "meta": meta, "arrays": layout}).encode()
    data_start = -(-(len(MAGIC) + 8 + len(header)) // _ALIGN) * _ALIGN
    with atomic_output(path) as tmp, open(tmp, "wb") as f:
        f.write(MAGIC + np.uint64(len(header)).tobytes() + header)
        for name, array in arrays.items():
            f.seek(data_start + layout[name]["offset"])
            if isinstance(array, Spilled):
                for part in array.files:
                    _copy_file(part, f)
            elif (span := file_span(array)) is not None and array.nbytes:     # a mapped file's, copied from it
                _copy_file(span[0], f, span[1], array.nbytes)
            else:          # in memory, a block at a time (a mapped one from its file: its pages do not stay)
                for block in blocks(np.ascontiguousarray(array).reshape(-1)):
                    f.write(block.data)                  # no copy of the bytes
        f.truncate(data_start + position)


def _copy_file(path, out, offset=0, size=None):
    """Append the bytes ``offset .. offset + size`` of the file at ``path`` (default: all) to the open file ``out``
    at its position: within the kernel where it can (``copy_file_range``: no pass through this process's memory,
    which halves the work of joining a streamed encode's parts, 6 GB of them for the 2048³ stack, or of writing a
    mapped object into a new file), else through a buffer.
    """
    out.flush()
    position, done = out.tell(), 0
    with open(path, "rb") as source:
        size = os.fstat(source.fileno()).st_size - offset if size is None else size
        try:
            while done < size:
                copied = os.copy_file_range(source.fileno(), out.fileno(), size - done, offset + done, position + done)
                if not copied:
                    break
                done += copied
        except (AttributeError, OSError):      # not Linux, or file systems it cannot copy between
            pass
        out.seek(position + done)
        source.seek(offset + done)
        while done < size:                      # what is left, if anything
            block = source.read(min(size - done, 16 << 20))
            if not block:
                raise OSError(f"{path} ended before its {size} bytes from {offset}")
            out.write(block)
            done += len(block)


def read_sections(path):
    """The header and the memory-mapped arrays of a ``.vxs`` file: ``(header, {name: array})``; each array is
    a view of the file's mapping (:func:`is_mapped`), read from disk as it is used.  An array the file does not
    hold whole, or of a type that is not a number, is a damaged file.
    """
    path = Path(path)
    try:
        size = path.stat().st_size
        with open(path, "rb") as f:
            start = f.read(len(MAGIC))
            if start != MAGIC:
                older = " written by an older voxrender; encode it again" if start.startswith(b"PK") else ""
                raise InputError(f"{path} is not a voxrender segments file (.vxs){older}")
            header_length = int(np.frombuffer(f.read(8), "<u8")[0])
            if header_length > size - len(MAGIC) - 8:
                raise _damaged(path, f"its header of {header_length} bytes is longer than the file")
            header = json.loads(f.read(header_length))
        data_start = -(-(len(MAGIC) + 8 + header_length) // _ALIGN) * _ALIGN
        raw = np.asarray(np.memmap(path, np.uint8, mode="r"))   # plain views of the mapping: no memmap overhead
        arrays = {}
        for name, spec in header["arrays"].items():
            begin, count = int(spec["offset"]), int(spec["count"])
            try:
                dtype = np.dtype(spec["dtype"])
            except TypeError:
                raise _damaged(path, f"its array {name} has no number type ({spec['dtype']!r})") from None
            if dtype.kind not in "biuf" or begin < 0 or count < 0 or data_start + begin + count * dtype.itemsize > size:
                raise _damaged(path, f"its array {name} ({count} of {dtype}) is not within the file")
            arrays[name] = raw[data_start + begin:data_start + begin + count * dtype.itemsize].view(dtype)
    except InputError:
        raise
    except (OSError, ValueError, KeyError, IndexError, TypeError, AttributeError) as exc:
        raise _damaged(path, f"{type(exc).__name__} in its header") from None
    return header, arrays


def _damaged(path, what):
    kind = ".vxo" if Path(path).suffix.lower() == ".vxo" else ".vxs"
    return InputError(f"{path} is a damaged {kind} file ({what}); encode it again")


def load(path):
    """Memory-map a ``.vxs`` file written by :func:`save`.

    >>> import tempfile, os
    >>> from voxrender.object.segments import encode
    >>> path = os.path.join(tempfile.mkdtemp(), "ball.vxs")
    >>> save(encode(np.ones((2, 2, 2), bool), meta={"threshold": 1}), path)
    >>> load(path).voxel_count
    8
    """
    return from_sections(*read_sections(path), path)


def from_sections(header, arrays, path):
    """The :class:`Segments` of a ``.vxs`` file's header and arrays (:func:`read_sections`), checked: runs that
    leave their grid or an index that does not add up is a damaged file, not a renderer's error later.  The
    coarser levels it keeps are checked alike and hang on its ``levels``; in a file with levels, whether each
    object's runs lie on its grid is checked when it is first drawn, so a picture from one level reads no other's.
    """
    meta = header.get("meta", {})
    if not isinstance(meta, dict):
        raise _damaged(path, "its meta is not a table of names")
    kept = meta.get("levels") or []
    if not isinstance(kept, list) or not all(isinstance(level, dict) for level in kept):
        raise _damaged(path, "its levels are not a list of grids")
    found = _object_of(header.get("shape"), header.get("spacing"),
                       {key: value for key, value in meta.items() if key != "levels"}, arrays, path, bool(kept))
    plain = {key: value for key, value in meta.items() if key not in ("levels", "normals_from")}
    levels = []
    for k, level in enumerate(kept, 1):
        prefix = f"level{k}."
        own = {name[len(prefix):]: array for name, array in arrays.items() if name.startswith(prefix)}
        differs = level.get("meta") or {}
        if not isinstance(differs, dict):
            raise _damaged(path, f"the meta of its level {k} is not a table of names")
        levels.append(_object_of(level.get("shape"), level.get("spacing"), {**plain, **differs}, own, path, True))
    found.levels = tuple(levels)
    return found


def _object_of(shape, spacing, meta, arrays, path, deferred=False):
    """One checked object of a file (its own, or a level's): see :func:`from_sections`; with ``deferred``, its
    runs are checked when first drawn (:meth:`~voxrender.object.segments.Segments.check`).
    """
    if not (isinstance(shape, list) and len(shape) == 3 and all(type(n) is int and n > 0 for n in shape)):
        raise _damaged(path, f"its shape {shape!r} is not three positive sizes")
    shape = tuple(shape)
    if not (isinstance(spacing, list) and len(spacing) == 3
            and all(type(v) in (int, float) and np.isfinite(v) and v > 0 for v in spacing)):
        raise _damaged(path, f"its spacing {spacing!r} is not three positive numbers")
    if not isinstance(meta, dict) or not isinstance(meta.get("label_table", {}), dict):
        raise _damaged(path, "its meta is not a table of names")
    missing = [name for name in ("offsets", "starts", "ends") if name not in arrays]
    if missing:
        raise _damaged(path, f"it lacks {', '.join(missing)}")
    if any(array.dtype.kind not in "iu" for array in arrays.values()):
        raise _damaged(path, "an array is not of integers")
    offsets, starts, ends = arrays["offsets"], arrays["starts"], arrays["ends"]
    if (offsets.size != shape[0] * shape[1] + 1 or offsets[0] != 0 or starts.size != offsets[-1]
            or ends.size != starts.size or np.any(offsets[1:] < offsets[:-1])):
        raise _damaged(path, "index and runs disagree")
    def off_grid(reads):                 # (read on the thread that checks them)
        first, last = (read() for read in reads)
        return bool(first.size and (first.min() < 0 or last.max() >= shape[2] or np.any(first > last)))

    def check_runs():
        if any(on_threads(off_grid, zip(block_reads(starts), block_reads(ends), strict=True))):
            raise _damaged(path, "runs leave their grid")

    if not deferred:
        check_runs()
    normals = None
    if "normal_index" in arrays:                 # files written before normals were kept have none
        index, packed = arrays["normal_index"], arrays.get("normal_packed", np.zeros(1, np.int16))
        if packed.size != 2 * index.size or index.size and (index[0] < 0 or index[-1] >= math.prod(shape)):
            raise _damaged(path, "surface normals and their voxels disagree")

        def rising(read):                # (read on the thread that checks it, with the next block's first)
            block = read()
            return bool(np.all(block[1:] > block[:-1]))

        def check_rising():         # read whole, so checked when first used: a picture of a level needs not
            if not all(on_threads(rising, block_reads(index, 1))):
                raise _damaged(path, "surface normals and their voxels disagree")

        normals = SurfaceNormals(shape, index, packed.reshape(-1, 2), str(meta.get("normals_from", "grey values")),
                                 check_rising)
    labels = arrays.get("labels")           # single-object files have none
    if labels is not None and labels.size != starts.size:
        raise _damaged(path, "runs and labels disagree")
    return Segments(shape, starts, ends, offsets, tuple(spacing), meta, normals, labels,
                    unchecked=check_runs if deferred else None)

