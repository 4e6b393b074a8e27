"""A DICOM segmentation (SEG): one file of segment frames, read as one label map on its own grid (highdicom).

This is how the Imaging Data Commons and clinical AI products publish segmentations: Segmentation Storage
(BINARY or FRACTIONAL segments, each frame one segment on one plane) and Label Map Segmentation Storage (LABELMAP:
each frame one plane of segment numbers).  highdicom, the Imaging Data Commons' own library, places the frames by
their plane positions (``Segmentation.get_volume``); only frames that hold segment pixels need be stored, so the
grid spans the planes the SEG stores, in its own orientation, on the referenced series' frame of reference.

- **Labels.** A voxel's label is its segment number.  A FRACTIONAL segment holds the voxels whose fraction is at
  least one half.
- **Overlaps.** BINARY and FRACTIONAL segments may overlap: each keeps its own voxels, a voxel in several holding
  the code of that set (:mod:`voxrender._shared.label_sets`, ``meta["label_sets"]``), and each pair that overlaps
  is reported in ``meta["overlaps"]`` as ``{"labels": [a, b], "names": [...], "voxels": n}``, with ``"inside"``
  naming the one wholly inside the other.
- **Names and colours.** ``meta["label_table"]`` names every segment by its SegmentLabel, with its
  RecommendedDisplayCIELabValue as sRGB 0..255 (``None`` when the file gives none).  Segments without a pixel are
  listed in ``meta["empty_labels"]``.
- **Its image.** ``meta["referenced_series"]`` is the SeriesInstanceUID of the series it was made from and
  ``meta["frame_of_reference"]`` its FrameOfReferenceUID: what pairs it with that series.

BINARY and FRACTIONAL frames are read one at a time, in order of segment number, into one uint8 (uint16 for
segment numbers beyond 255) label map: a whole-body SEG of a hundred segments never needs a 4-D array.
"""

from __future__ import annotations

import math
import sqlite3

import numpy as np

from .._shared import label_sets
from .._shared.text import first_line
from ..errors import InputError
from ._shared import Reader, Volume, check_fits, check_holds, quiet_log
from .dicomfile import SEG_CLASSES, BoundedFile, damaged_file_errors, fault, is_dicom


def is_seg(path):
    """Whether ``path`` is a DICOM SEG file, from its SOPClassUID (the header alone is read).

    >>> import tempfile, pathlib
    >>> is_seg(pathlib.Path(tempfile.mkdtemp()))
    False
    """
    if not path.is_file() or not is_dicom(path):      # asked of every file: no pydicom for a NIfTI
        return False
    import pydicom

    try:
        with BoundedFile(path) as stream:
            ds = pydicom.dcmread(stream, stop_before_pixels=True, specific_tags=["SOPClassUID"])
        return str(ds.get("SOPClassUID", "")) in SEG_CLASSES
    except damaged_file_errors():              # not DICOM, or too damaged to tell: not a SEG
        return False


