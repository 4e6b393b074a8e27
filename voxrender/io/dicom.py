"""A DICOM series: a folder of slice files (or one multi-frame file) ordered by ImagePositionPatient (pydicom).

The folder may hold several series (one is chosen by its SeriesInstanceUID) and nest its files in subfolders, as
exports do.  Classic slices are sorted along their normal; enhanced CT and MR place their frames by functional
groups, RT dose grids by GridFrameOffsetVector.
"""

from __future__ import annotations

import contextlib
import functools
import io
import struct
import sys
import warnings
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._shared.text import first_line
from ..errors import InputError
from ._shared import Reader, Volume, check_fits, check_spacing, fill_stack, identity_progress, to_grey
from ._stack import Stack
from .dicomfile import (
    NOT_IMAGES,
    SEGMENTATIONS,
    SUFFIXES,
    BoundedFile,
    choose_series,
    damaged_file_errors,
    dicom_files,
    is_dicom,
    is_rtstruct,
)
from .images import place_slice

# The header values that group, sort and place the slices.
HEADER_KEYWORDS = ("Rows", "Columns", "Modality", "SOPClassUID", "SeriesInstanceUID", "SeriesDescription",
                   "FrameOfReferenceUID", "NumberOfFrames", "ImagePositionPatient", "ImageOrientationPatient",
                   "InstanceNumber", "PixelSpacing", "SliceThickness", "SpacingBetweenSlices")
# The transfer syntaxes whose pixel data this reader takes straight from the file (uncompressed, little endian),
# with whether their elements are implicit VR; any other is decoded by pydicom.
PLAIN_SYNTAXES = {"1.2.840.10008.1.2": True,            # Implicit VR Little Endian
                  "1.2.840.10008.1.2.1": False}         # Explicit VR Little Endian
# A header is read in one call of this many bytes: most end (at their pixel data) within it, long private ones
# (Siemens CSA ...) too; the rest of a slice file is read straight into the volume.
HEADER_BYTES = 1 << 16


def read_dicom(folder, progress, series=None, run=None):
    """Read the DICOM series in ``folder`` (the one whose SeriesInstanceUID is ``series``, when it holds several;
    of a series with uneven steps, regular run ``run``, from 1, else the longest).
    """
    chosen, aside, plain = _series_files(folder, progress, series)
    if _multiframe(chosen, folder):
        with _header_values(folder):
            volume = _read_multiframe(chosen[0][0])
        volume.meta.update(_beside(aside))
        return volume
    items, spacing, meta, direction = _slices_placed(folder, chosen, aside, run)
    at = [plain.get(f) for f, _ in items]
    if all(a is not None for a in at) and len({a.dtype for a in at}) == 1:
        values = _read_plain_slices(items, at, progress, folder)
    else:
        values = fill_stack(items, lambda item: (_values(*item, plain.get(item[0])), item[0].name),
                            "reading DICOM slices", progress, folder)
    return Volume(values, spacing, meta, direction)


def open_dicom(folder, series=None, run=None):
    """The DICOM series in ``folder`` as a :class:`~voxrender.io._stack.Stack`: its headers are read now, as
    :func:`read_dicom` reads them, its pixels a slab of files at a time.

    The slices' type is :func:`read_dicom`'s: the type their rescaled values need.  The headers tell it when the
    rescale is fractional (``float32``) or takes every value the stored bits can hold into ``int16``; otherwise the
    pixels of the slices whose headers do not tell are read once now, one file at a time, for their range.
    """
    chosen, aside, plain = _series_files(folder, identity_progress, series)
    if _multiframe(chosen, folder):
        with _header_values(folder):
            stack = _open_multiframe(chosen[0][0])
        stack.meta.update(_beside(aside))
        return stack
    items, spacing, meta, direction = _slices_placed(folder, chosen, aside, run)
    shape = (len(items), int(items[0][1].Rows), int(items[0][1].Columns))
    told = [_told_type(ds) for _, ds in items]
    buffers = {}
    found = {_values(f, ds, plain.get(f), _buffer(buffers, shape[1:], plain.get(f))).dtype
             for (f, ds), dtype in zip(items, told, strict=True) if dtype is None}
    dtype = np.result_type(*({dtype for dtype in told if dtype is not None} | found))   # as fill_stack widens

    def read_slices(z0, z1):
        out, buffers = np.empty((z1 - z0, *shape[1:]), dtype), {}
        for k, (f, ds) in enumerate(items[z0:z1]):
            at = plain.get(f)
            place_slice(out, k, _values(f, ds, at, _buffer(buffers, shape[1:], at)), f.name, items[0][0].name)
        return out

    return Stack(shape, dtype, read_slices, spacing, direction, meta, sum(f.stat().st_size for f, _ in items))


