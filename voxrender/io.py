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
tiff       a multi-page TIFF, one page a slice (spacing from ImageJ or OME metadata)
nifti      NIfTI-1 or -2, ``.nii`` or ``.nii.gz`` (nibabel), scaled by scl_slope/scl_inter
nrrd       NRRD, ``.nrrd`` or ``.nhdr`` with a detached data file (pynrrd), raw, gzip or bzip2
========== ==========================================================================

Every reader also returns, when its header says it, the volume's *direction* (see :mod:`voxrender.orient`);
:func:`read_volume` then brings the volume to the canonical patient frame (LPS) by flips and permutations.

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

from . import orient
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

    ``direction`` (3 x 3, or ``None`` when the input does not say) holds in column ``k`` the patient (LPS)
    direction along which voxel axis ``k`` (x, y, z) grows; see :mod:`voxrender.orient`.

    Examples
    --------
    >>> v = Volume(np.zeros((3, 4, 5), np.int16), (0.5, 0.5, 2.0))
    >>> v.shape
    (3, 4, 5)
    """

    values: np.ndarray
    spacing: tuple[float, float, float] = (1.0, 1.0, 1.0)
    meta: dict = field(default_factory=dict)
    direction: np.ndarray | None = None

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
        raise InputError(f"cannot tell the format of {path}; give a folder of slices, .mhd/.mha, .nii/.nii.gz, "
                         ".nrrd/.nhdr, .npy, a multi-page .tif, or the layout of headerless slices", parameter="format")
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


def read_volume(path, *, format="auto", raw=None, spacing=None, series=None, frame=None, orientation=None,
                reorient=True, progress=None):
    """Read a slice stack into a :class:`Volume`, in the canonical patient frame.

    Parameters
    ----------
    path : str or Path
        A folder of slices or a volume file.
    format : str
        ``"auto"`` (detect it) or a name in ``READERS``.
    raw : RawLayout, optional
        The layout of headerless slices (implies ``format="raw"``).
    spacing : sequence of 3 floats, optional
        Voxel spacing (x, y, z) in mm; overrides what the files say.
    series : str, optional
        SeriesInstanceUID to read when a DICOM folder holds several series.
    frame : int, optional
        The volume to read from a 4-D file (NIfTI, NRRD).
    orientation : str, optional
        An orientation code (``"RAS"``, ``"LPI"`` ...) for inputs whose header says none, or to override it.
    reorient : bool
        Bring the volume to the canonical patient frame (x toward L, y toward P, z toward S) by flips and
        permutations, when its orientation is known.  ``False`` keeps the stored order.
    progress : callable, optional
        ``progress(iterable, length, label)`` wraps the slice loop (a progress bar).

    Returns
    -------
    Volume
        ``meta`` tells the format, where the spacing and orientation came from, and what reorienting did.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> np.save(folder / "v.npy", np.arange(24, dtype=np.int16).reshape(2, 3, 4))
    >>> read_volume(folder / "v.npy").shape
    (2, 3, 4)
    >>> read_volume(folder / "v.npy", orientation="RAS").meta["reoriented"]
    'RAS -> LPS: flipped x, y'
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
    given = {"raw": raw, "series": series, "frame": frame}
    for name, value in given.items():
        if value is not None and name not in reader.options:
            raise InputError(f"{format} input takes no {name}", parameter=name)
    volume = reader.function(path, progress, **{name: given[name] for name in reader.options})
    volume.meta.setdefault("format", format)
    volume.meta.setdefault("source", str(path))
    if volume.values.ndim != 3 or min(volume.values.shape) < 1:
        raise InputError(f"{path} does not hold a 3-D stack (shape {volume.values.shape})")
    if orientation is not None:
        volume.direction = orient.direction_of(orientation)
        volume.meta["orientation_from"] = "given"
    if volume.direction is None:
        volume.meta.setdefault("orientation_from", "unknown: the input does not say (stored order kept)")
    else:
        volume.meta["orientation"] = orient.code_of(volume.direction)
        volume.meta["affine"] = _affine(volume.direction, volume.spacing, volume.meta.get("origin")).tolist()
        if reorient:
            volume.values, volume.spacing, volume.direction, volume.meta["reoriented"] = orient.to_canonical(
                volume.values, volume.spacing, volume.direction, volume.meta.get("orientation_from", "the header"))
    if spacing is not None:
        volume.spacing = check_spacing(spacing)
        volume.meta["spacing_from"] = "given"
    return volume


