"""NRRD, ``.nrrd`` or ``.nhdr`` with a detached data file (pynrrd): raw, gzip or bzip2, oriented by its space.

A 4-D file gives the volume chosen by ``frame``; a 3D Slicer ``.seg.nrrd`` also gives its segments' names and
colours.  An early ``.seg.nrrd`` (3D Slicer before 4.11: ``space dimension: 4``, no ``space``, one binary volume a
segment along its fourth axis, cropped to ``Segmentation_Extent`` of a reference grid) is read as 3D Slicer reads
it: in RAS, shifted to its extent, each segment keeping its own voxels (:mod:`voxrender._shared.label_sets`).  A
folder of NRRD files is recognised, and refused with what it holds.  :func:`open_nrrd` gives the volume unread, a
slab at a time.

References
----------
3D Slicer, ``vtkMRMLSegmentationStorageNode::ReadBinaryLabelmapRepresentation4DSpatial`` (the early format's
reader) and ``vtkTeemNRRDReader`` (a space it cannot name is taken as RAS), https://github.com/Slicer/Slicer
"""

from __future__ import annotations

import contextlib
import os
import re
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._shared import label_sets
from .._shared.text import first_line
from ..errors import InputError
from ..space import orient
from ._shared import (
    Reader,
    Volume,
    check_fits,
    check_frame,
    check_spacing,
    folder_of_volumes,
    inflated_size,
    open_voxels,
    promised_bytes,
    read_voxels,
    volume_files,
)
from ._stack import Stack

SUFFIXES = (".nrrd", ".nhdr", ".seg.nrrd")
# NRRD's names of the encodings read here (the others, text, by pynrrd), and the axis kinds of a spatial volume
ENCODINGS = {"raw": "raw", "gzip": "gzip", "gz": "gzip", "bzip2": "bzip2", "bz2": "bzip2"}
SPATIAL_KINDS = {"domain", "space", "time", "none", "???"}


def read_nrrd(path, progress, frame=None):
    """Read a NRRD volume (of a 4-D file, the one ``frame`` names)."""
    stored, placement = _described(path, frame)
    with _bad_input(path):
        if stored.codec == "text":                          # what pynrrd reads is no bigger than the file
            check_fits(stored.shape, stored.dtype, path)
            with open(path, "rb") as f:
                f.seek(stored.offset)
                values = stored.read_text(f)
        else:
            with open(stored.source, "rb") as data:
                data.seek(stored.offset)
                values = read_voxels(data, stored.shape, stored.dtype, stored.source, stored.codec,
                                     skip=stored.skip, exact=stored.codec is None)
    if stored.segments:
        return _segment_volumes(values, placement, stored.header)
    if stored.frame_axis is not None:
        values = np.take(values, stored.frame, axis=stored.frame_axis)
    return Volume(values, *placement)


def _segment_volumes(values, placement, header):
    """The binary volumes of an early ``.seg.nrrd`` (segment after segment along numpy axis 0) as one map of label
    codes, segment ``k`` as label ``k + 1``: each keeps its own voxels, within its own ``SegmentK_Extent`` as 3D
    Slicer reads it.
    """
    spacing, meta, direction = placement
    corner = _extent(header, "Segmentation_Extent")[0::2]
    painter = label_sets.Painter(values.shape[1:], len(values))
    for index, segment in enumerate(values):
        inside = segment != 0
        own = _extent(header, f"Segment{index}_Extent")
        if own is not None:                                 # x, y, z bounds in the file's voxels, as z, y, x slices
            window = tuple(slice(max(lo, 0), max(hi + 1, 0)) for lo, hi in
                           zip(own[4::-2] - corner[::-1], own[5::-2] - corner[::-1], strict=True))
            kept = np.zeros_like(inside)
            kept[window] = inside[window]
            inside = kept
        painter.paint(index + 1, (slice(None),), inside)
    codes, sets = painter.finish()
    names = {int(k): v["name"] for k, v in meta.get("label_table", {}).items()}
    meta = {**meta, "overlap_rule": label_sets.RULE, "label_sets": sets,
            "overlaps": label_sets.overlap_report(codes, sets, names)}
    return Volume(codes, spacing, meta, direction)