def _series_files(folder, progress, series):
    """The files of the chosen series in ``folder`` with their headers, ``[(path, header), ...]``; the files set
    aside as not slices (segmentations, reports ...), ``[(path, kind), ...]``; and where the slices that store
    their pixels plainly hold them, ``{path: _Plain}`` (see :func:`_plain_pixels`).
    """
    if folder.is_file():
        if is_rtstruct(folder):
            raise InputError(f"{folder} is an RTSTRUCT: it holds contours, not a volume; give its CT series as the "
                             "image and the RTSTRUCT as its labels", parameter="labels_from")
        raise InputError(f"{folder} is one DICOM file; give the folder that holds the whole series")
    files = dicom_files(folder)
    if not files:
        raise InputError(f"{folder} holds no DICOM files")
    damaged = damaged_file_errors()
    headers, aside, plain, decoded, texts = [], [], {}, {}, {}
    for f in progress(files, len(files), "reading DICOM headers"):
        try:
            ds, position, element = _read_header(f)
            _decode_header(ds, decoded)
        except damaged as exc:
            raise InputError(f"cannot read DICOM file {f}: {first_line(exc)}") from None
        kind = SEGMENTATIONS.get(_text(ds, 0x00080016, "", texts))                          # SOPClassUID
        if kind or _text(ds, 0x00080060, "", texts) in NOT_IMAGES:       # Modality: beside the slices, not one
            aside.append((f, kind or str(ds.get("Modality"))))
            continue
        missing = [key for key in ("Rows", "Columns") if key not in ds]
        if missing:
            kind = str(getattr(ds, "Modality", "") or getattr(ds, "SOPClassUID", "")) or "unknown"
            raise InputError(f"DICOM file {f} holds no image (no {', '.join(missing)}; modality or class: {kind}); "
                             "give a folder of image slices")
        headers.append((f, ds))
        at = _plain_pixels(ds, position, element)
        if at is not None:
            plain[f] = at
    if not headers:
        found = ", ".join(f"{kind} {f.name}" for f, kind in aside[:3]) + (" ..." if len(aside) > 3 else "")
        raise InputError(f"{folder} holds no image slices, only {found}; a segmentation is shown on its image: "
                         "give the image's series, with the segmentation as its labels", parameter="labels_from")
    groups = {}
    for f, ds in headers:
        groups.setdefault(_text(ds, 0x0020000E, "(no SeriesInstanceUID)", texts), []).append((f, ds))
    return choose_series(groups, folder, series), aside, plain


@functools.cache
def _header_tags():
    """The tags of :data:`HEADER_KEYWORDS`, from pydicom's dictionary once (a keyword is looked up on each ask)."""
    from pydicom.datadict import tag_for_keyword

    return tuple(tag_for_keyword(keyword) for keyword in HEADER_KEYWORDS)


def _decode_header(ds, decoded):
    """Decode the values of :data:`HEADER_KEYWORDS` in the header ``ds``: pydicom decodes a value when first asked,
    and a damaged one fails here, naming its file.  A value stored as the one of an earlier file of the folder
    that decoded (``decoded``, by tag: kept up to date) decodes as it did; it is left for when it is asked (a
    series' slices mostly share their orientation, spacing, UIDs ...).
    """
    charset = _charset(ds)
    for tag in _header_tags():
        raw = ds.get_item(tag)
        if raw is None:
            continue
        key = _raw_key(raw)
        if key is not None and decoded.get(tag) == (charset, key):
            continue
        ds[tag]                                                     # noqa: B018 - decodes it
        if key is not None:
            decoded[tag] = (charset, key)


def _text(ds, tag, default, texts):
    """The value of ``tag`` in the header ``ds`` as text (``default`` when it has none), known without decoding it
    when an earlier header stored it alike (``texts``, a dict kept up to date).
    """
    if tag not in ds:
        return default
    key = _raw_key(ds.get_item(tag))
    if key is None:
        return str(ds[tag].value)
    key = (tag, _charset(ds), key)
    if key not in texts:
        texts[key] = str(ds[tag].value)
    return texts[key]


def _charset(ds):
    """The SpecificCharacterSet of ``ds``, undecoded or decoded, that text values are decoded by."""
    item = ds.get_item(0x00080005)
    return _raw_key(item) or (None if item is None else ("decoded", str(item.value)))


def _raw_key(raw):
    """What decides how pydicom decodes the element ``raw`` while it is still undecoded (its VR, bytes and
    encoding), else ``None``.
    """
    if not getattr(raw, "is_raw", False):             # a RawDataElement, not a DataElement nor None
        return None
    return raw.VR, raw.value, raw.is_implicit_VR, raw.is_little_endian


