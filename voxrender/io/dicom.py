"""A DICOM series: a folder of slice files (or one multi-frame file) ordered by ImagePositionPatient (pydicom).

The folder may hold several series (one is chosen by its SeriesInstanceUID) and nest its files in subfolders, as
exports do.  Classic slices are sorted along their normal; enhanced CT and MR place their frames by functional
groups, RT dose grids by GridFrameOffsetVector.
"""

from __future__ import annotations

import contextlib
import struct
import warnings

import numpy as np

from .._shared.text import first_line
from ..errors import InputError
from ._dicom_frames import open_multiframe, read_multiframe
from ._dicom_header import (
    decode_header,
    header_text,
    plain_pixels,
    read_header,
    read_plain_slices,
    slice_buffer,
    slice_file_values,
)
from ._dicom_values import frame_count, numbers_of, padding_of, pixel_spacing, told_type
from ._shared import Reader, Volume, check_spacing, fill_stack, identity_progress
from ._stack import Stack
from .dicomfile import (
    NOT_IMAGES,
    SEGMENTATIONS,
    SUFFIXES,
    choose_series,
    damaged_file_errors,
    dicom_files,
    is_dicom,
    is_rtstruct,
)
from .images import place_slice


def read_dicom(folder, progress, series=None, run=None):
    """Read the DICOM series in ``folder`` (the one whose SeriesInstanceUID is ``series``, when it holds several;
    of a series with uneven steps, regular run ``run``, from 1, else the longest).
    """
    chosen, aside, plain = _series_files(folder, progress, series)
    if _multiframe(chosen, folder):
        with _header_values(folder):
            volume = read_multiframe(chosen[0][0])
        volume.meta.update(_beside(aside))
        return volume
    items, spacing, meta, direction = _slices_placed(folder, chosen, aside, run)
    at = [plain.get(f) for f, _ in items]
    if all(a is not None for a in at) and len({a.dtype for a in at}) == 1:
        values = read_plain_slices(items, at, progress, folder)
    else:
        values = fill_stack(items, lambda item: (slice_file_values(*item, plain.get(item[0])), item[0].name),
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
            stack = open_multiframe(chosen[0][0])
        stack.meta.update(_beside(aside))
        return stack
    items, spacing, meta, direction = _slices_placed(folder, chosen, aside, run)
    shape = (len(items), int(items[0][1].Rows), int(items[0][1].Columns))
    told = [told_type(ds) for _, ds in items]
    buffers = {}
    found = {slice_file_values(f, ds, plain.get(f), slice_buffer(buffers, shape[1:], plain.get(f))).dtype
             for (f, ds), dtype in zip(items, told, strict=True) if dtype is None}
    dtype = np.result_type(*({dtype for dtype in told if dtype is not None} | found))   # as fill_stack widens

    def read_slices(z0, z1):
        out, buffers = np.empty((z1 - z0, *shape[1:]), dtype), {}
        for k, (f, ds) in enumerate(items[z0:z1]):
            at = plain.get(f)
            place_slice(out, k, slice_file_values(f, ds, at, slice_buffer(buffers, shape[1:], at)), f.name,
                        items[0][0].name)
        return out

    return Stack(shape, dtype, read_slices, spacing, direction, meta, sum(f.stat().st_size for f, _ in items))


def _series_files(folder, progress, series):
    """The files of the chosen series in ``folder`` with their headers, ``[(path, header), ...]``; the files set
    aside as not slices (segmentations, reports ...), ``[(path, kind), ...]``; and where the slices that store
    their pixels plainly hold them, ``{path: Plain}`` (see :func:`plain_pixels`).
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
            ds, position, element = read_header(f)
            decode_header(ds, decoded)
        except damaged as exc:
            raise InputError(f"cannot read DICOM file {f}: {first_line(exc)}") from None
        kind = SEGMENTATIONS.get(header_text(ds, 0x00080016, "", texts))                          # SOPClassUID
        if kind or header_text(ds, 0x00080060, "", texts) in NOT_IMAGES:       # Modality: beside the slices, not one
            aside.append((f, kind or str(ds.get("Modality"))))
            continue
        missing = [key for key in ("Rows", "Columns") if key not in ds]
        if missing:
            kind = str(getattr(ds, "Modality", "") or getattr(ds, "SOPClassUID", "")) or "unknown"
            raise InputError(f"DICOM file {f} holds no image (no {', '.join(missing)}; modality or class: {kind}); "
                             "give a folder of image slices")
        headers.append((f, ds))
        at = plain_pixels(ds, position, element)
        if at is not None:
            plain[f] = at
    if not headers:
        found = ", ".join(f"{kind} {f.name}" for f, kind in aside[:3]) + (" ..." if len(aside) > 3 else "")
        raise InputError(f"{folder} holds no image slices, only {found}; a segmentation is shown on its image: "
                         "give the image's series, with the segmentation as its labels", parameter="labels_from")
    groups = {}
    for f, ds in headers:
        groups.setdefault(header_text(ds, 0x0020000E, "(no SeriesInstanceUID)", texts), []).append((f, ds))
    return choose_series(groups, folder, series), aside, plain


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
        if not any(frame_count(ds) > 1 for _, ds in chosen):
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
        pixel = pixel_spacing(chosen[0][1], chosen[0][0])
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
    if numbers_of(first.get("ImagePositionPatient")) is not None:
        meta["origin"] = numbers_of(first.ImagePositionPatient)
    meta.update(padding_of(first))
    meta.update(_beside(aside))
    return chosen, check_spacing((pixel[1], pixel[0], spacing_z), folder), meta, direction


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