def open_nrrd(path, frame=None):
    """A NRRD volume (of a 4-D file, the one ``frame`` names) as a :class:`~voxrender.io._stack.Stack`: raw slices
    read at their offset, gzip or bzip2 ones inflated by one stream read forward.

    A frame whose volumes follow each other (the frame axis the slowest) is read alone; of any other 4-D layout,
    each slab is read with the slices of every frame, and the frame taken from it (memory: the frames' count
    times the slab's).  Text encodings are read whole, as :func:`read_nrrd` reads them, and served from memory.
    """
    stored, (spacing, meta, direction) = _described(path, frame)
    if stored.codec == "text" or stored.segments:       # a label map: small, read whole
        values = read_nrrd(path, None, frame).values

        def read_slices(z0, z1):
            return values[z0:z1].astype(values.dtype.newbyteorder("="))

        return Stack(values.shape, values.dtype.newbyteorder("="), read_slices, spacing, direction, meta)
    shape, first, count, volume = stored.shape, 0, None, stored.shape
    if stored.frame_axis == 0:                                # frame after frame: one frame's slices
        shape, volume = (shape[0] * shape[1], *shape[2:]), shape[1:]
        first, count = stored.frame * volume[0], volume[0]
    elif stored.frame_axis is not None:                       # the frames within each slice: a slab of them all
        volume = tuple(n for axis, n in enumerate(shape) if axis != stored.frame_axis)
    with _bad_input(path):
        read, stored_bytes = open_voxels(stored.source, stored.offset, shape, stored.dtype, stored.codec,
                                         skip=stored.skip, exact=stored.codec is None, first=first, count=count)

    def read_slices(z0, z1):
        slab = read(z0, z1)
        return slab if stored.frame_axis in (None, 0) else np.take(slab, stored.frame, axis=stored.frame_axis)

    return Stack(volume, stored.dtype.newbyteorder("="), read_slices, spacing, direction, meta, stored_bytes,
                 sequential=stored.codec is not None)


@dataclass
class _Stored:
    """Where and how a NRRD file keeps its voxels: the C-ordered array ``shape`` of ``dtype`` in ``source`` from
    byte ``offset``, raw (``codec`` None), ``"gzip"`` or ``"bzip2"`` past ``skip`` inflated bytes, or ``"text"``
    (read by pynrrd, from ``offset`` of the header's file); of a 4-D file, the ``frame`` to take along numpy axis
    ``frame_axis``, or all of them as ``segments`` (an early ``.seg.nrrd``).
    """

    header: dict
    source: Path
    offset: int
    shape: tuple
    dtype: np.dtype
    codec: str | None
    skip: int = 0
    frame: int | None = None
    frame_axis: int | None = None
    segments: bool = False


    def read_text(self, f):
        """The voxels of a text encoding, read by pynrrd from ``f`` (at ``offset``) or its data file."""
        import nrrd

        return nrrd.read_data(self.header, f, str(self.source), index_order="C")


@contextlib.contextmanager
def _bad_input(path):
    """Turn pynrrd's errors, and those of its decoders (zlib, bz2: OSError), into bad input naming ``path`` (an
    empty file is StopIteration to pynrrd; an empty vector, IndexError).
    """
    import nrrd

    try:
        yield
    except InputError:
        raise
    except FileNotFoundError as exc:
        raise InputError(f"{path}: its data file {exc.filename or ''} is missing") from None
    except (nrrd.NRRDError, OSError, EOFError, ValueError, KeyError, TypeError, IndexError, zlib.error,
            StopIteration) as exc:
        raise InputError(f"cannot read {path} as NRRD: {first_line(exc)}") from None