def read_seg(path, progress):
    """Read a DICOM SEG file as one label map: each voxel's label is its segment number.

    Parameters
    ----------
    path : Path
        A DICOM SEG file (BINARY, FRACTIONAL or LABELMAP).
    progress : callable
        ``progress(iterable, length, label)`` wraps the loop over the frames.

    Returns
    -------
    Volume
        Labels ``values[z, y, x]`` (uint8, or uint16 for segment numbers beyond 255), x along the frames' columns,
        y along their rows, z across the planes; the spacing, direction and ``meta["origin"]`` of highdicom's
        volume.  ``meta`` holds ``label_table``, ``overlaps``, ``overlap_rule``, ``empty_labels``,
        ``segmentation_type``, ``referenced_series`` and ``frame_of_reference``.

    Examples
    --------
    >>> import pathlib, sys, tempfile, voxrender
    >>> sys.path.insert(0, str(pathlib.Path(voxrender.__file__).parents[1] / "tests"))   # its SEG writer
    >>> from seg_files import write_ct_and_seg
    >>> labels = np.zeros((3, 4, 5), np.uint8); labels[1, 1:3, 1:4] = 2; labels[2, 0, 0] = 1
    >>> _, seg_path = write_ct_and_seg(pathlib.Path(tempfile.mkdtemp()), labels, ["liver", "spleen"])
    >>> volume = read_seg(seg_path, lambda items, length, label: items)
    >>> volume.shape, np.bincount(volume.values.ravel()).tolist()
    ((2, 4, 5), [33, 1, 6])
    >>> volume.meta["label_table"]["2"]["name"], volume.meta["segmentation_type"]
    ('spleen', 'BINARY')
    """
    import highdicom

    if path.is_dir():
        raise InputError(f"{path} is a folder; the seg format reads one DICOM SEG file", parameter="format")
    dataset = _read_dataset(path)
    kind = str(dataset.get("SegmentationType", ""))
    _check_frames(dataset, path)
    # besides pydicom's errors, highdicom's for a damaged data set: IndexError for an empty sequence, and
    # sqlite3's when it indexes frames that lack a segment number or a dimension index (it keeps them in SQLite)
    damaged = damaged_file_errors() + (IndexError, sqlite3.Error)
    try:
        with quiet_log("highdicom"):
            seg = highdicom.seg.Segmentation.from_dataset(dataset, copy=False)
            if seg.coordinate_system is None or seg.coordinate_system.value != "PATIENT" or seg.is_tiled:
                raise InputError(f"{path} is a SEG of a slide or of an image with no frame of reference, not of a "
                                 "patient volume; voxrender reads SEGs of CT, MR or PET series")
            geometry = seg.get_volume_geometry()
            numbers = [int(n) for n in seg.segment_numbers]
            names = {n: str(seg.get_segment_description(n).segment_label) for n in numbers}
            colours = {n: _colour(seg.get_segment_description(n), highdicom) for n in numbers}
    except InputError:
        raise
    except damaged as exc:
        raise InputError(f"cannot read DICOM SEG {path}: {fault(exc)}; the file is damaged") from None
    if geometry is None:
        raise InputError(f"{path}: the frames of this SEG are not a stack of parallel, evenly spaced planes, so "
                         "they make no volume; the file is damaged or segments a non-volume image")
    if not numbers:
        raise InputError(f"{path} describes no segments (an empty SegmentSequence); the file is damaged")
    shape = tuple(int(n) for n in geometry.spatial_shape)
    dtype = np.uint8 if max(numbers) <= np.iinfo(np.uint8).max else np.uint16
    check_fits(shape, dtype, path)
    try:
        with quiet_log("highdicom"):
            if kind == "LABELMAP":
                labels, sets, overlaps, empty = _labelmap(seg, numbers, shape, dtype, path)
            else:
                labels, sets, overlaps, empty = _segments(seg, dataset, numbers, names, geometry, shape, progress,
                                                          path)
    except InputError:
        raise
    except damaged as exc:
        raise InputError(f"cannot read the frames of DICOM SEG {path}: {fault(exc)}; the file is damaged") from None
    affine = np.asarray(geometry.affine, dtype=float)
    steps = affine[:3, [2, 1, 0]]                     # the patient step of voxel x (column), y (row), z (plane)
    spacing = np.linalg.norm(steps, axis=0)
    meta = {"format": "seg", "segmentation_type": kind, "segments": len(numbers),
            "referenced_series": _referenced_series(dataset),
            "frame_of_reference": str(dataset.get("FrameOfReferenceUID", "")),
            "series": str(dataset.get("SeriesInstanceUID", "")),
            "description": str(dataset.get("SeriesDescription", "")),
            "overlap_rule": label_sets.RULE, "label_sets": sets, "overlaps": overlaps, "empty_labels": empty,
            "label_table": {str(n): {"name": names[n], "colour": colours[n]} for n in numbers},
            "origin": [float(v) for v in affine[:3, 3]], "spacing_from": "DICOM SEG",
            "orientation_from": "DICOM SEG ImageOrientationPatient and the frame positions"}
    return Volume(labels, (float(spacing[0]), float(spacing[1]), float(spacing[2])), meta, steps / spacing)


