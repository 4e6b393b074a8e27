"""A DICOM RT Structure Set (RTSTRUCT): the planar contours of its ROIs, rasterised on the grid of their CT.

This is how every radiotherapy planning system stores its structures: for each ROI (region of interest), closed
polygons in patient coordinates (LPS, mm), one or more on each image slice it crosses, referenced to a CT series.
An RTSTRUCT has no grid of its own, so it is read onto its image's: :func:`read_rtstruct` takes the CT as
:func:`~voxrender.io.read_volume` gives it and returns a label map of the same shape, spacing and placement.

- **Labels.** Label k (from 1) is the k-th ROI in ROINumber order (ROINumbers may skip: 1, 5, 12 become 1, 2, 3);
  ``meta["roi_numbers"]`` maps each label back to its ROINumber.  Names come from ROIName, colours from
  ROIDisplayColor (``None`` when the file gives none).
- **Slices.** Each contour point is taken to voxel coordinates by the inverse of
  :func:`~voxrender.space.grids.patient_affine`.  A contour belongs to the image slice whose centre its plane lies
  within half a slice of, along the axis the image's slices were stacked on (z for an axial CT, x for a sagittal one
  once reoriented).  A contour whose points spread beyond half a slice from its plane is not in a slice plane; one off
  the image, or half-way between two slices, or on a finer plane beside another contour of its ROI on the same
  slice (contours drawn on a finer CT), lies between slices.  Those are counted in one warning, not drawn.
- **Holes.** All closed contours of one ROI on one slice are combined by the even-odd rule, as DICOM's
  exclusive-or (XOR) combination and keyhole contours mean: a contour inside another is a hole, a hollow ring stays
  hollow.  CLOSED_PLANAR and CLOSEDPLANAR_XOR contours are drawn; POINT and OPEN_* contours, contours of fewer
  than three points and damaged ones (ContourData not x, y, z triples of numbers, or not NumberOfContourPoints of
  them) are counted in the same warning.
- **Pixels.** A voxel belongs to an ROI when its centre is inside the polygon (:func:`fill_even_odd`), as
  scikit-image's ``polygon2mask`` decides; a centre on an edge belongs to the pixels right of and below it, so two
  ROIs that share an edge do not overlap.
- **Overlaps.** Each ROI keeps its own voxels (an organ inside BODY too): a voxel in several holds the code of that
  set (:mod:`voxrender._shared.label_sets`, ``meta["label_sets"]``), and each pair that overlaps is reported in
  ``meta["overlaps"]`` as ``{"labels": [a, b], "names": [...], "voxels": n}``, with ``"inside"`` naming the one
  wholly inside the other.  ROIs without a voxel are listed in ``meta["empty_labels"]``.
- **Its image.** ``meta["referenced_series"]`` is the SeriesInstanceUID of the CT it was drawn on and
  ``meta["frame_of_reference"]`` its FrameOfReferenceUID; :func:`check_reference` refuses another image.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from .._shared import label_sets
from ..errors import InputError
from ._shared import Volume, check_fits, identity_progress
from .dicomfile import RTSTRUCT_CLASS, BoundedFile, damaged_file_errors, fault

CLOSED_TYPES = ("CLOSED_PLANAR", "CLOSEDPLANAR_XOR")
OPEN_TYPES = ("POINT", "OPEN_PLANAR", "OPEN_NONPLANAR")
# Contours of one ROI on one slice whose planes lie within this many slices of each other are on one plane (an
# outline and its holes); a contour on a plane farther from the slice centre was drawn on a finer CT.
SAME_PLANE = 0.05
CONTOUR_DATA = 0x30060050
# Why a contour is not drawn, in the order the warning lists them.
SKIPPED = {"open": "are points or open lines (POINT, OPEN_PLANAR, OPEN_NONPLANAR), not areas",
           "few": "have fewer than 3 points",
           "damaged": "are damaged (ContourData not x, y, z triples of numbers, or not NumberOfContourPoints of "
                      "them, or no known ContourGeometricType)",
           "no_roi": "belong to an ROI its StructureSetROISequence does not describe",
           "not_planar": "do not lie in one of the image's slice planes",
           "between": "lie between the image's slices",
           "outside": "lie outside the image"}


def read_rtstruct(path, image, progress=None):
    """Rasterise the contours of an RTSTRUCT on the grid of its image: one label per ROI.

    Parameters
    ----------
    path : str or Path
        A DICOM RTSTRUCT file.
    image : Volume
        The CT it was drawn on, as :func:`~voxrender.io.read_volume` gives it (in the canonical frame).
    progress : callable, optional
        ``progress(iterable, length, label)`` wraps the loop over the ROIs.

    Returns
    -------
    Volume
        Labels ``values[z, y, x]`` (uint8, or uint16 beyond 255 ROIs) with the image's shape, spacing, direction
        and origin: label k is the k-th ROI in ROINumber order.  ``meta`` holds ``label_table``, ``roi_numbers``,
        ``overlaps``, ``overlap_rule``, ``empty_labels``, ``referenced_series``, ``frame_of_reference``,
        ``contours`` (how many were drawn) and ``skipped_contours`` (how many were not, by why).

    Examples
    --------
    >>> import pathlib, sys, tempfile, voxrender
    >>> sys.path.insert(0, str(pathlib.Path(voxrender.__file__).parents[1] / "tests"))   # its RTSTRUCT writer
    >>> from rtstruct_files import Roi, square, write_rtstruct
    >>> image = Volume(np.zeros((3, 10, 10), np.int16), (1.0, 1.0, 2.0), {"origin": [0.0, 0.0, 0.0]}, np.eye(3))
    >>> outline = square((4.5, 4.5), 6, z=2.0)             # 6 mm wide around (4.5, 4.5) mm, on slice 1
    >>> path = write_rtstruct(pathlib.Path(tempfile.mkdtemp()) / "rs.dcm", [Roi("GTV", [outline], (255, 0, 0))])
    >>> labels = read_rtstruct(path, image)
    >>> labels.values.sum(axis=(1, 2)).tolist(), labels.meta["label_table"]
    ([0, 36, 0], {'1': {'name': 'GTV', 'colour': [255, 0, 0]}})
    """
    from ..space.grids import patient_affine  # here, not above: voxrender.io imports this module

    path = Path(path)
    progress = progress or identity_progress
    if path.is_dir():
        raise InputError(f"{path} is a folder; give the RTSTRUCT file itself")
    if image.values.ndim != 3:
        raise InputError(f"the image of RTSTRUCT {path} is not a 3-D stack (shape {image.values.shape})")
    dataset = _read_dataset(path)
    numbers, names, colours, frame_of_reference = _structures(dataset, path)
    contours, skipped = _contours(dataset, path, numbers)
    check_fits(image.shape, np.uint8 if len(numbers) < 255 else np.uint16, path)
    affine = patient_affine(image)
    to_voxel = np.linalg.inv(affine)
    axis = _slice_axis(image, contours, to_voxel)
    painter = label_sets.Painter(image.shape, len(numbers), plane_axis=2 - axis)   # slice k: index k, rows, columns
    in_plane = sorted({0, 1, 2} - {axis})                     # voxel axes of its columns, then its rows
    plane_shape = tuple(np.delete(image.shape, 2 - axis))
    planes_shape = (image.shape[2 - axis], *plane_shape)
    drawable = sum(len(found) for found in contours.values())
    drawn, empty, first_points = 0, [], []
    for label, number in enumerate(progress(numbers, len(numbers), "rasterising RTSTRUCT ROIs"), start=1):
        on_slices, firsts = _on_slices(contours[number], to_voxel, axis, in_plane, planes_shape, skipped)
        first_points += firsts
        filled = 0
        for k, polygons in on_slices.items():
            rows, columns, inside = _fill_box(polygons, plane_shape)
            painter.paint(label, (k, rows, columns), inside)
            filled += int(inside.sum())
            drawn += len(polygons)
        if not filled:
            empty.append(label)
    labels, sets = painter.finish()
    overlaps = label_sets.overlap_report(labels, sets, dict(enumerate(names, start=1)))
    if drawable and not drawn:
        raise _all_outside(path, drawable, first_points, affine, axis, image, dataset)
    if not drawable:
        raise InputError(f"RTSTRUCT {path} holds no closed contour of three points or more ({_skipped_words(skipped)})"
                         "; it outlines no area")
    if any(skipped.values()):
        warnings.warn(f"RTSTRUCT {path}: {sum(skipped.values())} of its {drawn + sum(skipped.values())} contours are "
                      f"not drawn: {_skipped_words(skipped)}", stacklevel=2)
    referenced = _referenced_series(dataset)
    meta = {"format": "rtstruct", "source": str(path), "rois": len(numbers),
            "roi_numbers": {str(k): n for k, n in enumerate(numbers, start=1)},
            "referenced_series": referenced[0] if referenced else "", "referenced_series_all": referenced,
            "frame_of_reference": frame_of_reference,
            "series": str(dataset.get("SeriesInstanceUID", "")), "contours": drawn,
            "skipped_contours": {why: n for why, n in skipped.items() if n},
            "overlap_rule": label_sets.RULE, "label_sets": sets, "overlaps": overlaps, "empty_labels": empty,
            "envelopes": _external(dataset, numbers),
            "label_table": {str(k): {"name": names[k - 1], "colour": colours[k - 1]}
                            for k in range(1, len(numbers) + 1)}}
    for key in ("origin", "orientation", "orientation_from", "spacing_from"):
        if key in image.meta:
            meta[key] = image.meta[key]
    return Volume(labels, tuple(image.spacing), meta, None if image.direction is None else np.array(image.direction))


def check_reference(rtstruct_meta, image):
    """Refuse an image that is not the one the RTSTRUCT was drawn on: another SeriesInstanceUID (or, when either
    series is unknown, another FrameOfReferenceUID).  Nothing is checked where either side does not say.

    Parameters
    ----------
    rtstruct_meta : dict
        The ``meta`` of :func:`read_rtstruct`'s label map.
    image : Volume
        The image, as :func:`~voxrender.io.read_volume` gives it (``meta["series"]``).

    Examples
    --------
    >>> ct = Volume(np.zeros((1, 1, 1)), meta={"series": "1.2.3", "source": "ct"})
    >>> check_reference({"referenced_series": "1.2.3", "source": "rs.dcm"}, ct)
    >>> check_reference({"referenced_series": "1.2.4", "source": "rs.dcm"}, ct)
    Traceback (most recent call last):
    ...
    voxrender.errors.InputError: labels_from: RTSTRUCT rs.dcm was drawn on series 1.2.4, but the image ct is \