def _described(path, frame):
    """Where the voxels of the NRRD file ``path`` are (a :class:`_Stored`), checked, and its volume's spacing, meta
    and direction: what :func:`read_nrrd` and :func:`open_nrrd` share.
    """
    import nrrd

    if path.is_dir():
        raise folder_of_volumes(path, "NRRD", SUFFIXES)
    with _bad_input(path), open(path, "rb") as f:
        header = nrrd.read_header(f)
        stored = _stored(path, f, header)
    ndim = len(stored.shape)
    if _early_slicer_segmentation(header):
        header = _in_three_dimensions(path, header)
        check_frame(path, frame)
        stored.segments = True
        spacing, meta, direction = _placement(path, header, _space_directions(path, header, 3), frame)
        meta["orientation_from"] = ("an early 3D Slicer segmentation: its space taken as RAS, as 3D Slicer takes "
                                    "one it cannot name, from the corner of its Segmentation_Extent")
        return stored, (spacing, meta, direction)
    directions = _space_directions(path, header, ndim)
    axes = [0, 1, 2]                                        # the header's axes (fastest first) of the volume read
    if ndim == 4:
        # the non-spatial axis: 'none' in space directions
        spatial = [d is not None for d in (directions if directions is not None else [None] * 4)]
        if sum(spatial) != 3:
            raise InputError(f"{path} is 4-D without three spatial axes; voxrender needs a 3-D volume")
        extra = spatial.index(False)                        # in NRRD's axis order (fastest first)
        stored.frame_axis = 3 - extra
        stored.frame = frame = check_frame(path, frame, stored.shape[3 - extra])
        directions = [d for d, s in zip(directions, spatial, strict=True) if s]
        axes = [k for k in range(4) if k != extra]
    else:
        check_frame(path, frame)
    if ndim - (ndim == 4) != 3:
        raise InputError(f"{path} holds a {ndim}-D array (a table or a picture), not a 3-D spatial volume")
    if directions is not None and any(d is None for d in directions):
        axis = axes[[d is None for d in directions].index(True)]
        raise InputError(f"{path}: its axis {axis} has no space direction ({_kind(header, axis)}), so it holds "
                         "values of another kind along it, not a 3-D spatial volume")
    non_spatial = [k for k in axes if _kind(header, k) not in SPATIAL_KINDS]
    if non_spatial:
        raise InputError(f"{path}: its axis {non_spatial[0]} is of kind {_kind(header, non_spatial[0])!r}, so it "
                         "is not a 3-D spatial volume")
    return stored, _placement(path, header, directions, frame)


def _placement(path, header, directions, frame):
    """The spacing, meta and direction of a NRRD volume, from its space and space directions (of the volume's
    three axes), else its spacings.
    """
    meta = {"spacing_from": "NRRD header"}
    space = str(header.get("space", "")).lower()
    sides = ("left", "right", "posterior", "anterior", "superior", "inferior")
    short = {"lps": "left-posterior-superior", "ras": "right-anterior-superior", "las": "left-anterior-superior"}
    space = short.get(space, space)
    if directions is not None:
        matrix = np.array(directions, dtype=float).T        # column k: the direction of NRRD axis k (x, y, z)
        spacing = tuple(float(v) for v in np.linalg.norm(matrix, axis=0))
        words = space.split("-")
        if len(words) == 3 and all(w in sides for w in words):
            try:     # the space's axes as an orientation code: column k, the LPS direction of world axis k
                to_lps = orient.direction_of("".join(w[0] for w in words))
            except InputError:
                raise InputError(f"{path}: NRRD space {header.get('space')!r} names a patient axis twice") from None
            direction = to_lps @ (matrix / np.array(spacing))
            meta["orientation_from"] = f"NRRD space {header.get('space')} and space directions"
            if header.get("space origin") is not None:
                origin = np.asarray(header["space origin"], dtype=float)
                if origin.shape != (3,) or not np.all(np.isfinite(origin)):
                    raise InputError(f"{path}: its space origin {origin.tolist()} is not three numbers; the header "
                                     "is damaged")
                meta["origin"] = (to_lps @ origin).tolist()
        else:
            direction = None
            meta["orientation_from"] = f"unknown: NRRD space {header.get('space', 'not given')!s} is not anatomical"
    else:
        spacings = header.get("spacings")
        spacing = tuple(float(v) for v in spacings) if spacings is not None else (1.0, 1.0, 1.0)
        direction = None
        meta["orientation_from"] = "unknown: NRRD without space directions"
    if direction is not None and abs(abs(np.linalg.det(direction)) - 1) > 1e-3:
        raise InputError(f"{path}: its space directions are not orthogonal; voxrender needs a rectilinear grid")
    table = _segment_table(header, 0 if frame is None else frame)
    if table:
        meta["label_table"] = table
    return check_spacing(spacing, path), meta, direction


