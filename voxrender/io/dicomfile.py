"""The DICOM vocabulary the DICOM readers and writers share: which files are DICOM, the classes of segmentations
and of what is not an image, files whose reads a damaged length cannot blow up, the errors pydicom raises for a
damaged file, and the choice of one series among a folder's.
"""

from __future__ import annotations

import io
import os
import struct
import zlib
from pathlib import Path

from .._shared.text import first_line
from ..errors import InputError
from ._shared import natural_key

SUFFIXES = (".dcm", ".dicom", ".ima")


# Objects a study folder holds beside its slices that are not slices: segmentations (read as the labels of their
# image, by voxrender.io.seg and voxrender.io.rtstruct), structured reports, presentation states, plans.
SEG_CLASSES = {"1.2.840.10008.5.1.4.1.1.66.4": "SEG",                  # Segmentation Storage
               "1.2.840.10008.5.1.4.1.1.66.7": "SEG (label map)"}     # Label Map Segmentation Storage


RTSTRUCT_CLASS = "1.2.840.10008.5.1.4.1.1.481.3"                       # RT Structure Set Storage


SEGMENTATIONS = {**SEG_CLASSES, RTSTRUCT_CLASS: "RTSTRUCT"}


NOT_IMAGES = ("SR", "PR", "KO", "RTPLAN", "RTRECORD", "REG", "DOC")


def damaged_file_errors():
    """What pydicom raises for a damaged file or one it cannot decode, found in its test files and cut or garbled ones.

    Its own errors; ``struct.error`` and ``EOFError`` for cut-off elements; ``AttributeError`` (and ``KeyError``) for
    a missing required element; ``ValueError`` and ``TypeError`` for values that are not what their VR says;
    ``NotImplementedError`` for an unknown VR or transfer syntax; ``RuntimeError`` when no installed decoder reads
    the pixel data; ``zlib.error`` for a deflated data set that is cut or garbled.
    """
    from pydicom.errors import BytesLengthException, InvalidDicomError

    return (InvalidDicomError, BytesLengthException, OSError, EOFError, struct.error, AttributeError, KeyError,
            ValueError, TypeError, NotImplementedError, RuntimeError, zlib.error)


def dicom_files(folder):
    """DICOM files in ``folder``; when it holds none itself, those anywhere below it (exports nest them)."""
    files = [p for p in folder.iterdir() if p.is_file() and not p.name.startswith(".") and is_dicom(p)]
    if not files:
        files = [p for p in folder.rglob("*") if p.is_file() and not any(part.startswith(".") for part in
                                                                            p.relative_to(folder).parts)
                 and is_dicom(p)]
    return sorted((p for p in files if p.name.upper() != "DICOMDIR"), key=lambda p: natural_key(str(p)))


class BoundedFile(io.BufferedReader):
    """A file whose reads ask for no more than it holds: pydicom reads an element by its length, and a damaged
    length (or one read in the wrong byte order) would otherwise allocate that much before finding the file short.
    """

    def __init__(self, path):
        super().__init__(io.FileIO(path, "rb"))
        self.size = os.fstat(self.fileno()).st_size

    def read(self, size=-1):
        """At most ``size`` bytes, and never more than the file holds."""
        if size is not None and size > self.size:      # the file's size bounds it: no tell() on every small read
            size = self.size
        return super().read(size)


def is_dicom(path):
    """A DICOM file, by its suffix or its magic bytes."""
    if path.suffix.lower() in SUFFIXES:
        return True
    try:
        with open(path, "rb") as f:
            f.seek(128)
            return f.read(4) == b"DICM"
    except OSError:
        return False


def list_series(groups):
    """The series of ``groups`` for a message, on one line: a control character of a damaged header (a newline in a
    UID ...) is shown escaped.
    """
    listed = "; ".join(f"{uid} ({len(items)} slices, {getattr(items[0][1], 'SeriesDescription', '')!s})"
                       for uid, items in groups.items())
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in listed)


def fault(exc):
    """What a pydicom or highdicom error says is wrong, for a message (the SEG and RTSTRUCT readers'): the element a
    data set lacks (a ``KeyError`` of its tag or an ``AttributeError`` of its keyword), else the error's first line.

    >>> from pydicom.tag import Tag
    >>> fault(KeyError(Tag(0x0020, 0x9113))), fault(AttributeError("'Dataset' object has no attribute 'Rows'"))
    ('it lacks PlanePositionSequence (0020,9113)', 'it lacks Rows')
    """
    from pydicom.datadict import keyword_for_tag
    from pydicom.tag import BaseTag

    if isinstance(exc, KeyError) and exc.args and isinstance(exc.args[0], BaseTag):
        return f"it lacks {keyword_for_tag(exc.args[0]) or 'an element'} {exc.args[0]}"
    text = first_line(exc)
    if isinstance(exc, AttributeError) and "has no attribute '" in text:
        return "it lacks " + text.split("has no attribute '")[1].rstrip("'")
    return text.rstrip(".")


def segmentation_files(folder):
    """The segmentation files (SEG, RTSTRUCT) among a folder's DICOM files, by their SOPClassUID alone."""
    import pydicom

    found = []
    for f in dicom_files(folder):
        try:
            sop_class = str(pydicom.dcmread(f, stop_before_pixels=True, specific_tags=["SOPClassUID"], force=True)
                            .get("SOPClassUID", ""))
        except damaged_file_errors():
            continue                                   # not one: the slices' reader names a damaged file
        if sop_class in SEGMENTATIONS:
            found.append(f)
    return found


def is_rtstruct(path):
    """Whether ``path`` is a DICOM RTSTRUCT file, from its SOPClassUID or Modality (the header alone is read).

    >>> import tempfile, pathlib
    >>> is_rtstruct(pathlib.Path(tempfile.mkdtemp()))
    False
    """
    path = Path(path)
    if not path.is_file() or not is_dicom(path):      # asked of every label source: no pydicom for a NIfTI
        return False
    import pydicom

    try:
        with BoundedFile(path) as stream:         # force: an RTSTRUCT saved without preamble and file meta header
            ds = pydicom.dcmread(stream, stop_before_pixels=True, specific_tags=["SOPClassUID", "Modality"],
                                 force=True)
        return str(ds.get("SOPClassUID", "")) == RTSTRUCT_CLASS or str(ds.get("Modality", "")) == "RTSTRUCT"
    except damaged_file_errors():              # not DICOM, or too damaged to tell: not an RTSTRUCT
        return False


def choose_series(groups, where, series=None):
    """The files of one series of ``groups`` (``{SeriesInstanceUID: [(path, header), ...]}``, the DICOM files
    ``where`` holds): the one whose UID is ``series``, else the only one; the message of a missing or an unchosen
    series lists them (``parameter="series"``).
    """
    if series is not None:
        if series not in groups:
            raise InputError(f"no series {series} in {where}; it holds {list_series(groups)}", parameter="series")
        return groups[series]
    if len(groups) > 1:
        raise InputError(f"{where} holds {len(groups)} DICOM series; choose one by its UID: {list_series(groups)}",
                         parameter="series")
    return next(iter(groups.values()))
