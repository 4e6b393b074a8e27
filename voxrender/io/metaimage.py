"""MetaImage (ITK): a ``.mhd`` text header beside its data file, or a ``.mha`` holding both; raw or zlib.

MetaImage has no library here: the header is ``Key = Value`` lines up to ``ElementDataFile``.
:func:`open_metaimage` gives the volume unread, a slab at a time.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._shared.text import first_line
from ..errors import InputError
from ..space import orient
from ._shared import (
    Reader,
    Volume,
    check_spacing,
    files_in,
    folder_of_volumes,
    listed,
    open_voxels,
    promised_bytes,
    read_voxels,
)
from ._stack import Stack

SUFFIXES = (".mhd", ".mha")

ELEMENT_TYPES = {"MET_UCHAR": "u1", "MET_CHAR": "i1", "MET_USHORT": "u2", "MET_SHORT": "i2",
                   "MET_UINT": "u4", "MET_INT": "i4", "MET_ULONG": "u8", "MET_LONG": "i8",
                   "MET_ULONG_LONG": "u8", "MET_LONG_LONG": "i8", "MET_FLOAT": "f4", "MET_DOUBLE": "f8"}


def read_metaimage(path, progress):
    """Read a MetaImage header and its voxels; of a folder, the one MetaImage it holds."""
    stored, (spacing, meta, direction) = _described(path)
    with open(stored.source, "rb") as f:
        f.seek(stored.offset)
        values = read_voxels(f, stored.shape, stored.dtype, stored.source, stored.codec)
    return Volume(values.astype(stored.dtype.newbyteorder("="), copy=False), spacing, meta, direction)


def open_metaimage(path):
    """A MetaImage volume as a :class:`~voxrender.io._stack.Stack`: raw slices read at their offset, zlib ones
    inflated by one stream read forward.
    """
    stored, (spacing, meta, direction) = _described(path)
    read_slices, stored_bytes = open_voxels(stored.source, stored.offset, stored.shape, stored.dtype, stored.codec)
    return Stack(stored.shape, stored.dtype.newbyteorder("="), read_slices, spacing, direction, meta, stored_bytes,
                 sequential=stored.codec is not None)


@dataclass(frozen=True)
class _Stored:
    """Where a MetaImage keeps its voxels: the C-ordered array ``shape`` of ``dtype`` in ``source`` from byte
    ``offset``, raw (``codec`` None) or ``"zlib"``.
    """

    source: Path
    offset: int
    shape: tuple
    dtype: np.dtype
    codec: str | None


def _described(path):
    """Where the voxels of the MetaImage ``path`` (of a folder, the one it holds) are (a :class:`_Stored`),
    checked, and its volume's spacing, meta and direction: what :func:`read_metaimage` and :func:`open_metaimage`
    share.
    """
    if path.is_dir():
        headers = [f for f in files_in(path) if f.suffix.lower() in SUFFIXES]
        if len(headers) != 1:
            raise folder_of_volumes(path, "MetaImage", SUFFIXES)
        path = headers[0]
    header, data_offset = {}, None
    with open(path, "rb") as f:
        for raw_line in f:
            line = raw_line.decode("latin-1").strip()
            if not line:
                continue
            key, sep, value = line.partition("=")
            if not sep:
                raise InputError(f"{path}: header line {line[:60]!r} is not 'Key = Value'; not a MetaImage")
            header[key.strip()] = value.strip()
            if key.strip() == "ElementDataFile":
                data_offset = f.tell()
                break
    try:
        dims = [int(v) for v in header["DimSize"].split()]
        dtype = np.dtype(ELEMENT_TYPES[header["ElementType"]])
        data_file = header["ElementDataFile"]
        channels, header_size = int(header.get("ElementNumberOfChannels", 1)), int(header.get("HeaderSize", 0))
    except KeyError as exc:
        raise InputError(f"{path}: MetaImage header lacks {exc.args[0]} or has an unknown ElementType") from None
    except ValueError as exc:
        raise InputError(f"{path}: a MetaImage header value is not a whole number ({first_line(exc)})") from None
    if len(dims) != 3:
        raise InputError(f"{path}: a {len(dims)}-D MetaImage; voxrender needs a 3-D volume")
    if min(dims) < 1:
        raise InputError(f"{path}: its DimSize {dims} must be three positive sizes; the header is damaged")
    if channels != 1:
        raise InputError(f"{path}: MetaImage with several channels per voxel; give a single-channel volume")
    msb = header.get("ElementByteOrderMSB", header.get("BinaryDataByteOrderMSB", "False"))
    dtype = dtype.newbyteorder(">" if msb.lower() == "true" else "<")
    spacing = header.get("ElementSpacing", header.get("ElementSize", "1 1 1")).split()
    nbytes = promised_bytes(dims, dtype)
    if data_file == "LOCAL":
        source, offset = path, data_offset
    elif data_file.split()[:1] == ["LIST"] or "%" in data_file:
        raise InputError(f"{path}: MetaImage slice lists ({data_file}) are not supported; "
                         "give the slices as a folder instead")
    else:
        source, offset = path.parent / data_file, 0
        if not source.is_file():
            raise InputError(f"{path}: its data file {source} is missing")
    compressed = header.get("CompressedData", "False").lower() == "true"
    if header_size == -1:                                # the voxels end the file
        if compressed:
            raise InputError(f"{path}: HeaderSize -1 (the voxels at the end) with compressed data; the header is "
                             "damaged")
        offset = max(source.stat().st_size - nbytes, offset)
    elif header_size > 0:
        offset += header_size
    stored = _Stored(source, offset, tuple(dims[::-1]), dtype, "zlib" if compressed else None)
    direction, orientation_from = _metaimage_direction(header, path)
    meta = {"spacing_from": "MetaImage header", "orientation_from": orientation_from}
    for key in ("Offset", "Origin", "Position"):
        if key in header:
            try:
                origin = [float(v) for v in header[key].split()][:3]
            except ValueError:
                origin = []
            if len(origin) == 3 and all(np.isfinite(origin)):      # else it is left out, as one unsaid
                meta["origin"] = origin
            break
    meta["source"] = str(path)
    return stored, (check_spacing(spacing, path), meta, direction)


def _metaimage_direction(header, path):
    """MetaImage's orientation: TransformMatrix (row k: the LPS direction of voxel axis k, ITK's frame), else
    AnatomicalOrientation (ITK's letters name the side each axis comes *from*: RAI is LPS).
    """
    if "TransformMatrix" in header:
        try:
            rows = np.array([float(v) for v in header["TransformMatrix"].split()]).reshape(3, 3)
        except ValueError:
            raise InputError(f"{path}: TransformMatrix {header['TransformMatrix']!r} is not nine numbers") from None
        if abs(abs(np.linalg.det(rows)) - 1) > 1e-3:
            raise InputError(f"{path}: TransformMatrix is not a rotation (its determinant is {np.linalg.det(rows):g})")
        return rows.T, "MetaImage TransformMatrix"
    code = header.get("AnatomicalOrientation", "").strip().upper()
    if len(code) == 3 and "?" not in code:
        opposite = {"L": "R", "R": "L", "P": "A", "A": "P", "S": "I", "I": "S"}
        try:
            return orient.direction_of("".join(opposite.get(c, "?") for c in code)), "MetaImage AnatomicalOrientation"
        except InputError:
            raise InputError(f"{path}: AnatomicalOrientation {code!r} is not an orientation code") from None
    return None, "unknown: the MetaImage header does not say"


def holds_metaimage(path):
    """A folder holding a MetaImage header (one is read, several are listed)."""
    return path.is_dir() and any(f.suffix.lower() in SUFFIXES for f in listed(path))


READER = Reader(read_metaimage, SUFFIXES, sniff=holds_metaimage, open=open_metaimage)