def _stored(path, f, header):
    """Where the voxels ``header`` promises are (a :class:`_Stored`): in ``f`` (just past the header) or its data
    file; raw, gzip or bzip2 are read here, other encodings (text) by pynrrd.
    """
    from nrrd.reader import _determine_datatype  # pynrrd's own table of NRRD types

    missing = [key for key in ("dimension", "type", "encoding", "sizes") if key not in header]
    if missing:
        raise InputError(f"{path}: its NRRD header lacks {', '.join(missing)}; the header is damaged")
    sizes = [int(n) for n in np.atleast_1d(header["sizes"])]
    if header.get("dimension") != len(sizes) or min(sizes) < 1:
        raise InputError(f"{path}: its sizes {sizes} must be {header.get('dimension')} positive numbers (its "
                         "dimension); the header is damaged")
    dtype = _determine_datatype(header)
    encoding = ENCODINGS.get(header["encoding"])
    data_file = header.get("data file", header.get("datafile"))
    line_skip = int(header.get("line skip", header.get("lineskip", 0)))
    byte_skip = int(header.get("byte skip", header.get("byteskip", 0)))
    if line_skip < 0 or byte_skip < -1:
        raise InputError(f"{path}: its line skip {line_skip} or byte skip {byte_skip} is negative; the header is "
                         "damaged")
    if encoding is None:                                    # pynrrd skips lines and bytes itself
        return _Stored(header, path, f.tell(), tuple(sizes[::-1]), dtype, "text")
    source = path.parent / data_file if data_file is not None else path
    with open(source, "rb") if data_file is not None else contextlib.nullcontext(f) as data:
        for _ in range(line_skip):
            data.readline()
        offset = data.tell()
        if encoding == "raw":                                # byte skip -1: the voxels end the file
            held = os.fstat(data.fileno()).st_size - offset
            offset += max(held - promised_bytes(sizes, dtype), 0) if byte_skip == -1 else byte_skip
            return _Stored(header, source, offset, tuple(sizes[::-1]), dtype, None)
        if byte_skip == -1:                                  # the voxels end the inflated stream, as pynrrd reads it
            byte_skip = _skip_to_the_end(data, encoding, promised_bytes(sizes, dtype), path)
    return _Stored(header, source, offset, tuple(sizes[::-1]), dtype, encoding, skip=byte_skip)


def _skip_to_the_end(data, encoding, promised, path):
    """The inflated bytes before the voxels of compressed data whose byte skip is -1 (the voxels at its end), counted
    from ``data``'s place (put back) without keeping them, no further than the promised voxels and as many bytes
    again as the file holds: more would be a bomb, not a header before the voxels.
    """
    start = data.tell()
    limit = promised + os.fstat(data.fileno()).st_size
    inflated = inflated_size(data, encoding, limit)
    data.seek(start)
    if inflated > limit:
        raise InputError(f"{path}: its {encoding} data inflates beyond the {promised} bytes of voxels its header "
                         "promises and the file's own size (byte skip -1); the file is damaged")
    return max(inflated - promised, 0)


def _early_slicer_segmentation(header):
    """Whether ``header`` is an early 3D Slicer ``.seg.nrrd``'s: 4-D in a space of 4 dimensions it does not name,
    with the segments along its slowest axis, which has no extent in the first three.
    """
    directions = header.get("space directions")
    if header.get("dimension") != 4 or header.get("space dimension") != 4 or "space" in header:
        return False
    if "Segmentation_MasterRepresentation" not in header or directions is None:
        return False
    rows = np.asarray(directions, dtype=float)
    return rows.shape == (4, 4) and np.all(np.isfinite(rows)) and not np.any(rows[:3, 3]) and not np.any(rows[3, :3])