series 1.2.3; give the CT series it was drawn on
    """
    source = rtstruct_meta.get("source", "the RTSTRUCT")
    image_name = image.meta.get("source", "")
    image_name = f"the image {image_name}" if image_name else "the image"
    drawn_on = [s for s in rtstruct_meta.get("referenced_series_all") or [rtstruct_meta.get("referenced_series")]
                if s]
    series = image.meta.get("series") or ""
    ours, theirs = rtstruct_meta.get("frame_of_reference") or "", image.meta.get("frame_of_reference") or ""
    if drawn_on and series:
        if series not in drawn_on:
            raise InputError(f"RTSTRUCT {source} was drawn on series {' or '.join(drawn_on)}, but {image_name} is "
                             f"series {series}; give the CT series it was drawn on", parameter="labels_from")
        if ours and theirs and ours != theirs:        # rt-utils writes a new UID: the series says which CT it is
            warnings.warn(f"RTSTRUCT {source} references {image_name}'s series but another frame of reference "
                          f"({ours}, the image's {theirs}); its contours are drawn in the image's patient "
                          "coordinates, as the series it references says", stacklevel=2)
        return
    if ours and theirs and ours != theirs:
        raise InputError(f"RTSTRUCT {source} is in frame of reference {ours}, but {image_name} is in {theirs}: its "
                         "contours are not in this image's patient coordinates; give the CT it was drawn on",
                         parameter="labels_from")


def fill_even_odd(polygons, shape):
    """The pixels of a plane of ``shape`` (rows, columns) whose centres lie inside ``polygons`` by the even-odd
    rule: inside when a ray from the centre crosses their edges an odd number of times, so that a polygon inside
    another is a hole.

    Parameters
    ----------
    polygons : list of (N, 2) arrays
        Closed polygons (the last vertex joins the first), as (column, row) pixel coordinates: pixel (r, c) has its
        centre at (c, r).
    shape : tuple of 2 ints

    Returns
    -------
    ndarray of bool
        A centre on an edge belongs to the pixels right of and below the edge (half-open, like a scanline fill).

    Examples
    --------
    >>> ring = [np.array([[0.5, 0.5], [5.5, 0.5], [5.5, 5.5], [0.5, 5.5]]),
    ...         np.array([[1.5, 1.5], [4.5, 1.5], [4.5, 4.5], [1.5, 4.5]])]
    >>> fill_even_odd(ring, (7, 7)).astype(int)[:, :6]
    array([[0, 0, 0, 0, 0, 0],
           [0, 1, 1, 1, 1, 1],
           [0, 1, 0, 0, 0, 1],
           [0, 1, 0, 0, 0, 1],
           [0, 1, 0, 0, 0, 1],
           [0, 1, 1, 1, 1, 1],
           [0, 0, 0, 0, 0, 0]])
    """
    mask = np.zeros(shape, bool)
    rows, columns, inside = _fill_box([np.asarray(p, dtype=float) for p in polygons], shape)
    mask[rows, columns] = inside
    return mask


def _fill_box(polygons, shape):
    """:func:`fill_even_odd` within the box of the polygons: ``(rows, columns, inside)``, two slices of the plane
    and the pixels of that box inside.  Each edge crosses the row centres ``r`` with ``low <= r < high`` (its end
    rows; half-open, so a vertex on a row counts once); each crossing toggles the pixels from the first centre at or
    right of it, and a running sum along the row keeps its parity.  Cost: the crossings and the box, no more.
    """
    n_rows, n_columns = shape
    x0 = np.concatenate([p[:, 0] for p in polygons])
    y0 = np.concatenate([p[:, 1] for p in polygons])
    x1 = np.concatenate([np.roll(p[:, 0], -1) for p in polygons])
    y1 = np.concatenate([np.roll(p[:, 1], -1) for p in polygons])
    top = int(min(max(np.ceil(y0.min()), 0), n_rows))
    bottom = int(min(max(np.ceil(y0.max()), 0), n_rows))            # rows top .. bottom - 1 may be inside
    left = int(min(max(np.ceil(x0.min()), 0), n_columns))
    right = int(min(max(np.floor(x0.max()) + 1, 0), n_columns))      # columns left .. right - 1
    rows, columns = slice(top, max(bottom, top)), slice(left, max(right, left))
    height, width = rows.stop - rows.start, columns.stop - columns.start
    if not height or not width:
        return rows, columns, np.zeros((height, width), bool)
    low, high = np.minimum(y0, y1), np.maximum(y0, y1)
    first = np.clip(np.ceil(low), top, rows.stop).astype(np.int64)
    last = np.clip(np.ceil(high), top, rows.stop).astype(np.int64)
    count = last - first                                              # 0 for a flat edge
    edge = np.repeat(np.arange(len(x0)), count)
    row = first[edge] + np.arange(len(edge)) - np.repeat(np.cumsum(count) - count, count)
    x_cross = x0[edge] + (row - y0[edge]) * (x1 - x0)[edge] / (y1 - y0)[edge]
    column = np.clip(np.ceil(x_cross) - left, 0, width).astype(np.int64)
    toggles = np.bincount((row - top) * (width + 1) + column, minlength=height * (width + 1))
    inside = (np.cumsum(toggles.reshape(height, width + 1)[:, :width], axis=1) & 1).astype(bool)
    return rows, columns, inside


def _read_dataset(path):
    """The RTSTRUCT's data set, or one clean error: not DICOM, not an RTSTRUCT, or damaged."""
    import pydicom
    from pydicom.errors import InvalidDicomError

    damaged = damaged_file_errors()
    try:
        try:
            with BoundedFile(path) as stream:
                dataset = pydicom.dcmread(stream)
        except InvalidDicomError:             # no file meta header: older files, read as a bare data set
            with BoundedFile(path) as stream:
                dataset = pydicom.dcmread(stream, force=True)
        sop_class, modality = str(dataset.get("SOPClassUID", "")), str(dataset.get("Modality", ""))
        dataset.get("SeriesInstanceUID")      # pydicom decodes a value when first asked: a damaged one fails here
    except damaged as exc:
        raise InputError(f"cannot read RTSTRUCT {path}: {fault(exc)}; the file is damaged or not DICOM") from None
    if not sop_class and not modality:
        raise InputError(f"{path} is not a DICOM RTSTRUCT (it has neither SOPClassUID nor Modality: not DICOM, or "
                         "damaged); give the RTSTRUCT file of the image's structures")
    if sop_class != RTSTRUCT_CLASS and modality != "RTSTRUCT":
        raise InputError(f"{path} is not an RTSTRUCT (SOPClassUID {sop_class or 'missing'}, modality "
                         f"{modality or 'missing'}); give the RTSTRUCT file of the image's structures")
    return dataset