def _affine(direction, spacing, origin=None):
    """The 4 x 4 voxel (x, y, z) -> patient (LPS, mm) matrix of the stored volume (origin 0 when unknown)."""
    affine = np.eye(4)
    affine[:3, :3] = np.asarray(direction, dtype=float) * np.asarray(spacing, dtype=float)[None, :]
    affine[:3, 3] = origin if origin is not None else 0.0
    return np.round(affine, 6)


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
            try:
                ds = pydicom.dcmread(f, stop_before_pixels=True)
            except InvalidDicomError:               # no file meta header: older files, read as a bare data set
                ds = pydicom.dcmread(f, stop_before_pixels=True, force=True)
        except (InvalidDicomError, OSError, EOFError, ValueError, TypeError, KeyError, AttributeError) as exc:
            raise InputError(f"cannot read DICOM file {f}: {_short(exc)}") from None
        missing = [key for key in ("Rows", "Columns") if key not in ds]
        if missing:
            kind = str(getattr(ds, "Modality", "") or getattr(ds, "SOPClassUID", "")) or "unknown"
            raise InputError(f"DICOM file {f} holds no image (no {', '.join(missing)}; modality or class: {kind}); "
                             "give a folder of image slices")
        headers.append((f, ds))
    groups = {}
    for f, ds in headers:
        groups.setdefault(str(getattr(ds, "SeriesInstanceUID", "(no SeriesInstanceUID)")), []).append((f, ds))
    if series is not None:
        if series not in groups:
            raise InputError(f"no series {series} in {folder}; it holds {_list_series(groups)}", parameter="series")
        chosen = groups[series]
    elif len(groups) > 1:
        raise InputError(f"{folder} holds {len(groups)} DICOM series; choose one by its UID: "
                         f"{_list_series(groups)}", parameter="series")
    else:
        chosen = next(iter(groups.values()))
    if any(_frames(ds) > 1 for _, ds in chosen):
        if len(chosen) > 1:
            raise InputError(f"the series in {folder} mixes multi-frame and single-frame files; keep one kind")
        return _read_multiframe(chosen[0][0])
    try:
        chosen, spacing_z, sorted_by, direction = _sort_dicom(chosen)
    except (ValueError, TypeError) as exc:       # a header value that is not what its type says (e.g. IS "1A")
        raise InputError(f"{folder}: a DICOM header value is invalid ({_short(exc)}); the files are damaged") from None
    first = chosen[0][1]
    for f, ds in chosen:
        if (getattr(ds, "Rows", None), getattr(ds, "Columns", None)) != (first.Rows, first.Columns):
            raise InputError(f"slice {f.name} is {ds.Columns}x{ds.Rows} but {chosen[0][0].name} is "
                             f"{first.Columns}x{first.Rows}; all slices must have the same size")
    if "PixelSpacing" not in first:
        warnings.warn("the DICOM series has no PixelSpacing; using 1 mm (give the spacing if that is wrong)",
                      stacklevel=2)
    pixel = [float(v) for v in getattr(first, "PixelSpacing", [1.0, 1.0])]

    def read(item):
        f, _ = item
        ds = None
        ds, data = _dicom_pixels(f)
        return _rescale(_to_grey(data, f.name), ds), f.name

    values = _fill_stack(chosen, read, "reading DICOM slices", progress)
    meta = {"slices": len(chosen), "series": str(getattr(first, "SeriesInstanceUID", "")),
            "description": str(getattr(first, "SeriesDescription", "")),
            "modality": str(getattr(first, "Modality", "")),
            "units": "HU" if str(getattr(first, "Modality", "")) == "CT" else "stored values",
            "sorted_by": sorted_by, "spacing_from": "DICOM"}
    if direction is not None:
        meta["orientation_from"] = "DICOM ImageOrientationPatient and the slice positions"
    if "ImagePositionPatient" in first:
        meta["origin"] = [float(v) for v in first.ImagePositionPatient]
    return Volume(values, (pixel[1], pixel[0], spacing_z), meta, direction)