def _read_header(path):
    """The header of the DICOM file ``path`` (pydicom's data set of its elements before its pixel data), the
    position in the file where reading stopped (at its pixel data element, if it has one) and the twelve bytes
    there: ``(ds, position, element)``.

    The file's first :data:`HEADER_BYTES` are read in one call and parsed in memory: pydicom reads a stream a few
    bytes at a time, each read a call of :class:`BoundedFile`.  A header that does not end within them at a pixel
    data element (a long one; a damaged, deflated or odd file) is parsed again from the file, as every header once
    was, for its data set or its error.
    """
    with BoundedFile(path) as stream:
        start = stream.read(HEADER_BYTES)
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                buffer = io.BytesIO(start)
                ds = _parse_header(buffer)
            position = buffer.tell()
            element = start[position:position + 12]
            if len(element) == 12 and struct.unpack_from("<HH", element) in PIXEL_TAGS:
                for warning in caught:                    # said once, as the parse of the file would say it
                    warnings.warn_explicit(warning.message, warning.category, warning.filename, warning.lineno)
                ds.buffer = None                          # pydicom keeps what it read from: let it go
                return ds, position, element
        except Exception:                                 # any: the parse of the file below says what it is
            pass
        stream.seek(0)
        ds = _parse_header(stream)
        position = stream.tell()
        return ds, position, stream.read(12)


def _parse_header(stream):
    """The data set of the elements of ``stream`` before its pixel data (pydicom); a file without a file meta
    header (an older one) is read as a bare data set.
    """
    import pydicom
    from pydicom.errors import InvalidDicomError

    try:
        return pydicom.dcmread(stream, stop_before_pixels=True)
    except InvalidDicomError:
        stream.seek(0)
        return pydicom.dcmread(stream, stop_before_pixels=True, force=True)


@dataclass(frozen=True)
class _Plain:
    """Where and how a slice file stores its pixels plainly: uncompressed, little endian, one grey frame."""

    offset: int             # of the pixel data's first byte in the file
    dtype: np.dtype         # of the stored values, as pydicom's pixel_array gives them
    shift: int              # BitsAllocated - BitsStored: the unused high bits pydicom clears or fills with the sign


PIXEL_TAGS = {(0x7FE0, 0x0010), (0x7FE0, 0x0009), (0x7FE0, 0x0008)}     # where pydicom stops before the pixels


def _plain_pixels(ds, position, element):
    """Where the slice whose header is ``ds`` holds its pixels, read at ``position`` with its first bytes there,
    ``element``, when it stores them plainly (:class:`_Plain`), its header valid as pydicom's pixel_array checks
    it; else ``None``: pydicom decodes them.

    Plainly means an uncompressed little endian transfer syntax read as its file meta header says (on a little
    endian machine); one grey sample of 8, 16 or 32 bits (BitsStored 1 to BitsAllocated, PixelRepresentation 0
    or 1, MONOCHROME1 or 2) in one frame; and a (7FE0,0010) Pixel Data element whose length is the pixels' (or one
    byte more, an odd length's padding).
    Anything else, odd or damaged, keeps pydicom's reading and its messages.
    """
    module = _pixel_module(ds)
    if not module:
        return None
    implicit, rows, columns, allocated, stored, signed = module
    size = 8 if implicit else 12            # tag, length; or tag, VR, two reserved bytes, length
    if len(element) < size or struct.unpack_from("<HH", element) != (0x7FE0, 0x0010) or \
            (not implicit and element[4:6] not in (b"OB", b"OW")):
        return None
    length = struct.unpack_from("<L", element, size - 4)[0]
    expected = rows * columns * allocated // 8
    if length not in (expected, expected + expected % 2):
        return None
    return _Plain(position + size, np.dtype(f"{'i' if signed else 'u'}{allocated // 8}"), allocated - stored)


def _pixel_module(ds):
    """``(implicit VR, rows, columns, BitsAllocated, BitsStored, signed)`` of the header ``ds`` when its pixels
    may be stored plainly (see :func:`_plain_pixels`), else ``()``.
    """
    try:
        syntax = str(ds.file_meta.TransferSyntaxUID)
        implicit = PLAIN_SYNTAXES.get(syntax)
        if implicit is None or tuple(ds.original_encoding) != (implicit, True) or sys.byteorder != "little":
            return ()
        if int(ds.SamplesPerPixel) != 1 or str(ds.PhotometricInterpretation) not in ("MONOCHROME1", "MONOCHROME2") \
                or ("NumberOfFrames" in ds and ds.NumberOfFrames != 1):
            return ()
        allocated, stored, signed = int(ds.BitsAllocated), int(ds.BitsStored), int(ds.PixelRepresentation)
        rows, columns = int(ds.Rows), int(ds.Columns)
    except (*damaged_file_errors(), OverflowError):    # a value cut short (a file cut in its header) too
        return ()
    if allocated not in (8, 16, 32) or not 1 <= stored <= allocated or signed not in (0, 1) or \
            not (0 < rows < 1 << 16 and 0 < columns < 1 << 16):
        return ()
    return implicit, rows, columns, allocated, stored, signed


def _read_plain(path, at, out):
    """The stored values of the slice file ``path`` whose pixels ``at`` places (:class:`_Plain`), read straight
    from the file into ``out`` (one slice, C-ordered), as pydicom's pixel_array gives them; a file cut short within
    them is a damaged file.
    """
    view = out.reshape(-1).view(np.uint8)
    try:
        with open(path, "rb", buffering=0) as f:
            f.seek(at.offset)
            got = 0
            while got < view.size:
                count = f.readinto(view[got:])
                if not count:
                    break
                got += count
    except OSError as exc:
        raise InputError(f"cannot read the pixels of DICOM file {path}: {first_line(exc)}") from None
    if got < view.size:
        raise InputError(f"cannot read the pixels of DICOM file {path}: it holds {got} of the {view.size} bytes of "
                         "its pixel data; the file is truncated")
    if at.shift:                    # as pydicom clears the unused bits: shifts in the stored type (signed: its sign)
        np.left_shift(out, at.shift, out=out)
        np.right_shift(out, at.shift, out=out)
    return out


