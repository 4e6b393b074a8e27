"""The fast path of the DICOM reader: a slice file's header parsed from its first bytes (the few elements that
group, sort and place the slices), and its uncompressed pixels read straight from the file into the volume.
"""

from __future__ import annotations

import functools
import io
import struct
import sys
import warnings
from dataclasses import dataclass

import numpy as np

from .._shared.text import first_line
from ..errors import InputError
from ._dicom_values import raw_key, rescaled_by, rescaled_values, slice_values
from ._shared import check_fits
from .dicomfile import (
    BoundedFile,
    damaged_file_errors,
)

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


@functools.cache
def _header_tags():
    """The tags of :data:`HEADER_KEYWORDS`, from pydicom's dictionary once (a keyword is looked up on each ask)."""
    from pydicom.datadict import tag_for_keyword

    return tuple(tag_for_keyword(keyword) for keyword in HEADER_KEYWORDS)


def decode_header(ds, decoded):
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
        key = raw_key(raw)
        if key is not None and decoded.get(tag) == (charset, key):
            continue
        ds[tag]                                                     # noqa: B018 - decodes it
        if key is not None:
            decoded[tag] = (charset, key)


def header_text(ds, tag, default, texts):
    """The value of ``tag`` in the header ``ds`` as text (``default`` when it has none), known without decoding it
    when an earlier header stored it alike (``texts``, a dict kept up to date).
    """
    if tag not in ds:
        return default
    key = raw_key(ds.get_item(tag))
    if key is None:
        return str(ds[tag].value)
    key = (tag, _charset(ds), key)
    if key not in texts:
        texts[key] = str(ds[tag].value)
    return texts[key]


def _charset(ds):
    """The SpecificCharacterSet of ``ds``, undecoded or decoded, that text values are decoded by."""
    item = ds.get_item(0x00080005)
    return raw_key(item) or (None if item is None else ("decoded", str(item.value)))


def read_header(path):
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
class Plain:
    """Where and how a slice file stores its pixels plainly: uncompressed, little endian, one grey frame."""

    offset: int             # of the pixel data's first byte in the file
    dtype: np.dtype         # of the stored values, as pydicom's pixel_array gives them
    shift: int              # BitsAllocated - BitsStored: the unused high bits pydicom clears or fills with the sign


PIXEL_TAGS = {(0x7FE0, 0x0010), (0x7FE0, 0x0009), (0x7FE0, 0x0008)}     # where pydicom stops before the pixels


def plain_pixels(ds, position, element):
    """Where the slice whose header is ``ds`` holds its pixels, read at ``position`` with its first bytes there,
    ``element``, when it stores them plainly (:class:`Plain`), its header valid as pydicom's pixel_array checks
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
    return Plain(position + size, np.dtype(f"{'i' if signed else 'u'}{allocated // 8}"), allocated - stored)


def _pixel_module(ds):
    """``(implicit VR, rows, columns, BitsAllocated, BitsStored, signed)`` of the header ``ds`` when its pixels
    may be stored plainly (see :func:`plain_pixels`), else ``()``.
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


def read_plain(path, at, out):
    """The stored values of the slice file ``path`` whose pixels ``at`` places (:class:`Plain`), read straight
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


def read_plain_slices(items, at, progress, folder):
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
        data = rescaled_values(read_plain(f, a, scratch if stored is None else stored[z]), ds,
                        *rescaled_by(ds, rescales), reuse=True)
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


def slice_buffer(buffers, shape, at):
    """A slice of ``shape`` of the type the pixels ``at`` places are stored in, from ``buffers`` (by type, kept up
    to date): one slice's stored values, read again and again.  ``None`` for pixels pydicom decodes.
    """
    if at is None:
        return None
    if at.dtype not in buffers:
        buffers[at.dtype] = np.empty(shape, at.dtype)
    return buffers[at.dtype]


def slice_file_values(path, ds, at, buffer=None):
    """The rescaled values of the slice file ``path`` whose header is ``ds``: read plainly where ``at`` says (into
    ``buffer``, one slice of the stored type, when given: the values may be computed in it), else decoded by
    pydicom (:func:`slice_values`).
    """
    if at is None:
        return slice_values(path)
    if buffer is None:
        buffer = np.empty((int(ds.Rows), int(ds.Columns)), at.dtype)
    return rescaled_values(read_plain(path, at, buffer), ds, reuse=True)