def _frames(ds):
    try:
        return int(getattr(ds, "NumberOfFrames", 1) or 1)
    except (ValueError, TypeError):
        return 1


def _dicom_pixels(path):
    """The data set and its pixels (colour as RGB), or one clean error."""
    import pydicom

    ds = None
    try:
        ds = pydicom.dcmread(path, force=True)
        data = ds.pixel_array
        if str(getattr(ds, "PhotometricInterpretation", "")).startswith("YBR") and data.shape[-1] == 3:
            from pydicom.pixels import convert_color_space

            data = convert_color_space(data, ds.PhotometricInterpretation, "RGB")
    except Exception as exc:  # pydicom raises many types for truncated or compressed data
        syntax = getattr(getattr(ds, "file_meta", None), "TransferSyntaxUID", None)
        hint = f" (transfer syntax {syntax.name})" if syntax is not None and syntax.is_compressed else ""
        raise InputError(f"cannot read the pixels of DICOM file {path}{hint}: {_short(exc)}") from None
    return ds, data


def _rescale(data, ds, slope=None, intercept=None):
    """Stored values to units (Hounsfield for CT) by RescaleSlope and RescaleIntercept; int16 when they fit."""
    try:
        slope = float(slope if slope is not None else (getattr(ds, "RescaleSlope", 1) or 1))
        intercept = float(intercept if intercept is not None else (getattr(ds, "RescaleIntercept", 0) or 0))
    except (ValueError, TypeError):
        raise InputError("a DICOM file's RescaleSlope or RescaleIntercept is not a number; the file is damaged") \
            from None
    if slope.is_integer() and intercept.is_integer() and data.dtype.kind in "iub":
        data = data.astype(np.int32) * int(slope) + int(intercept)
        if data.size and np.iinfo(np.int16).min <= data.min() and data.max() <= np.iinfo(np.int16).max:
            data = data.astype(np.int16)
        return data
    return (data * np.float32(slope) + np.float32(intercept)).astype(np.float32)


def _group(ds, sequence, name):
    """A functional-group attribute of an enhanced DICOM frame's group (or of the shared groups): the value of
    ``name`` in the first item of ``sequence``, or ``None``."""
    if ds is None or sequence not in ds or not len(ds[sequence].value):
        return None
    return getattr(ds[sequence].value[0], name, None)


