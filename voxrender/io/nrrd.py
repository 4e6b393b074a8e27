"""NRRD, ``.nrrd`` or ``.nhdr`` with a detached data file (pynrrd): raw, gzip or bzip2, oriented by its space.

A 4-D file gives the volume chosen by ``frame``; a 3D Slicer ``.seg.nrrd`` also gives its segments' names and
colours.  A folder of NRRD files is recognised, and refused with what it holds.
"""

from __future__ import annotations

import re
import zlib

import numpy as np

from .. import orient
from ..errors import InputError
from ._shared import Reader, Volume, check_frame, check_spacing, first_line, folder_of_volumes, volume_files

SUFFIXES = (".nrrd", ".nhdr", ".seg.nrrd")


def read_nrrd(path, progress, frame=None):
    """Read a NRRD volume (of a 4-D file, the one ``frame`` names)."""
    import nrrd

    if path.is_dir():
        raise folder_of_volumes(path, "NRRD", SUFFIXES)
    try:               # pynrrd's errors, and those of its decoders (zlib, bz2: OSError); an empty file, StopIteration
        values, header = nrrd.read(str(path), index_order="C")
    except FileNotFoundError as exc:
        raise InputError(f"{path}: its data file {exc.filename or ''} is missing") from None
    except (nrrd.NRRDError, OSError, EOFError, ValueError, KeyError, TypeError, zlib.error, StopIteration) as exc:
        raise InputError(f"cannot read {path} as NRRD: {first_line(exc)}") from None
    directions = header.get("space directions")
    if values.ndim == 4:
        # the non-spatial axis: 'none' in space directions, or a list/vector kind
        spatial = [d is not None and not (isinstance(d, float) and np.isnan(d)) and np.all(np.isfinite(d))
                   for d in (directions if directions is not None else [None] * 4)]
        if directions is None or sum(spatial) != 3:
            raise InputError(f"{path} is 4-D without three spatial axes; voxrender needs a 3-D volume")
        extra = spatial.index(False)                        # in NRRD's axis order (fastest first)
        check_frame(path, frame, values.shape[3 - extra])
        values = np.take(values, frame, axis=3 - extra)
        directions = [d for d, s in zip(directions, spatial, strict=True) if s]
    else:
        check_frame(path, frame)
    if values.ndim != 3:
        raise InputError(f"{path} holds a {values.ndim}-D array; voxrender needs a 3-D volume")
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
                meta["origin"] = (to_lps @ np.asarray(header["space origin"], dtype=float)).tolist()
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