def _read_dataset(path):
    """The SEG's data set (pixels too), or one clean error: not DICOM, not a SEG, or damaged."""
    import pydicom
    from pydicom.errors import InvalidDicomError

    damaged = damaged_file_errors()
    try:
        with BoundedFile(path) as stream:
            dataset = pydicom.dcmread(stream)
        sop_class = str(dataset.get("SOPClassUID", ""))
    except InvalidDicomError:
        raise InputError(f"{path} is not a DICOM file; the seg format reads a DICOM SEG file",
                         parameter="format") from None
    except damaged as exc:
        raise InputError(f"cannot read DICOM SEG {path}: {fault(exc)}; the file is damaged") from None
    if sop_class not in SEG_CLASSES:
        modality = str(dataset.get("Modality", "")) or "no modality"
        raise InputError(f"{path} is a DICOM file but not a SEG (SOPClassUID {sop_class or 'missing'}, {modality}); "
                         "give a DICOM SEG file, or a series folder as an image", parameter="format")
    return dataset


def _check_frames(dataset, path):
    """Refuse a SEG without frames, and one whose pixel data holds fewer bytes than its frames take."""
    damaged = damaged_file_errors()
    try:
        frames = int(dataset.get("NumberOfFrames", 0) or 0)
        rows, columns = int(dataset.Rows), int(dataset.Columns)
        bits = int(dataset.BitsAllocated)
        per_frame = len(dataset.PerFrameFunctionalGroupsSequence) if "PerFrameFunctionalGroupsSequence" in \
            dataset else None
        pixel_bytes = len(dataset.get("PixelData") or b"")
        encapsulated = pixel_bytes > 0 and dataset.file_meta.TransferSyntaxUID.is_compressed
    except damaged as exc:
        raise InputError(f"DICOM SEG {path} has a damaged header ({first_line(exc)}): it lacks Rows, Columns or "
                         "BitsAllocated, or they are not numbers") from None
    if frames < 1 or not pixel_bytes:
        raise InputError(f"DICOM SEG {path} holds no frames: it segments nothing; give a SEG with segment frames")
    if per_frame is None and str(dataset.get("DimensionOrganizationType", "")) == "TILED_FULL":
        raise InputError(f"DICOM SEG {path} is a tiled segmentation of a slide (TILED_FULL, slide microscopy), not "
                         "of a patient volume; voxrender reads SEGs of CT, MR or PET series")
    if per_frame is None:
        raise InputError(f"DICOM SEG {path} has no PerFrameFunctionalGroupsSequence, so nothing places its "
                         f"{frames} frames; the file is damaged")
    if per_frame != frames:
        raise InputError(f"DICOM SEG {path} places {per_frame} frames (PerFrameFunctionalGroupsSequence) but holds "
                         f"{frames} (NumberOfFrames); the file is damaged")
    if rows < 1 or columns < 1 or bits not in (1, 8, 16):
        raise InputError(f"DICOM SEG {path} has frames of {columns}x{rows} pixels of {bits} bits; the file is "
                         "damaged")
    if not encapsulated:                          # compressed frames have no size to check before decoding
        check_holds(path, math.ceil(frames * rows * columns * bits / 8), pixel_bytes, what="frames")
    check_fits((frames, rows, columns), np.uint8 if bits < 16 else np.uint16, path)


def _labelmap(seg, numbers, shape, dtype, path):
    """A LABELMAP SEG: its frames already hold segment numbers, which cannot overlap."""
    labels = seg.get_volume(combine_segments=True, dtype=dtype).array
    counts = np.bincount(labels.ravel())
    undescribed = np.setdiff1d(np.flatnonzero(counts[1:]) + 1, numbers)
    if len(undescribed):
        raise InputError(f"DICOM SEG {path}: its pixels hold segment {undescribed[0]}, which its SegmentSequence "
                         "does not describe; the file is damaged")
    counts = np.pad(counts, (0, max(0, max(numbers) + 1 - len(counts))))
    return labels, {}, [], [n for n in numbers if counts[n] == 0]


