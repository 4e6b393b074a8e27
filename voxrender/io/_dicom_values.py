"""The values of a DICOM slice: what its header says of its pixels (spacing, padding, frames), the pixels decoded
by pydicom, and their rescale to the type that holds every rescaled value (``told_type``: float32 for a fractional
rescale, int16 when it fits).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from .._shared.text import first_line
from ..errors import InputError
from ._shared import check_fits, to_grey
from .dicomfile import (
    BoundedFile,
    damaged_file_errors,
)


def raw_key(raw):
    """What decides how pydicom decodes the element ``raw`` while it is still undecoded (its VR, bytes and
    encoding), else ``None``.
    """
    if not getattr(raw, "is_raw", False):             # a RawDataElement, not a DataElement nor None
        return None
    return raw.VR, raw.value, raw.is_implicit_VR, raw.is_little_endian


def slice_values(path):
    """The rescaled values of one slice file (colour becomes grey), decoded by pydicom."""
    ds, data = dicom_pixels(path)
    return rescaled_values(to_grey(data, path.name), ds)


def numbers_of(value, count=3):
    """A DICOM multi-value as ``count`` finite floats, or ``None`` when it is not that (one value, text ...)."""
    if value is None:
        return None
    items = list(value) if isinstance(value, Iterable) and not isinstance(value, (str, bytes)) else [value]
    try:
        numbers = [float(v) for v in items]
    except (TypeError, ValueError):
        return None
    return numbers if len(numbers) == count and all(np.isfinite(numbers)) else None


def pixel_spacing(ds, source, value=None):
    """The (row, column) spacing in mm of ``ds`` (or the ``value`` a functional group gives), 1 mm when unsaid."""
    value = value if value is not None else ds.get("PixelSpacing")
    if value is None:
        return [1.0, 1.0]
    pixel = numbers_of(value, 2)
    if pixel is None:
        raise InputError(f"{source}: its PixelSpacing {value} is not two numbers (row, column spacing); the file is "
                         "damaged")
    return pixel


def padding_of(ds):
    """``{"padding_value": v}``: the PixelPaddingValue that fills the outside of a CT's scan circle, in the
    volume's units (rescaled as the voxels are); empty when the file has none.
    """
    try:
        padding = float(ds.PixelPaddingValue)
    except (AttributeError, TypeError, ValueError):
        return {}
    return {"padding_value": float(rescaled_values(np.array([padding]), ds)[0])}


def frame_count(ds):
    try:
        return int(getattr(ds, "NumberOfFrames", 1) or 1)
    except (ValueError, TypeError):
        return 1


def dicom_pixels(path):
    """The data set and its pixels (colour as RGB), or one clean error."""
    import pydicom
    from pydicom.pixels import convert_color_space

    damaged = damaged_file_errors()
    ds = None
    try:
        with BoundedFile(path) as stream:
            ds = pydicom.dcmread(stream, force=True)
        check_pixels_fit(ds, path)
        data = ds.pixel_array
        if str(getattr(ds, "PhotometricInterpretation", "")).startswith("YBR") and data.shape[-1] == 3:
            data = convert_color_space(data, ds.PhotometricInterpretation, "RGB")
    except damaged as exc:
        raise InputError(f"cannot read the pixels of DICOM file {path}{compression_note(ds, damaged)}: "
                         f"{first_line(exc)}") from None
    return ds, data


def check_pixels_fit(ds, path, frames=None):
    """Refuse, before decoding them, pixels the free memory cannot hold (a compressed file can promise any size):
    all of them, or so many ``frames`` at a time.
    """
    samples = int(ds.get("SamplesPerPixel", 1) or 1)
    shape = [frames or frame_count(ds), int(ds.Rows), int(ds.Columns)] + [samples] * (samples > 1)
    dtype = {8: np.uint8, 32: np.uint32, 64: np.float64}.get(int(ds.get("BitsAllocated", 16) or 16), np.uint16)
    check_fits(shape, dtype, path)


def compression_note(ds, damaged):
    """`` (transfer syntax NAME)`` when ``ds`` says its pixel data is compressed, for a message; else empty."""
    try:
        syntax = ds.file_meta.TransferSyntaxUID
        return f" (transfer syntax {syntax.name})" if syntax.is_transfer_syntax and syntax.is_compressed else ""
    except damaged:                       # no data set, no file meta, or a garbled UID: the message goes without
        return ""


def rescaled_values(data, ds, slope=None, intercept=None, reuse=False):
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


def rescaled_by(ds, rescales):
    """The RescaleSlope and RescaleIntercept of ``ds`` (:func:`_slope_intercept`), known without decoding them when
    an earlier slice stored them alike (``rescales``, a dict kept up to date): a series' slices mostly share them.
    """
    raws = (raw_key(ds.get_item(0x00281053)), raw_key(ds.get_item(0x00281052)))
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


def told_type(ds, slope=None, intercept=None):
    """The type :func:`rescaled_values` gives the pixels of the slice ``ds`` (rescaled by its own slope and intercept,
    or those given: a frame's) when its header alone tells it: float32 for a fractional rescale, int16 when every value
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