def _structures(dataset, path):
    """The ROIs, in ROINumber order: their numbers, names, colours (``None`` when unsaid) and the frame of reference."""
    damaged = damaged_file_errors() + (IndexError,)
    try:
        items = list(dataset.get("StructureSetROISequence") or [])
        numbers = [int(item.ROINumber) for item in items]
        names = {n: str(item.get("ROIName", "") or f"ROI {n}") for n, item in zip(numbers, items, strict=True)}
        colours = {}
        for item in dataset.get("ROIContourSequence") or []:
            if "ReferencedROINumber" in item:
                colours[int(item.ReferencedROINumber)] = _colour(item.get("ROIDisplayColor"))
        frames = dataset.get("ReferencedFrameOfReferenceSequence") or []
        frame_of_reference = str(frames[0].get("FrameOfReferenceUID", "")) if len(frames) else ""
        if not frame_of_reference and items:
            frame_of_reference = str(items[0].get("ReferencedFrameOfReferenceUID", ""))
    except damaged as exc:
        raise InputError(f"RTSTRUCT {path} has a damaged structure set ({fault(exc)}): each ROI needs a ROINumber") \
            from None
    if not numbers:
        raise InputError(f"RTSTRUCT {path} describes no ROIs (an empty or missing StructureSetROISequence); it "
                         "outlines nothing")
    twice = sorted({n for n in numbers if numbers.count(n) > 1})
    if twice:
        raise InputError(f"RTSTRUCT {path} numbers two ROIs {twice[0]} (ROINumber); the file is damaged")
    numbers.sort()
    return numbers, [names[n] for n in numbers], [colours.get(n) for n in numbers], frame_of_reference


