"""Reading slice stacks into a :class:`Volume`.

Supported inputs (detected from the path, or named with ``format=``):

========== ==========================================================================
format     what
========== ==========================================================================
images     a folder of 2-D images (PNG, TIFF, BMP, JPEG), in natural order of names
dicom      a folder holding a DICOM series, ordered by ImagePositionPatient
metaimage  a MetaImage ``.mhd`` (header + raw file) or ``.mha`` (one file), raw or zlib
raw        headerless slices: a folder of files or one file, with ``raw=RawLayout(...)``
npy        a 3-D NumPy ``.npy`` array ``[z, y, x]``
tiff       a multi-page TIFF, one page a slice
========== ==========================================================================

Readers stream: the volume array is allocated once and filled slice by slice.

Adding a reader is one function ``read(path, progress, **options) -> Volume`` and one
:class:`Reader` record in ``READERS`` (see ``docs/design.md``).
"""

from __future__ import annotations

import re
import warnings
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from .errors import InputError

__all__ = ["Volume", "RawLayout", "Reader", "READERS", "FORMATS", "read_volume", "detect_format", "natural_key",
           "check_spacing"]

IMAGE_EXTENSIONS = {".png", ".tif", ".tiff", ".bmp", ".jpg", ".jpeg"}
DICOM_EXTENSIONS = {".dcm", ".dicom", ".ima"}
# Files that sit beside raw slices but are not slices (headers and notes).
NOT_SLICE_EXTENSIONS = {".nhdr", ".nrrd", ".mhd", ".hdr", ".txt", ".md", ".json", ".csv", ".xml", ".ini", ".py"}


@dataclass
class Volume:
    """A stack of slices: ``values[z, y, x]`` with voxel ``spacing`` (x, y, z) in mm.

    Examples
    --------
    >>> v = Volume(np.zeros((3, 4, 5), np.int16), (0.5, 0.5, 2.0))
    >>> v.shape
    (3, 4, 5)
    """

    values: np.ndarray
    spacing: tuple[float, float, float] = (1.0, 1.0, 1.0)
    meta: dict = field(default_factory=dict)

    @property
    def shape(self):
        return self.values.shape


def natural_key(name):
    """Sort key that orders ``quarter.2`` before ``quarter.10``.

    >>> sorted(["s10.png", "s2.png", "s1.png"], key=natural_key)
    ['s1.png', 's2.png', 's10.png']
    """
    return [(0, int(part), "") if part.isdigit() else (1, 0, part.lower())
            for part in re.split(r"(\d+)", str(name)) if part]


def _identity_progress(iterable, length=None, label=None):
    return iterable


@dataclass(frozen=True)
class RawLayout:
    """How headerless slices are laid out: ``width`` x ``height`` values of ``dtype`` (with its byte order).

    >>> RawLayout(64, 64, np.dtype("<u2")).slice_bytes
    8192
    """

    width: int
    height: int
    dtype: np.dtype

    def __post_init__(self):
        if int(self.width) < 1 or int(self.height) < 1:
            raise InputError(f"width and height must be positive, not {self.width}x{self.height}", parameter="raw")
        if np.dtype(self.dtype).kind not in "uif":
            raise InputError(f"dtype {np.dtype(self.dtype).name!r} is not numeric", parameter="raw")

    @property
    def slice_bytes(self):
        return int(self.width) * int(self.height) * np.dtype(self.dtype).itemsize


def _files_in(folder):
    files = sorted((p for p in folder.iterdir() if p.is_file() and not p.name.startswith(".")),
                   key=lambda p: natural_key(p.name))
    if not files:
        raise InputError(f"{folder} is an empty folder; give a folder of slices")
    return files