def _segments(seg, dataset, numbers, names, geometry, shape, progress, path):
    """BINARY or FRACTIONAL segments into one map of label codes, frame by frame, each frame placed on its plane;
    each segment keeps its own voxels (:mod:`voxrender._shared.label_sets`).  Frames, not one ``get_volume`` a
    segment: that would index all the frames again for each segment.
    """
    frame_segments, frame_planes = _frame_places(dataset, geometry, shape, names, path)
    fractional = seg.segmentation_type.value == "FRACTIONAL"
    half = float(dataset.get("MaximumFractionalValue", 255) or 255) / 2 if fractional else 0.5
    painter = label_sets.Painter(shape, max(numbers))
    held = set()
    order = np.lexsort((frame_planes, frame_segments))
    for index in progress(order.tolist(), len(order), "reading SEG frames"):
        number, plane = int(frame_segments[index]), int(frame_planes[index])
        inside = seg.get_stored_frame(index, as_index=True) >= half
        if inside.shape != shape[1:]:
            raise InputError(f"DICOM SEG {path}: frame {index + 1} is {inside.shape[1]}x{inside.shape[0]} pixels, "
                             f"not the {shape[2]}x{shape[1]} of its Columns and Rows; the file is damaged")
        if inside.any():
            held.add(number)
            painter.paint(number, (plane,), inside)
    codes, sets = painter.finish()
    return codes, sets, label_sets.overlap_report(codes, sets, names), [n for n in numbers if n not in held]


def _frame_places(dataset, geometry, shape, names, path):
    """The segment number and the plane (index along the volume's z) of each frame, by its position."""
    groups = dataset.PerFrameFunctionalGroupsSequence
    shared = dataset.SharedFunctionalGroupsSequence[0] if dataset.get("SharedFunctionalGroupsSequence") else None

    def value(group, sequence, keyword):       # a frame's own functional group, else the one all frames share
        found = group if sequence in group else shared
        return getattr(found[sequence].value[0], keyword)

    numbers = np.array([int(value(g, "SegmentIdentificationSequence", "ReferencedSegmentNumber")) for g in groups])
    positions = np.array([[float(v) for v in value(g, "PlanePositionSequence", "ImagePositionPatient")]
                          for g in groups])
    if positions.shape != (len(groups), 3):
        raise InputError(f"DICOM SEG {path}: a frame's ImagePositionPatient is not three numbers; the file is damaged")
    unknown = np.setdiff1d(numbers, list(names))
    if len(unknown):
        raise InputError(f"DICOM SEG {path}: a frame belongs to segment {unknown[0]}, which its SegmentSequence does "
                         "not describe; the file is damaged")
    to_index = np.linalg.inv(np.asarray(geometry.affine, dtype=float))
    index = positions @ to_index[:3, :3].T + to_index[:3, 3]          # (plane, row, column) of each frame's corner
    planes = np.rint(index[:, 0]).astype(np.int64)
    off = np.abs(index - np.c_[planes, np.zeros((len(planes), 2))]).max(axis=1) > 0.05
    if off.any() or planes.min() < 0 or planes.max() >= shape[0]:
        k = int(np.argmax(off | (planes < 0) | (planes >= shape[0])))
        raise InputError(f"DICOM SEG {path}: frame {k + 1} lies off the planes of the others; the file is damaged")
    pairs = numbers.astype(np.int64) * shape[0] + planes
    if len(np.unique(pairs)) < len(pairs):
        again = numbers[np.argmax(np.bincount(np.unique(pairs, return_inverse=True)[1]))]
        raise InputError(f"DICOM SEG {path}: two frames of segment {again} lie on one plane; the file is damaged or "
                         "mixes segmentations")
    return numbers, planes


def _colour(description, highdicom):
    """A segment's RecommendedDisplayCIELabValue as sRGB ``[r, g, b]`` (0..255), or ``None`` when it has none (or
    the installed highdicom, before 0.27, cannot convert it).
    """
    value = description.get("RecommendedDisplayCIELabValue")
    colour_class = getattr(getattr(highdicom, "color", None), "CIELabColor", None)
    if value is None or not hasattr(colour_class, "from_dicom_value"):
        return None
    rgb = colour_class.from_dicom_value([int(v) for v in value]).to_rgb(clip=True)
    return [int(v) for v in rgb]


def _referenced_series(dataset):
    """The SeriesInstanceUID of the series the SEG was made from (``""`` when it does not say)."""
    items = dataset.get("ReferencedSeriesSequence") or []
    return str(items[0].get("SeriesInstanceUID", "")) if len(items) else ""


READER = Reader(read_seg, (), sniff=is_seg, sniff_first=True)