def _read_plain_slices(items, at, progress, folder):
    """The rescaled values of the slices ``items`` (all stored plainly, in one type, where ``at`` says), as
    :func:`~voxrender.io._shared.fill_stack` gives them.  When the first slice's values keep the stored values'
    width (int16 from 16 bits), each slice is read straight into the volume and rescaled there; otherwise each is
    read into one slice and placed in a volume of the type they need.
    """
    first = items[0][1]
    shape = (len(items), int(first.Rows), int(first.Columns))
    scratch = np.empty(shape[1:], at[0].dtype)
    stored = volume = None
    rescales = {}
    for z, ((f, ds), a) in enumerate(zip(progress(items, len(items), "reading DICOM slices"), at, strict=True)):
        data = _rescale(_read_plain(f, a, scratch if stored is None else stored[z]), ds,
                        *_rescaled_by(ds, rescales), reuse=True)
        if volume is None:
            check_fits(shape, data.dtype, folder)
            if np.may_share_memory(data, scratch):              # rescaled in its own width: in place from now on
                stored = np.empty(shape, at[0].dtype)
                volume = stored.view(data.dtype)
            else:
                volume = np.empty(shape, data.dtype)
        elif not np.can_cast(data.dtype, volume.dtype, "safe"):    # a later slice needs a wider type: widen once
            wider = np.result_type(volume.dtype, data.dtype)
            check_fits(shape, wider, folder)
            widened = np.empty(shape, wider)
            widened[:z] = volume[:z]
            volume = widened
        if not np.may_share_memory(data, volume):                # not already there
            volume[z] = data
    return volume


def _buffer(buffers, shape, at):
    """A slice of ``shape`` of the type the pixels ``at`` places are stored in, from ``buffers`` (by type, kept up
    to date): one slice's stored values, read again and again.  ``None`` for pixels pydicom decodes.
    """
    if at is None:
        return None
    if at.dtype not in buffers:
        buffers[at.dtype] = np.empty(shape, at.dtype)
    return buffers[at.dtype]


def _values(path, ds, at, buffer=None):
    """The rescaled values of the slice file ``path`` whose header is ``ds``: read plainly where ``at`` says (into
    ``buffer``, one slice of the stored type, when given: the values may be computed in it), else decoded by
    pydicom (:func:`_slice_values`).
    """
    if at is None:
        return _slice_values(path)
    if buffer is None:
        buffer = np.empty((int(ds.Rows), int(ds.Columns)), at.dtype)
    return _rescale(_read_plain(path, at, buffer), ds, reuse=True)


@contextlib.contextmanager
def _header_values(folder):
    """Header values found invalid while the slices are placed are a damaged folder: a value its VR does not allow
    (IS "1A", DS "?.0"), or a sequence pydicom decodes only when first read, garbled or cut (OSError "no tag to
    read", EOFError, struct.error).
    """
    try:
        yield
    except InputError:
        raise
    except (ValueError, TypeError, NotImplementedError, OSError, EOFError, struct.error) as exc:
        raise InputError(f"{folder}: a DICOM header value is invalid ({first_line(exc)}); the files are damaged") \
            from None


def _multiframe(chosen, folder):
    """Whether the series is one multi-frame file (a series mixing both kinds is refused)."""
    with _header_values(folder):
        if not any(_frames(ds) > 1 for _, ds in chosen):
            return False
    if len(chosen) > 1:
        raise InputError(f"the series in {folder} mixes multi-frame and single-frame files; keep one kind")
    return True


def _slices_placed(folder, chosen, aside, run=None):
    """The slices of a classic series in order (of a series with uneven steps, regular run ``run``, else the
    longest), with the volume's spacing, meta and direction, from their headers.
    """
    with _header_values(folder):
        chosen, spacing_z, sorted_by, direction = _sort_dicom(chosen, run)
        pixel = _pixel_spacing(chosen[0][1], chosen[0][0])
    first = chosen[0][1]
    for f, ds in chosen:
        if (getattr(ds, "Rows", None), getattr(ds, "Columns", None)) != (first.Rows, first.Columns):
            raise InputError(f"slice {f.name} is {ds.Columns}x{ds.Rows} but {chosen[0][0].name} is "
                             f"{first.Columns}x{first.Rows}; all slices must have the same size")
    if "PixelSpacing" not in first:
        warnings.warn("the DICOM series has no PixelSpacing; using 1 mm (give the spacing if that is wrong)",
                      stacklevel=3)
    meta = {"slices": len(chosen), "series": str(getattr(first, "SeriesInstanceUID", "")),
            "frame_of_reference": str(getattr(first, "FrameOfReferenceUID", "")),
            "description": str(getattr(first, "SeriesDescription", "")),
            "modality": str(getattr(first, "Modality", "")),
            "units": "HU" if str(getattr(first, "Modality", "")) == "CT" else "stored values",
            "sorted_by": sorted_by, "spacing_from": "DICOM"}
    if direction is not None:
        meta["orientation_from"] = "DICOM ImageOrientationPatient and the slice positions"
    if _numbers(first.get("ImagePositionPatient")) is not None:
        meta["origin"] = _numbers(first.ImagePositionPatient)
    meta.update(_padding(first))
    meta.update(_beside(aside))
    return chosen, check_spacing((pixel[1], pixel[0], spacing_z), folder), meta, direction