def _external(dataset, numbers):
    """The labels (1 = the first of ``numbers``) of the ROIs whose RTROIInterpretedType is EXTERNAL: the patient's
    outline.  Unreadable observations say nothing (the type is optional, and only decides what a surface shows).
    """
    external = set()
    try:
        for item in dataset.get("RTROIObservationsSequence") or []:
            if str(item.get("RTROIInterpretedType", "")).strip().upper() == "EXTERNAL":
                external.add(int(item.ReferencedROINumber))
    except damaged_file_errors() + (AttributeError, IndexError):
        return []
    return [label for label, number in enumerate(numbers, start=1) if number in external]


def _contours(dataset, path, numbers):
    """The closed contours of each ROI, ``{ROINumber: [(N, 3) points in mm, ...]}``, and the counts of those
    skipped by why (see ``SKIPPED``).
    """
    skipped = dict.fromkeys(SKIPPED, 0)
    found = {n: [] for n in numbers}
    damaged = damaged_file_errors() + (IndexError,)
    try:
        roi_contours = list(dataset.get("ROIContourSequence") or [])
        for roi in roi_contours:
            sequence = list(roi.get("ContourSequence") or [])
            number = int(roi.ReferencedROINumber) if "ReferencedROINumber" in roi else None
            if number not in found:
                skipped["no_roi"] += len(sequence)
                continue
            for contour in sequence:
                why, points = _contour(contour)
                if why:
                    skipped[why] += 1
                else:
                    found[number].append(points)
    except damaged as exc:
        raise InputError(f"RTSTRUCT {path} has a damaged ROIContourSequence ({fault(exc)}); the file is damaged") \
            from None
    if not sum(len(f) for f in found.values()) and not any(skipped.values()):
        raise InputError(f"RTSTRUCT {path} describes {len(numbers)} ROIs but holds no contour (an empty or missing "
                         "ROIContourSequence); it outlines nothing")
    return found, skipped