def _in_three_dimensions(path, header):
    """The header of an early ``.seg.nrrd`` as a 3-D volume's: its first three axes in RAS (the space 3D Slicer
    takes one it cannot name to be), the origin moved to the corner of ``Segmentation_Extent`` (the file holds that
    part of a reference grid whose corner its ``space origin`` gives).
    """
    rows = np.asarray(header["space directions"], dtype=float)[:3, :3]
    origin = np.asarray(header.get("space origin", np.zeros(4)), dtype=float)
    extent = _extent(header, "Segmentation_Extent")
    if origin.shape != (4,) or not np.all(np.isfinite(origin)) or extent is None:
        raise InputError(f"{path}: its space origin or Segmentation_Extent is not what an early 3D Slicer "
                         "segmentation holds (four numbers; six whole numbers); the header is damaged")
    return {**header, "space": "right-anterior-superior", "space directions": rows,
            "space origin": origin[:3] + extent[0::2] @ rows}


def _extent(header, key):
    """The six whole numbers (x from, x to, y.., z..) of a 3D Slicer extent in ``header``; ``None`` when absent or
    not six whole numbers.
    """
    try:
        extent = np.array([int(v) for v in str(header[key]).split()], dtype=np.int64)
    except (KeyError, ValueError):
        return None
    return extent if extent.shape == (6,) else None


def _kind(header, axis):
    """The NRRD kind of ``axis`` (fastest first), ``"domain"`` when the header gives none."""
    kinds = header.get("kinds") or []
    return str(kinds[axis]) if axis < len(kinds) else "domain"


def _space_directions(path, header, ndim):
    """The space direction of each axis (fastest first) as three finite numbers, or ``None`` for an axis that has
    none (``none`` in the header); ``None`` when the header gives no space directions.
    """
    directions = header.get("space directions")
    if directions is None:
        return None
    rows = np.asarray(directions, dtype=float)
    if rows.ndim != 2 or rows.shape != (ndim, 3):
        count, length = (rows.shape if rows.ndim == 2 else (rows.size, 1))
        raise InputError(f"{path}: its space directions are {count} vectors of {length} numbers; a {ndim}-D file "
                         f"in a 3-D space needs {ndim} vectors of 3 numbers")
    found = []
    for axis, row in enumerate(rows):
        if np.all(np.isnan(row)):
            found.append(None)
        elif not np.all(np.isfinite(row)) or not np.any(row):
            raise InputError(f"{path}: the space direction of its axis {axis} is {row.tolist()}, which has no "
                             "length; the header is damaged")
        else:
            found.append(row)
    return found


def _segment_table(header, layer=0):
    """The names and colours of a 3D Slicer ``.seg.nrrd``'s segments (``SegmentN_Name``, ``_Color`` as r g b in
    0..1, ``_LabelValue``, ``_Layer``) in ``layer``, as ``{"label": {"name", "colour": [r, g, b]}}``.
    """
    table = {}
    for key in header:
        match = re.fullmatch(r"Segment(\d+)_Name", str(key))
        if not match:
            continue
        prefix = f"Segment{match.group(1)}_"
        try:
            label = int(header.get(prefix + "LabelValue", int(match.group(1)) + 1))
            if int(header.get(prefix + "Layer", 0)) != layer:
                continue
            colour = str(header.get(prefix + "Color", header.get(prefix + "DefaultColor", "")))   # early: Default
            colour = [int(round(float(c) * 255)) for c in colour.split()]
        except ValueError:
            continue
        if label > 0 and len(colour) == 3 and all(0 <= c <= 255 for c in colour):
            table[str(label)] = {"name": str(header[key]), "colour": colour}
    return table


def holds_nrrd(path):
    """A folder of NRRD files (besides notes)."""
    return path.is_dir() and bool(volume_files(path, SUFFIXES))


READER = Reader(read_nrrd, SUFFIXES, options=("frame",), sniff=holds_nrrd, open=open_nrrd)