def _slice_values(path):
    """The rescaled values of one slice file (colour becomes grey), decoded by pydicom."""
    ds, data = _dicom_pixels(path)
    return _rescale(to_grey(data, path.name), ds)


def _numbers(value, count=3):
    """A DICOM multi-value as ``count`` finite floats, or ``None`` when it is not that (one value, text ...)."""
    if value is None:
        return None
    items = list(value) if isinstance(value, Iterable) and not isinstance(value, (str, bytes)) else [value]
    try:
        numbers = [float(v) for v in items]
    except (TypeError, ValueError):
        return None
    return numbers if len(numbers) == count and all(np.isfinite(numbers)) else None


def _pixel_spacing(ds, source, value=None):
    """The (row, column) spacing in mm of ``ds`` (or the ``value`` a functional group gives), 1 mm when unsaid."""
    value = value if value is not None else ds.get("PixelSpacing")
    if value is None:
        return [1.0, 1.0]
    pixel = _numbers(value, 2)
    if pixel is None:
        raise InputError(f"{source}: its PixelSpacing {value} is not two numbers (row, column spacing); the file is "
                         "damaged")
    return pixel


def _padding(ds):
    """``{"padding_value": v}``: the PixelPaddingValue that fills the outside of a CT's scan circle, in the
    volume's units (rescaled as the voxels are); empty when the file has none.
    """
    try:
        padding = float(ds.PixelPaddingValue)
    except (AttributeError, TypeError, ValueError):
        return {}
    return {"padding_value": float(_rescale(np.array([padding]), ds)[0])}


def _frames(ds):
    try:
        return int(getattr(ds, "NumberOfFrames", 1) or 1)
    except (ValueError, TypeError):
        return 1


def _dicom_pixels(path):
    """The data set and its pixels (colour as RGB), or one clean error."""
    import pydicom
    from pydicom.pixels import convert_color_space

    damaged = damaged_file_errors()
    ds = None
    try:
        with BoundedFile(path) as stream:
            ds = pydicom.dcmread(stream, force=True)
        _check_pixels_fit(ds, path)
        data = ds.pixel_array
        if str(getattr(ds, "PhotometricInterpretation", "")).startswith("YBR") and data.shape[-1] == 3:
            data = convert_color_space(data, ds.PhotometricInterpretation, "RGB")
    except damaged as exc:
        raise InputError(f"cannot read the pixels of DICOM file {path}{_compression(ds, damaged)}: "
                         f"{first_line(exc)}") from None
    return ds, data


def _check_pixels_fit(ds, path, frames=None):
    """Refuse, before decoding them, pixels the free memory cannot hold (a compressed file can promise any size):
    all of them, or so many ``frames`` at a time.
    """
    samples = int(ds.get("SamplesPerPixel", 1) or 1)
    shape = [frames or _frames(ds), int(ds.Rows), int(ds.Columns)] + [samples] * (samples > 1)
    dtype = {8: np.uint8, 32: np.uint32, 64: np.float64}.get(int(ds.get("BitsAllocated", 16) or 16), np.uint16)
    check_fits(shape, dtype, path)


def _compression(ds, damaged):
    """`` (transfer syntax NAME)`` when ``ds`` says its pixel data is compressed, for a message; else empty."""
    try:
        syntax = ds.file_meta.TransferSyntaxUID
        return f" (transfer syntax {syntax.name})" if syntax.is_transfer_syntax and syntax.is_compressed else ""
    except damaged:                       # no data set, no file meta, or a garbled UID: the message goes without
        return ""