def _read_multiframe(path):
    """One multi-frame DICOM file: enhanced CT/MR (functional groups), an RT dose grid (GridFrameOffsetVector),
    or frames in file order (cine, secondary capture) when nothing places them."""
    ds, data = _dicom_pixels(path)
    count = _frames(ds)
    data = data.reshape((count,) + data.shape[-(data.ndim - 1):]) if data.ndim > 2 else data[None]
    frames = [_to_grey(frame, path.name) for frame in data]
    shared = ds.SharedFunctionalGroupsSequence[0] if "SharedFunctionalGroupsSequence" in ds else None
    per_frame = list(ds.PerFrameFunctionalGroupsSequence) if "PerFrameFunctionalGroupsSequence" in ds else None

    def attribute(k, sequence, name):
        found = _group(per_frame[k], sequence, name) if per_frame is not None and k < len(per_frame) else None
        found = found if found is not None else _group(shared, sequence, name)
        return found if found is not None else getattr(ds, name, None)

    orientation = attribute(0, "PlaneOrientationSequence", "ImageOrientationPatient")
    pixel = attribute(0, "PixelMeasuresSequence", "PixelSpacing")
    meta = {"slices": count, "series": str(getattr(ds, "SeriesInstanceUID", "")),
            "description": str(getattr(ds, "SeriesDescription", "")), "modality": str(getattr(ds, "Modality", "")),
            "spacing_from": "DICOM"}
    if per_frame is not None:
        positions = [attribute(k, "PlanePositionSequence", "ImagePositionPatient") for k in range(count)]
        if any(p is None for p in positions) or orientation is None:
            raise InputError(f"{path}: an enhanced DICOM whose frames lack ImagePositionPatient or "
                             "ImageOrientationPatient; their order and spacing are unknown")
        rescale = [(attribute(k, "PixelValueTransformationSequence", "RescaleSlope"),
                    attribute(k, "PixelValueTransformationSequence", "RescaleIntercept")) for k in range(count)]
        meta["sorted_by"] = "per-frame ImagePositionPatient"
    elif "GridFrameOffsetVector" in ds and "ImagePositionPatient" in ds and orientation is not None:
        normal = np.cross(np.array(orientation[:3], float), np.array(orientation[3:], float))
        origin = np.array([float(v) for v in ds.ImagePositionPatient])
        positions = [origin + float(offset) * normal for offset in ds.GridFrameOffsetVector]
        scaling = float(getattr(ds, "DoseGridScaling", 1) or 1)
        rescale = [(scaling, 0.0)] * count
        meta.update(sorted_by="GridFrameOffsetVector", units=str(getattr(ds, "DoseUnits", "")) or "stored values")
    else:
        warnings.warn(f"{path}: nothing places its {count} frames; they are taken in file order, 1 mm apart",
                      stacklevel=3)
        positions, rescale, orientation = None, [(None, None)] * count, None
        meta["sorted_by"] = "file order"
    values = np.stack([_rescale(frame, ds, *rescale[k]) for k, frame in enumerate(frames)])
    row_spacing, column_spacing = (float(v) for v in (pixel or (1.0, 1.0)))
    direction, spacing_z = None, 1.0
    if positions is not None:
        orientation = np.array([float(v) for v in orientation])
        normal = np.cross(orientation[:3], orientation[3:])
        along = np.array([np.dot(np.asarray(p, float), normal) for p in positions])
        order = np.argsort(along, kind="stable")
        values, along = values[order], along[order]
        steps = np.diff(along)
        if len(steps) and np.any(np.isclose(steps, 0)):
            raise InputError(f"{path}: two frames share one position; the file mixes acquisitions")
        spacing_z = float(np.median(steps)) if len(steps) else float(getattr(ds, "SliceThickness", 1) or 1)
        direction = np.stack([orientation[:3], orientation[3:], normal], axis=1)
        meta["orientation_from"] = "DICOM ImageOrientationPatient and the frame positions"
        meta["origin"] = [float(v) for v in np.asarray(positions[order[0]], float)]
    if str(getattr(ds, "Modality", "")) == "CT":
        meta["units"] = "HU"
    meta.setdefault("units", "stored values")
    return Volume(values, (column_spacing, row_spacing, abs(spacing_z)), meta, direction)


def _list_series(groups):
    return "; ".join(f"{uid} ({len(items)} slices, {getattr(items[0][1], 'SeriesDescription', '')!s})"
                     for uid, items in groups.items())


def _sort_dicom(items):
    """Order slices along the slice normal; return (items, slice spacing, how they were sorted, direction).

    The direction (see :mod:`voxrender.orient`) is known when the slices have ImageOrientationPatient:
    x along its row direction, y along its column direction, z along the normal, the way the slices are sorted.
    """
    first = items[0][1]
    known = "ImageOrientationPatient" in first
    if len(items) == 1 and "ImagePositionPatient" not in first:
        return items, float(getattr(first, "SliceThickness", 1) or 1), "a single slice", None
    try:
        orientation = (np.array([float(v) for v in first.ImageOrientationPatient], dtype=float)
                       if known else np.array([1.0, 0, 0, 0, 1, 0]))  # axial, when the header does not say
        if orientation.shape != (6,):
            raise ValueError("ImageOrientationPatient needs six numbers")
        normal = np.cross(orientation[:3], orientation[3:])
        direction = np.stack([orientation[:3], orientation[3:], normal], axis=1) if known else None
        positions = np.array([np.dot([float(v) for v in ds.ImagePositionPatient], normal) for _, ds in items])
        how = "ImagePositionPatient"
    except (AttributeError, ValueError, TypeError):
        direction = None
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
        return items, abs(fallback), how, direction
    spacing = float(np.median(steps))
    if np.ptp(steps) > max(0.01, 0.01 * spacing):
        warnings.warn(f"slice spacing varies from {steps.min():g} to {steps.max():g} mm; using the median "
                      f"{spacing:g} mm", stacklevel=2)
    return items, spacing, how, direction


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
    direction, orientation_from = _metaimage_direction(header, path)
    meta = {"spacing_from": "MetaImage header", "orientation_from": orientation_from}
    for key in ("Offset", "Origin", "Position"):
        if key in header:
            try:
                meta["origin"] = [float(v) for v in header[key].split()][:3]
            except ValueError:
                pass
            break
    return Volume(values.astype(dtype.newbyteorder("=")), check_spacing(spacing, path), meta, direction)


