"""NRRD, ``.nrrd`` or ``.nhdr`` with a detached data file (pynrrd): raw, gzip or bzip2, oriented by its space.

A 4-D file gives the volume chosen by ``frame``; a 3D Slicer ``.seg.nrrd`` also gives its segments' names and
colours.  A folder of NRRD files is recognised, and refused with what it holds.
"""

from __future__ import annotations

import contextlib
import os
import re
import zlib

import numpy as np

from .. import orient
from ..errors import InputError
from ._shared import (
    Reader,
    Volume,
    check_fits,
    check_frame,
    check_spacing,
    first_line,
    folder_of_volumes,
    promised_bytes,
    read_voxels,
    volume_files,
)

SUFFIXES = (".nrrd", ".nhdr", ".seg.nrrd")
# NRRD's names of the encodings read here (the others, text, by pynrrd), and the axis kinds of a spatial volume
ENCODINGS = {"raw": "raw", "gzip": "gzip", "gz": "gzip", "bzip2": "bzip2", "bz2": "bzip2"}
SPATIAL_KINDS = {"domain", "space", "time", "none", "???"}


def read_nrrd(path, progress, frame=None):
    """Read a NRRD volume (of a 4-D file, the one ``frame`` names)."""
    import nrrd

    if path.is_dir():
        raise folder_of_volumes(path, "NRRD", SUFFIXES)
    try:               # pynrrd's errors, and those of its decoders (zlib, bz2: OSError); an empty file, StopIteration
        with open(path, "rb") as f:
            header = nrrd.read_header(f)
            values = _read_voxels(path, f, header)
    except InputError:
        raise
    except FileNotFoundError as exc:
        raise InputError(f"{path}: its data file {exc.filename or ''} is missing") from None
    except (nrrd.NRRDError, OSError, EOFError, ValueError, KeyError, TypeError, IndexError, zlib.error,
            StopIteration) as exc:                  # IndexError: pynrrd parsing an empty vector
        raise InputError(f"cannot read {path} as NRRD: {first_line(exc)}") from None
    directions = _space_directions(path, header, values.ndim)
    axes = [0, 1, 2]                                        # the header's axes (fastest first) of the volume read
    if values.ndim == 4:
        # the non-spatial axis: 'none' in space directions
        spatial = [d is not None for d in (directions if directions is not None else [None] * 4)]
        if sum(spatial) != 3:
            raise InputError(f"{path} is 4-D without three spatial axes; voxrender needs a 3-D volume")
        extra = spatial.index(False)                        # in NRRD's axis order (fastest first)
        frame = check_frame(path, frame, values.shape[3 - extra])
        values = np.take(values, frame, axis=3 - extra)
        directions = [d for d, s in zip(directions, spatial, strict=True) if s]
        axes = [k for k in range(4) if k != extra]
    else:
        check_frame(path, frame)
    if values.ndim != 3:
        raise InputError(f"{path} holds a {values.ndim}-D array (a table or a picture), not a 3-D spatial volume")
    if directions is not None and any(d is None for d in directions):
        axis = axes[[d is None for d in directions].index(True)]
        raise InputError(f"{path}: its axis {axis} has no space direction ({_kind(header, axis)}), so it holds "
                         "values of another kind along it, not a 3-D spatial volume")
    non_spatial = [k for k in axes if _kind(header, k) not in SPATIAL_KINDS]
    if non_spatial:
        raise InputError(f"{path}: its axis {non_spatial[0]} is of kind {_kind(header, non_spatial[0])!r}, so it "
                         "is not a 3-D spatial volume")
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
    return Volume(values, check_spacing(spacing, path), meta, direction)


def _read_voxels(path, f, header):
    """The voxels ``header`` promises, read from ``f`` (just past the header) or its data file: raw, gzip or bzip2
    are read here, with their sizes checked before allocating; other encodings (text) by pynrrd.
    """
    import nrrd
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
    if encoding is None:                                    # text: what pynrrd reads is no bigger than the file
        check_fits(sizes, dtype, path)
        return nrrd.read_data(header, f, str(path), index_order="C")
    if byte_skip == -1 and encoding != "raw":
        raise InputError(f"{path}: byte skip -1 (the voxels at the end) with {encoding} data is not supported; "
                         "give the data uncompressed")
    source = path.parent / data_file if data_file is not None else path
    with open(source, "rb") if data_file is not None else contextlib.nullcontext(f) as data:
        for _ in range(line_skip):
            data.readline()
        if encoding == "raw":                                # byte skip -1: the voxels end the file
            held = os.fstat(data.fileno()).st_size - data.tell()
            data.seek(max(held - promised_bytes(sizes, dtype), 0) if byte_skip == -1 else byte_skip, os.SEEK_CUR)
            return read_voxels(data, sizes[::-1], dtype, source, exact=True)
        return read_voxels(data, sizes[::-1], dtype, source, encoding, skip=byte_skip)


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
            colour = [int(round(float(c) * 255)) for c in str(header.get(prefix + "Color", "")).split()]
        except ValueError:
            continue
        if label > 0 and len(colour) == 3 and all(0 <= c <= 255 for c in colour):
            table[str(label)] = {"name": str(header[key]), "colour": colour}
    return table


def holds_nrrd(path):
    """A folder of NRRD files (besides notes)."""
    return path.is_dir() and bool(volume_files(path, SUFFIXES))


READER = Reader(read_nrrd, SUFFIXES, options=("frame",), sniff=holds_nrrd)