def _rescale(data, ds, slope=None, intercept=None, reuse=False):
    """Stored values to units (Hounsfield for CT) by RescaleSlope and RescaleIntercept: integers (int16 when they
    fit) for whole numbers, else float32 (see :func:`_rescaled_type`); a slope or intercept that is not finite, or
    takes the values beyond float32, is a damaged file.

    With ``reuse``, integers are computed in ``data`` itself when their type is as wide as the stored one (else in
    one copy), in its width, wrapping: the low bits of the exact values, so the same values as the computation in
    int32 that keeps ``data``.
    """
    slope, intercept = _slope_intercept(ds, slope, intercept)
    low, high = (float(data.min()), float(data.max())) if data.size else (0.0, 0.0)
    ends = [low * slope + intercept, high * slope + intercept]
    if not np.all(np.isfinite([slope, intercept])) or max(abs(e) for e in ends) > float(np.finfo(np.float32).max):
        raise InputError(f"a DICOM file's RescaleSlope {slope:g} and RescaleIntercept {intercept:g} take its values "
                         f"{low:g} to {high:g} beyond any number; the file is damaged")
    dtype = _rescaled_type(ends if data.size else [np.inf], slope, intercept, data.dtype.kind)
    if dtype == np.float32:
        return (data * np.float32(slope) + np.float32(intercept)).astype(np.float32)
    if not reuse:
        return (data.astype(np.int32) * int(slope) + int(intercept)).astype(dtype, copy=False)
    values = data if data.dtype.itemsize == dtype.itemsize else data.astype(dtype)
    unsigned = values.view(f"u{values.dtype.itemsize}")            # unsigned: wraps, as C defines it
    if slope != 1:
        np.multiply(unsigned, np.array(int(slope) % (1 << 8 * unsigned.itemsize), unsigned.dtype), out=unsigned)
    if intercept != 0:
        np.add(unsigned, np.array(int(intercept) % (1 << 8 * unsigned.itemsize), unsigned.dtype), out=unsigned)
    return values.view(dtype)


def _rescaled_by(ds, rescales):
    """The RescaleSlope and RescaleIntercept of ``ds`` (:func:`_slope_intercept`), known without decoding them when
    an earlier slice stored them alike (``rescales``, a dict kept up to date): a series' slices mostly share them.
    """
    raws = (_raw_key(ds.get_item(0x00281053)), _raw_key(ds.get_item(0x00281052)))
    if any(raw is None and tag in ds for raw, tag in zip(raws, (0x00281053, 0x00281052), strict=True)):
        return _slope_intercept(ds)
    if raws not in rescales:
        rescales[raws] = _slope_intercept(ds)
    return rescales[raws]


def _slope_intercept(ds, slope=None, intercept=None):
    """The RescaleSlope and RescaleIntercept of ``ds`` (or those given: a frame's), as floats."""
    try:
        return (float(slope if slope is not None else (getattr(ds, "RescaleSlope", 1) or 1)),
                float(intercept if intercept is not None else (getattr(ds, "RescaleIntercept", 0) or 0)))
    except (ValueError, TypeError, NotImplementedError):          # not a number, or of an unknown VR
        raise InputError("a DICOM file's RescaleSlope or RescaleIntercept is not a number; the file is damaged") \
            from None


def _rescaled_type(ends, slope, intercept, kind):
    """The type of values of ``kind`` rescaled to the range ``ends``: whole numbers within int32 stay integers,
    int16 when the range fits it (an int32 range, such as ``[inf]``, never does), anything else becomes float32.
    """
    int16, int32 = np.iinfo(np.int16), np.iinfo(np.int32)
    if slope.is_integer() and intercept.is_integer() and kind in "iub" and \
            all(int32.min <= e <= int32.max for e in [*ends, slope, intercept] if np.isfinite(e)):
        return np.dtype(np.int16 if int16.min <= min(ends) and max(ends) <= int16.max else np.int32)
    return np.dtype(np.float32)


def _told_type(ds, slope=None, intercept=None):
    """The type :func:`_rescale` gives the pixels of the slice ``ds`` (rescaled by its own slope and intercept, or
    those given: a frame's) when its header alone tells it: float32 for a fractional rescale, int16 when every value
    its stored bits can hold rescales into int16; else ``None`` (the type hangs on the values: only their range
    tells).  pydicom keeps the stored values within their bits.
    """
    try:
        grey = int(ds.get("SamplesPerPixel", 1) or 1) == 1
        allocated, bits = int(ds.BitsAllocated), int(ds.BitsStored)        # 32 or 64 allocated: maybe floats
        signed = int(ds.get("PixelRepresentation", 0) or 0) == 1
        slope, intercept = _slope_intercept(ds, slope, intercept)
    except (*damaged_file_errors(), InputError):                  # the pixels' reading will say
        return None
    if not grey or allocated not in (8, 16) or not 1 <= bits <= allocated or \
            not np.all(np.isfinite([slope, intercept])):
        return None
    if not (slope.is_integer() and intercept.is_integer()):
        return np.dtype(np.float32)
    low, high = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
    dtype = _rescaled_type([low * slope + intercept, high * slope + intercept], slope, intercept, "i")
    return dtype if dtype == np.int16 else None


def _group(ds, sequence, name):
    """A functional-group attribute of an enhanced DICOM frame's group (or of the shared groups): the value of
    ``name`` in the first item of ``sequence``, or ``None``.
    """
    if ds is None or sequence not in ds or not len(ds[sequence].value):
        return None
    return getattr(ds[sequence].value[0], name, None)