def _dicom_files(folder):
    """DICOM files in ``folder``; when it holds none itself, those anywhere below it (exports nest them)."""
    files = [p for p in folder.iterdir() if p.is_file() and not p.name.startswith(".") and _is_dicom(p)]
    if not files:
        files = [p for p in folder.rglob("*") if p.is_file() and not any(part.startswith(".") for part in
                                                                            p.relative_to(folder).parts)
                 and _is_dicom(p)]
    return sorted((p for p in files if p.name.upper() != "DICOMDIR"), key=lambda p: natural_key(str(p)))


def _is_dicom(path):
    if path.suffix.lower() in DICOM_EXTENSIONS:
        return True
    try:
        with open(path, "rb") as f:
            f.seek(128)
            return f.read(4) == b"DICM"
    except OSError:
        return False


def detect_format(path, raw=None):
    """Name the format of ``path`` (see the module table)."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"no such file or folder: {path}")
    if raw is not None:
        return "raw"
    if path.is_file():
        name = path.name.lower()
        for format, reader in READERS.items():
            if any(name.endswith(suffix) for suffix in reader.suffixes):
                return format
        if path.suffix.lower() in DICOM_EXTENSIONS or _is_dicom(path):
            raise InputError(f"{path} is one DICOM file; give the folder that holds the whole series")
        raise InputError(f"cannot tell the format of {path}; give a folder of slices, .mhd/.mha, .npy, "
                         "a multi-page .tif, or the layout of headerless slices", parameter="format")
    if not any(p.is_file() for p in path.iterdir()) and not any(p.is_dir() for p in path.iterdir()):
        raise InputError(f"{path} is an empty folder; give a folder of slices")
    if _dicom_files(path):
        return "dicom"
    files = _files_in(path)
    if any(f.suffix.lower() in IMAGE_EXTENSIONS for f in files):
        return "images"
    metaimages = [f for f in files if f.suffix.lower() in (".mhd", ".mha")]
    if len(metaimages) == 1:
        return "metaimage"
    raise InputError(f"{path} holds no DICOM files or images (PNG, TIFF, BMP, JPEG); "
                     "for headerless slices give their layout", parameter="raw")


def read_volume(path, *, format="auto", raw=None, spacing=None, series=None, progress=None):
    """Read a slice stack into a :class:`Volume`.

    Parameters
    ----------
    path : str or Path
        A folder of slices or a volume file.
    format : str
        ``"auto"`` (detect it) or a name in ``READERS``: ``images, dicom, metaimage, raw, npy, tiff``.
    raw : RawLayout, optional
        The layout of headerless slices (implies ``format="raw"``).
    spacing : sequence of 3 floats, optional
        Voxel spacing (x, y, z) in mm; overrides what the files say.
    series : str, optional
        SeriesInstanceUID to read when a DICOM folder holds several series.
    progress : callable, optional
        ``progress(iterable, length, label)`` wraps the slice loop (a progress bar).

    Returns
    -------
    Volume

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> np.save(folder / "v.npy", np.arange(24, dtype=np.int16).reshape(2, 3, 4))
    >>> read_volume(folder / "v.npy").shape
    (2, 3, 4)
    """
    path = Path(path)
    progress = progress or _identity_progress
    if format != "auto" and format not in READERS:
        raise InputError(f"unknown format {format!r}; choose one of auto, {', '.join(READERS)}", parameter="format")
    if format == "auto":
        format = detect_format(path, raw)
    elif not path.exists():
        raise InputError(f"no such file or folder: {path}")
    if format == "raw" and raw is None:
        raise InputError("raw slices need their layout: width, height, dtype and byte order", parameter="raw")
    if format == "metaimage" and path.is_dir():
        path = next(f for f in _files_in(path) if f.suffix.lower() in (".mhd", ".mha"))
    reader = READERS[format]
    given = {"raw": raw, "series": series}
    for name, value in given.items():
        if value is not None and name not in reader.options:
            raise InputError(f"{format} input takes no {name}", parameter=name)
    volume = reader.function(path, progress, **{name: given[name] for name in reader.options})
    volume.meta.setdefault("format", format)
    volume.meta.setdefault("source", str(path))
    if spacing is not None:
        volume.spacing = check_spacing(spacing)
        volume.meta["spacing_from"] = "given"
    if volume.values.ndim != 3 or min(volume.values.shape) < 1:
        raise InputError(f"{path} does not hold a 3-D stack (shape {volume.values.shape})")
    return volume


def check_spacing(spacing, source=None):
    """``spacing`` as three positive floats (x, y, z) in mm; ``source`` names the file it came from, if any.

    >>> check_spacing([1, 1, 2.5])
    (1.0, 1.0, 2.5)
    """
    where = f"{source}: " if source else ""
    try:
        values = tuple(float(s) for s in spacing)
    except (TypeError, ValueError):
        values = ()
    if len(values) != 3 or not all(np.isfinite(v) and v > 0 for v in values):
        raise InputError(f"{where}spacing must be three positive numbers x, y, z in mm, not {spacing}",
                         parameter=None if source else "spacing")
    return values


def _to_grey(image, name):
    """A 2-D slice from an image file; colour images become luminance in their own units."""
    if image.ndim == 3 and image.shape[-1] in (3, 4):
        rgb = image[..., :3]
        if np.all(rgb == rgb[..., :1]):
            return rgb[..., 0]
        return (rgb @ np.array([0.2125, 0.7154, 0.0721])).astype(np.float32)
    if image.ndim != 2:
        raise InputError(f"{name} is not a 2-D image (shape {image.shape}); slices must be single images")
    return image


def _fill_stack(items, read_slice, label, progress):
    """Allocate the volume from the first slice, then fill it slice by slice."""
    volume = None
    for z, item in enumerate(progress(items, len(items), label)):
        data, name = read_slice(item)
        if volume is None:
            volume = np.empty((len(items),) + data.shape, dtype=data.dtype)
            first = name
        if data.shape != volume.shape[1:]:
            raise InputError(f"slice {name} is {data.shape[1]}x{data.shape[0]} but {first} is "
                             f"{volume.shape[2]}x{volume.shape[1]}; all slices must have the same size")
        if np.can_cast(data.dtype, volume.dtype, "safe"):
            volume[z] = data
        else:  # a later slice needs a wider type: widen once, keep going
            volume = volume.astype(np.result_type(volume.dtype, data.dtype))
            volume[z] = data
    return volume


def _read_images(folder, progress):
    import imageio.v3 as iio

    files = [f for f in _files_in(folder) if f.suffix.lower() in IMAGE_EXTENSIONS]
    if not files:
        raise InputError(f"{folder} holds no images (PNG, TIFF, BMP, JPEG)")

    def read(f):
        try:
            return _to_grey(iio.imread(f), f.name), f.name
        except InputError:
            raise
        except Exception as exc:  # imageio raises many types for a bad file
            raise InputError(f"cannot read image {f}: {_short(exc)}") from None

    values = _fill_stack(files, read, "reading images", progress)
    return Volume(values, (1.0, 1.0, 1.0), {"spacing_from": "default (images carry no spacing)",
                                            "slices": len(files)})


def _short(exc):
    text = str(exc).strip().splitlines()
    return (text[0] if text else type(exc).__name__)[:200]


def _read_dicom(folder, progress, series=None):
    import pydicom
    from pydicom.errors import InvalidDicomError

    files = _dicom_files(folder)
    if not files:
        raise InputError(f"{folder} holds no DICOM files")
    headers = []
    for f in progress(files, len(files), "reading DICOM headers"):
        try:
            ds = pydicom.dcmread(f, stop_before_pixels=True)
        except (InvalidDicomError, OSError, EOFError, ValueError, TypeError, KeyError) as exc:
            raise InputError(f"cannot read DICOM file {f}: {_short(exc)}") from None
        missing = [key for key in ("SeriesInstanceUID", "Rows", "Columns") if key not in ds]
        if missing:
            raise InputError(f"DICOM file {f} is damaged or not an image slice (no {', '.join(missing)}); "
                             "move it out of the folder")
        headers.append((f, ds))
    groups = {}
    for f, ds in headers:
        groups.setdefault(str(ds.SeriesInstanceUID), []).append((f, ds))
    if series is not None:
        if series not in groups:
            raise InputError(f"no series {series} in {folder}; it holds {_list_series(groups)}", parameter="series")
        chosen = groups[series]
    elif len(groups) > 1:
        raise InputError(f"{folder} holds {len(groups)} DICOM series; choose one by its UID: "
                         f"{_list_series(groups)}", parameter="series")
    else:
        chosen = next(iter(groups.values()))
    chosen, spacing_z, sorted_by = _sort_dicom(chosen)
    first = chosen[0][1]
    for f, ds in chosen:
        if (getattr(ds, "Rows", None), getattr(ds, "Columns", None)) != (first.Rows, first.Columns):
            raise InputError(f"slice {f.name} is {ds.Columns}x{ds.Rows} but {chosen[0][0].name} is "
                             f"{first.Columns}x{first.Rows}; all slices must have the same size")
    if int(getattr(first, "NumberOfFrames", 1) or 1) > 1:
        raise InputError(f"{chosen[0][0]} is a multi-frame DICOM; voxrender reads one slice per file")
    if "PixelSpacing" not in first:
        warnings.warn("the DICOM series has no PixelSpacing; using 1 mm (give the spacing if that is wrong)",
                      stacklevel=2)
    pixel = [float(v) for v in getattr(first, "PixelSpacing", [1.0, 1.0])]

    def read(item):
        f, _ = item
        ds = None
        try:
            ds = pydicom.dcmread(f)
            data = ds.pixel_array
        except Exception as exc:  # pydicom raises many types for truncated or compressed data
            syntax = getattr(getattr(ds, "file_meta", None), "TransferSyntaxUID", None)
            hint = f" (transfer syntax {syntax.name})" if syntax is not None and syntax.is_compressed else ""
            raise InputError(f"cannot read the pixels of DICOM file {f}{hint}: {_short(exc)}") from None
        slope = float(getattr(ds, "RescaleSlope", 1) or 1)
        intercept = float(getattr(ds, "RescaleIntercept", 0) or 0)
        if slope.is_integer() and intercept.is_integer():
            data = data.astype(np.int32) * int(slope) + int(intercept)
            if data.size and np.iinfo(np.int16).min <= data.min() and data.max() <= np.iinfo(np.int16).max:
                data = data.astype(np.int16)
        else:
            data = (data * np.float32(slope) + np.float32(intercept)).astype(np.float32)
        return data, f.name

    values = _fill_stack(chosen, read, "reading DICOM slices", progress)
    meta = {"slices": len(chosen), "series": str(getattr(first, "SeriesInstanceUID", "")),
            "description": str(getattr(first, "SeriesDescription", "")),
            "modality": str(getattr(first, "Modality", "")),
            "units": "HU" if str(getattr(first, "Modality", "")) == "CT" else "stored values",
            "sorted_by": sorted_by, "spacing_from": "DICOM"}
    return Volume(values, (pixel[1], pixel[0], spacing_z), meta)


def _list_series(groups):
    return "; ".join(f"{uid} ({len(items)} slices, {getattr(items[0][1], 'SeriesDescription', '')!s})"
                     for uid, items in groups.items())


def _sort_dicom(items):
    """Order slices along the slice normal; return (items, slice spacing, how they were sorted)."""
    try:
        first = items[0][1]
        orientation = (np.array([float(v) for v in first.ImageOrientationPatient])
                       if "ImageOrientationPatient" in first else np.array([1.0, 0, 0, 0, 1, 0]))  # axial
        normal = np.cross(orientation[:3], orientation[3:])
        positions = np.array([np.dot([float(v) for v in ds.ImagePositionPatient], normal) for _, ds in items])
        how = "ImagePositionPatient"
    except (AttributeError, ValueError, TypeError):
        try:
            positions = np.array([float(ds.InstanceNumber) for _, ds in items])
            how = "InstanceNumber"
        except (AttributeError, ValueError, TypeError):
            raise InputError(f"{items[0][0].parent}: DICOM slices have neither ImagePositionPatient nor "
                             "InstanceNumber, so their order is unknown") from None
    order = np.argsort(positions, kind="stable")
    items = [items[i] for i in order]
    positions = positions[order]
    steps = np.diff(positions)
    if len(steps) and np.any(np.isclose(steps, 0)):
        k = int(np.argmax(np.isclose(steps, 0)))
        raise InputError(f"DICOM slices {items[k][0].name} and {items[k + 1][0].name} share one position; "
                         "the folder mixes acquisitions: keep one in the folder")
    first = items[0][1]
    fallback = float(getattr(first, "SpacingBetweenSlices", 0) or getattr(first, "SliceThickness", 0) or 1.0)
    if how != "ImagePositionPatient" or not len(steps):
        return items, abs(fallback), how
    spacing = float(np.median(steps))
    if np.ptp(steps) > max(0.01, 0.01 * spacing):
        warnings.warn(f"slice spacing varies from {steps.min():g} to {steps.max():g} mm; using the median "
                      f"{spacing:g} mm", stacklevel=2)
    return items, spacing, how


METAIMAGE_TYPES = {"MET_UCHAR": "u1", "MET_CHAR": "i1", "MET_USHORT": "u2", "MET_SHORT": "i2",
                   "MET_UINT": "u4", "MET_INT": "i4", "MET_ULONG": "u8", "MET_LONG": "i8",
                   "MET_ULONG_LONG": "u8", "MET_LONG_LONG": "i8", "MET_FLOAT": "f4", "MET_DOUBLE": "f8"}


def _read_metaimage(path, progress):
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
        dtype = np.dtype(METAIMAGE_TYPES[header["ElementType"]])
        data_file = header["ElementDataFile"]
    except KeyError as exc:
        raise InputError(f"{path}: MetaImage header lacks {exc.args[0]} or has an unknown ElementType") from None
    if len(dims) != 3:
        raise InputError(f"{path}: a {len(dims)}-D MetaImage; voxrender needs a 3-D volume")
    if int(header.get("ElementNumberOfChannels", 1)) != 1:
        raise InputError(f"{path}: MetaImage with several channels per voxel; give a single-channel volume")
    msb = header.get("ElementByteOrderMSB", header.get("BinaryDataByteOrderMSB", "False"))
    dtype = dtype.newbyteorder(">" if msb.lower() == "true" else "<")
    spacing = header.get("ElementSpacing", header.get("ElementSize", "1 1 1")).split()
    nbytes = int(np.prod(dims)) * dtype.itemsize
    if data_file == "LOCAL":
        source, offset = path, data_offset
    elif data_file.split()[0] == "LIST" or "%" in data_file:
        raise InputError(f"{path}: MetaImage slice lists ({data_file}) are not supported; "
                         "give the slices as a folder instead")
    else:
        source, offset = path.parent / data_file, 0
        if not source.is_file():
            raise InputError(f"{path}: its data file {source} is missing")
    header_size = int(header.get("HeaderSize", 0))
    if header_size == -1:
        offset = source.stat().st_size - nbytes
    elif header_size > 0:
        offset += header_size
    with open(source, "rb") as f:
        f.seek(max(offset, 0))
        payload = f.read()
    if header.get("CompressedData", "False").lower() == "true":
        try:
            payload = zlib.decompressobj(zlib.MAX_WBITS | 32).decompress(payload)
        except zlib.error as exc:
            raise InputError(f"{source}: compressed MetaImage data is corrupt ({exc})") from None
    if len(payload) < nbytes or offset < 0:
        raise InputError(f"{source}: holds {len(payload)} bytes of voxels but DimSize {dims} of "
                         f"{header['ElementType']} needs {nbytes}; the file is truncated or the header wrong")
    values = np.frombuffer(payload, dtype, count=int(np.prod(dims))).reshape(dims[::-1])
    return Volume(values.astype(dtype.newbyteorder("=")),
                  check_spacing(spacing, path), {"spacing_from": "MetaImage header"})


def _read_raw(path, progress, raw):
    width, height, dtype, slice_bytes = int(raw.width), int(raw.height), np.dtype(raw.dtype), raw.slice_bytes
    if path.is_dir():
        files = [f for f in _files_in(path) if f.suffix.lower() not in NOT_SLICE_EXTENSIONS]
    else:
        files = [path]
    counts = []
    for f in files:
        size = f.stat().st_size
        if size == 0 or size % slice_bytes:
            raise InputError(f"{f} is {size} bytes, not a multiple of one {width}x{height} {dtype.name} slice "
                             f"({slice_bytes} bytes); check the raw layout", parameter="raw")
        counts.append(size // slice_bytes)
    values = np.empty((sum(counts), height, width), dtype.newbyteorder("="))
    z = 0
    for f, count in progress(list(zip(files, counts)), len(files), "reading raw slices"):
        values[z:z + count] = np.fromfile(f, dtype).reshape(count, height, width)
        z += count
    return Volume(values, (1.0, 1.0, 1.0), {"spacing_from": "default (raw slices carry no spacing)",
                                            "slices": int(sum(counts))})


def _read_npy(path, progress):
    try:
        values = np.load(path, mmap_mode="r", allow_pickle=False)
    except (ValueError, OSError) as exc:
        raise InputError(f"cannot read {path} as a .npy array: {_short(exc)}") from None
    if values.ndim != 3 or values.dtype.kind not in "uifb":
        raise InputError(f"{path} holds a {values.ndim}-D {values.dtype} array; voxrender needs a 3-D "
                         "numeric array [z, y, x]")
    if values.dtype.kind == "b":
        values = values.astype(np.uint8)
    return Volume(values, (1.0, 1.0, 1.0), {"spacing_from": "default (.npy carries no spacing)"})


def _read_tiff(path, progress):
    import imageio.v3 as iio

    try:
        values = iio.imread(path, index=None)
    except Exception as exc:  # tifffile raises many types for a bad file
        raise InputError(f"cannot read TIFF {path}: {_short(exc)}") from None
    if values.ndim == 2:
        raise InputError(f"{path} is a single 2-D image; give a multi-page TIFF or a folder of slices")
    if values.ndim == 4 and values.shape[-1] in (3, 4):
        values = np.stack([_to_grey(page, path.name) for page in values])
    return Volume(values, (1.0, 1.0, 1.0), {"spacing_from": "default (TIFF spacing is not read)"})


@dataclass(frozen=True)
class Reader:
    """One input format: its reading function and how to recognise it.

    Parameters
    ----------
    function : callable
        ``function(path, progress, **options) -> Volume``.
    suffixes : tuple of str
        File name endings (lower case) that mean this format when ``format="auto"``.
    options : tuple of str
        The keyword options of :func:`read_volume` it takes (``"raw"``, ``"series"``).
    """

    function: Callable
    suffixes: tuple = ()
    options: tuple = ()


READERS = {
    "images": Reader(_read_images),
    "dicom": Reader(_read_dicom, options=("series",)),
    "metaimage": Reader(_read_metaimage, (".mhd", ".mha")),
    "raw": Reader(_read_raw, options=("raw",)),
    "npy": Reader(_read_npy, (".npy",)),
    "tiff": Reader(_read_tiff, (".tif", ".tiff")),
}
FORMATS = ("auto", *READERS)