def _metaimage_direction(header, path):
    """MetaImage's orientation: TransformMatrix (row k: the LPS direction of voxel axis k, ITK's frame), else
    AnatomicalOrientation (ITK's letters name the side each axis comes *from*: RAI is LPS)."""
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
    spacing, spacing_from = _tiff_spacing(path)
    return Volume(values, spacing, {"spacing_from": spacing_from})


def _tiff_spacing(path):
    """Voxel spacing (x, y, z) in mm from OME or ImageJ metadata, and where it came from; 1 mm when neither says."""
    import re as regex

    import tifffile

    units = {"mm": 1.0, "millimeter": 1.0, "um": 1e-3, "µm": 1e-3, "micron": 1e-3, "micrometer": 1e-3,
             "nm": 1e-6, "cm": 10.0, "m": 1000.0}
    try:
        with tifffile.TiffFile(path) as tif:
            if tif.ome_metadata:
                sizes, scale = [], []
                for axis in "XYZ":
                    found = regex.search(rf'PhysicalSize{axis}="([0-9.eE+-]+)"', tif.ome_metadata)
                    unit = regex.search(rf'PhysicalSize{axis}Unit="([^"]+)"', tif.ome_metadata)
                    sizes.append(float(found.group(1)) if found else None)
                    scale.append(units.get(unit.group(1), 1e-3) if unit else 1e-3)   # OME's default unit: µm
                if all(s is not None and s > 0 for s in sizes):
                    return tuple(s * f for s, f in zip(sizes, scale)), "OME metadata"
            if tif.imagej_metadata:
                page = tif.pages[0]
                factor = units.get(str(tif.imagej_metadata.get("unit", "")).replace("\\u00B5", "µ"), 1.0)
                resolution = []
                for tag in ("XResolution", "YResolution"):
                    value = page.tags.get(tag)
                    numerator, denominator = value.value if value is not None else (1, 1)
                    resolution.append(denominator / numerator if numerator else 1.0)
                z = float(tif.imagej_metadata.get("spacing", 1.0))
                spacing = tuple(v * factor for v in (*resolution, z))
                if all(v > 0 for v in spacing):
                    return spacing, "ImageJ metadata"
    except (OSError, ValueError, KeyError, TypeError, ZeroDivisionError):
        pass
    return (1.0, 1.0, 1.0), "default (the TIFF has no ImageJ or OME spacing)"


def _check_frame(path, frame, count=None):
    """Check the ``frame`` asked of a 4-D file of ``count`` volumes (``None``: a 3-D file, which takes none)."""
    if count is None:
        if frame is not None:
            raise InputError(f"{path} holds one volume; a frame number applies to 4-D files", parameter="frame")
    elif frame is None:
        raise InputError(f"{path} holds {count} volumes (4-D); choose one with a frame number 0 to {count - 1}",
                         parameter="frame")
    elif not 0 <= frame < count:
        raise InputError(f"{frame} is not a volume of {path}, which holds {count} (0 to {count - 1})",
                         parameter="frame")