def _read_multiframe(path):
    """One multi-frame DICOM file: enhanced CT/MR (functional groups), an RT dose grid (GridFrameOffsetVector),
    or frames in file order (cine, secondary capture) when nothing places them.
    """
    ds, data = _dicom_pixels(path)
    placed = _frames_placed(path, ds)
    data = data.reshape((len(placed.order),) + data.shape[-(data.ndim - 1):]) if data.ndim > 2 else data[None]
    values = np.stack([placed.values(data[k], k) for k in placed.order])
    return Volume(values, placed.spacing, placed.meta, placed.direction)


def _open_multiframe(path):
    """One multi-frame DICOM file as a :class:`~voxrender.io._stack.Stack`: its header read now, its grey frames a
    slab at a time (colour frames, rare in a volume, are read whole now).
    """
    import pydicom

    damaged = damaged_file_errors()
    try:
        with BoundedFile(path) as stream:
            ds = pydicom.dcmread(stream, stop_before_pixels=True, force=True)
    except damaged as exc:
        raise InputError(f"cannot read DICOM file {path}: {first_line(exc)}") from None
    placed = _frames_placed(path, ds)
    if int(ds.get("SamplesPerPixel", 1) or 1) > 1:
        values = _read_multiframe(path).values
        return Stack(values.shape, values.dtype, lambda z0, z1: values[z0:z1].copy(), placed.spacing,
                     placed.direction, placed.meta)
    count = len(placed.order)
    told = [_told_type(ds, *placed.rescale[k]) for k in range(count)]
    found = {values.dtype for _, values in _frames_read(path, ds, placed, [k for k in range(count) if told[k] is None])}
    dtype = np.result_type(*({dtype for dtype in told if dtype is not None} | found))   # as np.stack widens

    def read_slices(z0, z1):
        out = np.empty((z1 - z0, int(ds.Rows), int(ds.Columns)), dtype)
        for k, (frame, values) in enumerate(_frames_read(path, ds, placed, placed.order[z0:z1])):
            place_slice(out, k, values, f"frame {frame} of {path.name}", f"frame {placed.order[0]}")
        return out

    return Stack((count, int(ds.Rows), int(ds.Columns)), dtype, read_slices, placed.spacing, placed.direction,
                 placed.meta, path.stat().st_size)


def _frames_read(path, ds, placed, frames):
    """``(frame, values)`` for the ``frames`` (numbers in the file) of the multi-frame file ``path`` whose header is
    ``ds``, decoded one at a time by pydicom and rescaled.
    """
    from pydicom.pixels import iter_pixels

    frames = [int(k) for k in frames]
    if not frames:                                      # iter_pixels takes no frames to mean all of them
        return
    damaged = damaged_file_errors()
    _check_pixels_fit(ds, path, frames=1)
    try:
        with BoundedFile(path) as stream:
            for k, data in zip(frames, iter_pixels(stream, indices=frames), strict=True):
                yield k, placed.values(data, k)
    except InputError:
        raise
    except damaged as exc:
        raise InputError(f"cannot read the pixels of DICOM file {path}{_compression(ds, damaged)}: "
                         f"{first_line(exc)}") from None


@dataclass
class _Frames:
    """The frames of a multi-frame file as its header places them: ``order``, the frame numbers in slice order;
    ``rescale``, each frame's (slope, intercept), ``None`` for the file's; ``values(data, k)``, the slice of the
    pixels ``data`` of frame ``k`` (grey, rescaled).
    """

    path: Path
    ds: object
    order: np.ndarray
    rescale: list
    spacing: tuple
    meta: dict
    direction: np.ndarray | None

    def values(self, data, k):
        return _rescale(to_grey(data, self.path.name), self.ds, *self.rescale[k])


def _frames_placed(path, ds):
    """Where the header ``ds`` of the multi-frame file ``path`` places its frames (see :class:`_Frames`)."""
    count = _frames(ds)
    shared = ds.SharedFunctionalGroupsSequence[0] if "SharedFunctionalGroupsSequence" in ds else None
    per_frame = list(ds.PerFrameFunctionalGroupsSequence) if "PerFrameFunctionalGroupsSequence" in ds else None

    def attribute(k, sequence, name):
        found = _group(per_frame[k], sequence, name) if per_frame is not None and k < len(per_frame) else None
        found = found if found is not None else _group(shared, sequence, name)
        return found if found is not None else getattr(ds, name, None)

    orientation = attribute(0, "PlaneOrientationSequence", "ImageOrientationPatient")
    pixel = attribute(0, "PixelMeasuresSequence", "PixelSpacing")
    meta = {"slices": count, "series": str(getattr(ds, "SeriesInstanceUID", "")),
            "frame_of_reference": str(getattr(ds, "FrameOfReferenceUID", "")),
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
                      stacklevel=4)
        positions, rescale, orientation = None, [(None, None)] * count, None
        meta["sorted_by"] = "file order"
    row_spacing, column_spacing = _pixel_spacing(ds, path, pixel)
    direction, spacing_z, order = None, 1.0, np.arange(count)
    if positions is not None:
        orientation = np.array([float(v) for v in orientation])
        normal = np.cross(orientation[:3], orientation[3:])
        along = np.array([np.dot(np.asarray(p, float), normal) for p in positions])
        order = np.argsort(along, kind="stable")
        steps = np.diff(along[order])
        if len(steps) and np.any(np.isclose(steps, 0)):
            raise InputError(f"{path}: two frames share one position; the file mixes acquisitions")
        spacing_z = float(np.median(steps)) if len(steps) else float(getattr(ds, "SliceThickness", 1) or 1)
        direction = np.stack([orientation[:3], orientation[3:], normal], axis=1)
        meta["orientation_from"] = "DICOM ImageOrientationPatient and the frame positions"
        meta["origin"] = [float(v) for v in np.asarray(positions[order[0]], float)]
    if str(getattr(ds, "Modality", "")) == "CT":
        meta["units"] = "HU"
    meta.setdefault("units", "stored values")
    meta.update(_padding(ds))
    spacing = check_spacing((column_spacing, row_spacing, abs(spacing_z)), path)
    return _Frames(path, ds, order, rescale, spacing, meta, direction)