def _contour(contour):
    """One ContourSequence item: ``(None, points)``, its (N, 3) points in mm, or ``(why, None)`` when it is not drawn.
    ContourData is parsed from its stored text at once (pydicom would make a number object of each value first).
    """
    kind = str(contour.get("ContourGeometricType", "")).strip().upper()
    if kind in OPEN_TYPES:
        return "open", None
    if kind not in CLOSED_TYPES:
        return "damaged", None
    element = contour.get_item(CONTOUR_DATA)
    if element is None or element.value is None:
        return "damaged", None
    try:
        if isinstance(element.value, bytes):
            values = np.array(element.value.rstrip(b"\0 ").split(b"\\"), dtype=np.float64)
        else:
            values = np.asarray(contour.ContourData, dtype=np.float64).ravel()
        declared = contour.get("NumberOfContourPoints")
        declared = None if declared in (None, "") else int(declared)
    except (ValueError, TypeError):           # text that is not a number
        return "damaged", None
    if len(values) % 3 or not np.all(np.isfinite(values)) or declared not in (None, len(values) // 3):
        return "damaged", None
    if len(values) < 9:
        return "few", None
    return None, values.reshape(-1, 3)


def _slice_axis(image, contours, to_voxel):
    """The voxel axis (0 x, 1 y, 2 z) the image's slices were stacked along: the stored slice normal, which
    :func:`~voxrender.io.read_volume` keeps in ``meta["affine"]``; without it, the axis the contours vary least.
    """
    direction = np.eye(3) if image.direction is None else np.asarray(image.direction, dtype=float)
    stored = image.meta.get("affine")
    if stored is not None:
        normal = np.asarray(stored, dtype=float)[:3, 2]
        return int(np.argmax(np.abs(direction.T @ normal)))
    spreads = [np.ptp(points @ to_voxel[:3, :3].T, axis=0) for found in contours.values() for points in found]
    return int(np.argmin(np.median(spreads, axis=0))) if spreads else 2


def _on_slices(contours, to_voxel, axis, in_plane, shape, skipped):
    """The polygons of one ROI on each slice, ``{k: [(N, 2) (column, row) arrays]}``, and the first point (LPS mm)
    of each of its contours, for a message; what is not drawn is counted in ``skipped``.  All points of the ROI are
    taken to voxel coordinates at once.
    """
    if not contours:
        return {}, []
    sizes = np.array([len(p) for p in contours])
    starts = np.cumsum(sizes) - sizes
    points = np.concatenate(contours)
    voxel = points @ to_voxel[:3, :3].T + to_voxel[:3, 3]
    along = voxel[:, axis]
    plane = np.add.reduceat(along, starts) / sizes
    spread = np.maximum(np.maximum.reduceat(along, starts) - plane, plane - np.minimum.reduceat(along, starts))
    k = np.rint(plane).astype(np.int64)
    off = np.abs(plane - k)
    columns, rows = voxel[:, in_plane[0]], voxel[:, in_plane[1]]
    outside = ((np.maximum.reduceat(columns, starts) < 0) | (np.minimum.reduceat(columns, starts) > shape[2] - 1)
               | (np.maximum.reduceat(rows, starts) < 0) | (np.minimum.reduceat(rows, starts) > shape[1] - 1)
               | (k < 0) | (k >= shape[0]))
    not_planar = spread >= 0.5
    between = ~not_planar & ~outside & (off >= 0.5 - 1e-6)
    candidate = ~(not_planar | outside | between)
    for slice_index in np.unique(k[candidate]):                # a finer plane beside the nearest one: between
        here = candidate & (k == slice_index)
        finer = here & (off > off[here].min() + SAME_PLANE)
        between |= finer
        candidate &= ~finer
    skipped["not_planar"] += int(not_planar.sum())
    skipped["outside"] += int((outside & ~not_planar).sum())
    skipped["between"] += int(between.sum())
    flat = np.stack([columns, rows], axis=1)
    on_slices = {}
    for i in np.flatnonzero(candidate):
        on_slices.setdefault(int(k[i]), []).append(flat[starts[i]:starts[i] + sizes[i]])
    return on_slices, list(points[starts])                    # a point of each contour, for a message


def _all_outside(path, count, first_points, affine, axis, image, dataset):
    """The error for an RTSTRUCT none of whose contours lies on the image's slices, with both spans in mm along
    the patient axis nearest the slices' normal.
    """
    patient = int(np.argmax(np.abs(affine[:3, axis])))
    slices = affine[patient, axis] * np.array([0, image.shape[2 - axis] - 1]) + affine[patient, 3]
    at = np.array([p[patient] for p in first_points])
    letter = "xyz"[patient]
    referenced, series = _referenced_series(dataset), image.meta.get("series") or ""
    other = (f" (it was drawn on series {referenced[0]}, the image is series {series})"
             if referenced and series and series not in referenced else "")
    return InputError(f"none of the {count} contours of RTSTRUCT {path} lies within the image's slices: they are at "
                      f"{letter} {at.min():g} to {at.max():g} mm, the slices at {letter} {slices.min():g} to "
                      f"{slices.max():g} mm{other}; give the CT it was drawn on")


def _skipped_words(skipped):
    return "; ".join(f"{n} {SKIPPED[why]}" for why, n in skipped.items() if n) or "no contours"


def _colour(value):
    """ROIDisplayColor as ``[r, g, b]`` (0..255), or ``None`` when the file gives none or not three numbers."""
    try:
        rgb = [int(round(float(v))) for v in value] if value is not None else []
    except (TypeError, ValueError):
        return None
    return [min(max(v, 0), 255) for v in rgb] if len(rgb) == 3 else None


def _referenced_series(dataset):
    """The SeriesInstanceUIDs the RTSTRUCT's contours were drawn on (ReferencedFrameOfReferenceSequence >
    RTReferencedStudySequence > RTReferencedSeriesSequence), in file order; empty when it does not say.
    """
    found = []
    try:
        for frame in dataset.get("ReferencedFrameOfReferenceSequence") or []:
            for study in frame.get("RTReferencedStudySequence") or []:
                for series in study.get("RTReferencedSeriesSequence") or []:
                    uid = str(series.get("SeriesInstanceUID", "") or "")
                    if uid and uid not in found:
                        found.append(uid)
    except damaged_file_errors():           # a damaged reference says nothing: the image cannot be checked
        return found
    return found