def _read_nifti(path, progress, frame=None):
    import nibabel
    from nibabel.filebasedimages import ImageFileError

    logger = nibabel.imageglobals.logger
    level = logger.level
    logger.setLevel(40)                              # nibabel logs header repairs; the errors below say enough
    try:
        image = nibabel.load(str(path))
        header = image.header
        shape = image.shape
    except (ImageFileError, OSError, EOFError, ValueError) as exc:
        raise InputError(f"cannot read {path} as NIfTI: {_short(exc)}") from None
    finally:
        logger.setLevel(level)
    with nibabel.openers.ImageOpener(str(path)) as opener:     # as stored: loading mends a zero pixdim to 1
        stored = type(header).from_fileobj(opener, check=False)
    pixdim = [float(v) for v in stored["pixdim"][1:4]]
    if not all(np.isfinite(v) and v > 0 for v in pixdim):
        raise InputError(f"{path}: its voxel sizes (pixdim) {pixdim} must be positive; the header is damaged")
    data = image.dataobj
    if len(shape) == 4 and shape[3] == 1 and frame is None:
        frame = 0
    if len(shape) == 4:
        _check_frame(path, frame, shape[3])
        data = data[..., frame]
    else:
        _check_frame(path, frame)
        if len(shape) != 3:
            raise InputError(f"{path} holds a {len(shape)}-D image; voxrender needs a 3-D volume")
    try:
        values = np.asanyarray(data)
    except (OSError, EOFError, ValueError) as exc:         # a truncated or corrupt file
        raise InputError(f"cannot read the voxels of {path}: {_short(exc)}; the file is truncated or damaged") from None
    values = np.transpose(values, (2, 1, 0))                  # NIfTI stores [i, j, k], i fastest: our x, y, z
    affine, code = header.get_sform(coded=True)
    source = "NIfTI sform"
    if not code:
        affine, code = header.get_qform(coded=True)
        source = "NIfTI qform"
    meta = {"spacing_from": "NIfTI pixdim"}
    if code:
        matrix = np.asarray(affine, dtype=float)[:3, :3]
        sizes = np.linalg.norm(matrix, axis=0)
        if not np.all(sizes > 0):
            raise InputError(f"{path}: its {source} has a zero column; the header is damaged")
        direction = orient.ras_to_lps(matrix / sizes)
        spacing = tuple(float(v) for v in sizes)
        meta.update(spacing_from=source, orientation_from=source,
                    origin=orient.ras_to_lps(np.asarray(affine, dtype=float)[:3, 3]).tolist())
    else:
        warnings.warn(f"{path} has neither sform nor qform; its orientation is unknown (give it with an "
                      "orientation code if the presets should hold)", stacklevel=2)
        direction, spacing = None, tuple(pixdim)
        meta["orientation_from"] = "unknown: NIfTI without sform or qform"
    if header.get("scl_slope") is not None and np.isfinite(header["scl_slope"]) and header["scl_slope"] not in (0, 1):
        meta["scaled"] = f"scl_slope {float(header['scl_slope']):g}, scl_inter {float(header['scl_inter']):g}"
    return Volume(values, check_spacing(spacing, path), meta, direction)


def _read_nrrd(path, progress, frame=None):
    import nrrd

    try:
        values, header = nrrd.read(str(path), index_order="C")
    except FileNotFoundError as exc:
        raise InputError(f"{path}: its data file {exc.filename or ''} is missing") from None
    except (nrrd.NRRDError, OSError, EOFError, ValueError, KeyError, TypeError) as exc:
        raise InputError(f"cannot read {path} as NRRD: {_short(exc)}") from None
    directions = header.get("space directions")
    if values.ndim == 4:
        # the non-spatial axis: 'none' in space directions, or a list/vector kind
        spatial = [d is not None and not (isinstance(d, float) and np.isnan(d)) and np.all(np.isfinite(d))
                   for d in (directions if directions is not None else [None] * 4)]
        if directions is None or sum(spatial) != 3:
            raise InputError(f"{path} is 4-D without three spatial axes; voxrender needs a 3-D volume")
        extra = spatial.index(False)                        # in NRRD's axis order (fastest first)
        _check_frame(path, frame, values.shape[3 - extra])
        values = np.take(values, frame, axis=3 - extra)
        directions = [d for d, s in zip(directions, spatial) if s]
    else:
        _check_frame(path, frame)
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
    0..1, ``_LabelValue``, ``_Layer``) in ``layer``, as ``{"label": {"name", "colour": [r, g, b]}}``."""
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
    "nifti": Reader(_read_nifti, (".nii", ".nii.gz"), options=("frame",)),
    "nrrd": Reader(_read_nrrd, (".nrrd", ".nhdr", ".seg.nrrd"), options=("frame",)),
}
FORMATS = ("auto", *READERS)