def _beside(aside):
    """The segmentation files found beside the slices, ``{"segmentations": [path, ...]}`` (or nothing): the labels
    that a folder given as its own labels holds.
    """
    found = [str(f) for f, kind in aside if kind in SEGMENTATIONS.values()]
    return {"segmentations": found} if found else {}


RUN_TOLERANCE = 0.1      # steps within 10 % of the median one make one regular run of slices


def _sort_dicom(items, run=None):
    """Order slices along the slice normal; return (items, slice spacing, how they were sorted, direction).

    The direction (see :mod:`voxrender.space.orient`) is known when the slices have ImageOrientationPatient:
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
    runs = _regular_runs(positions) if how == "ImagePositionPatient" and len(steps) else [(0, len(items))]
    if run is not None and not 1 <= run <= len(runs):
        raise InputError(f"run {run} is not one of the series' {len(runs)} regular run{'s' * (len(runs) > 1)} of "
                         "slices" + (f" (1 to {len(runs)})" if len(runs) > 1 else "; its steps are even"),
                         parameter="run")
    if how != "ImagePositionPatient" or not len(steps):
        return items, abs(fallback), how, direction
    first, last = runs[run - 1] if run is not None else max(runs, key=lambda r: r[1] - r[0])
    if (first, last) != (0, len(items)):
        warnings.warn(_run_taken(items, positions, runs, (first, last), run is None), stacklevel=2)
        items, steps = items[first:last], steps[first:last - 1]
        if len(steps) == 0:
            return items, abs(fallback), how, direction
    spacing = float(np.median(steps))
    if np.ptp(steps) > max(0.01, 0.01 * spacing):
        warnings.warn(f"slice spacing varies from {steps.min():g} to {steps.max():g} mm; using the median "
                      f"{spacing:g} mm", stacklevel=2)
    return items, spacing, how, direction


def _regular_runs(positions, tolerance=RUN_TOLERANCE):
    """The runs ``(first, last)`` (slices ``first .. last - 1``, sorted by position) into which a series falls where
    a step differs from its median step by more than ``tolerance`` (a slice 200 mm from the others, a gap, a second
    acquisition); one run of them all when the steps are even.

    >>> _regular_runs(np.array([-99.5, 103.0, 104.25, 105.5]))
    [(0, 1), (1, 4)]
    >>> _regular_runs(np.array([0.0, 2.0, 4.0, 6.1]))
    [(0, 4)]
    """
    steps = np.diff(positions)
    typical = np.median(steps)
    breaks = np.flatnonzero(np.abs(steps - typical) > max(0.01, tolerance * abs(typical))) + 1
    return [(int(a), int(b)) for a, b in zip(np.r_[0, breaks], np.r_[breaks, len(positions)], strict=True)]


def _run_taken(items, positions, runs, taken, longest):
    """The warning that says which regular run of an uneven series is read (the ``longest``, or the one asked
    for), and what is set aside.
    """
    first, last = taken
    aside = [f.name for f, _ in items[:first] + items[last:]]
    shown = ", ".join(aside[:3]) + (" ..." if len(aside) > 3 else "")
    steps = np.diff(positions)
    which = "the longest regular run" if longest else "regular run"
    return (f"the series' slice steps are uneven ({steps.min():g} to {steps.max():g} mm), so its slices are not one "
            f"stack but {len(runs)} regular runs: reading {which} {runs.index(taken) + 1}, slices {first + 1} to "
            f"{last} of {len(items)} (at {positions[first]:g} to {positions[last - 1]:g} mm along the slice "
            f"normal), and setting aside {len(aside)} slice{'s' * (len(aside) > 1)} ({shown}); choose another run "
            "with --run")


def holds_dicom(path):
    """A folder holding DICOM files (or with some below it), or one DICOM file."""
    return is_dicom(path) if path.is_file() else bool(dicom_files(path))


READER = Reader(read_dicom, SUFFIXES, options=("series", "run"), sniff=holds_dicom, open=open_dicom)
