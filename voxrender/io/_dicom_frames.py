"""An enhanced (multi-frame) DICOM file: its frames placed by their functional groups, or an RT dose grid by its
GridFrameOffsetVector, read whole or a slab of frames at a time.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._shared.text import first_line
from ..errors import InputError
from ._dicom_values import (
    check_pixels_fit,
    compression_note,
    dicom_pixels,
    frame_count,
    padding_of,
    pixel_spacing,
    rescaled_values,
    told_type,
)
from ._shared import Volume, check_spacing, to_grey
from ._stack import Stack
from .dicomfile import (
    BoundedFile,
    damaged_file_errors,
)
from .images import place_slice


def _group(ds, sequence, name):
    """A functional-group attribute of an enhanced DICOM frame's group (or of the shared groups): the value of
    ``name`` in the first item of ``sequence``, or ``None``.
    """
    if ds is None or sequence not in ds or not len(ds[sequence].value):
        return None
    return getattr(ds[sequence].value[0], name, None)


def read_multiframe(path):
    """One multi-frame DICOM file: enhanced CT/MR (functional groups), an RT dose grid (GridFrameOffsetVector),
    or frames in file order (cine, secondary capture) when nothing places them.
    """
    ds, data = dicom_pixels(path)
    placed = _frames_placed(path, ds)
    data = data.reshape((len(placed.order),) + data.shape[-(data.ndim - 1):]) if data.ndim > 2 else data[None]
    values = np.stack([placed.values(data[k], k) for k in placed.order])
    return Volume(values, placed.spacing, placed.meta, placed.direction)


def open_multiframe(path):
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
        values = read_multiframe(path).values
        return Stack(values.shape, values.dtype, lambda z0, z1: values[z0:z1].copy(), placed.spacing,
                     placed.direction, placed.meta)
    count = len(placed.order)
    told = [told_type(ds, *placed.rescale[k]) for k in range(count)]
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
    check_pixels_fit(ds, path, frames=1)
    try:
        with BoundedFile(path) as stream:
            for k, data in zip(frames, iter_pixels(stream, indices=frames), strict=True):
                yield k, placed.values(data, k)
    except InputError:
        raise
    except damaged as exc:
        raise InputError(f"cannot read the pixels of DICOM file {path}{compression_note(ds, damaged)}: "
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
        return rescaled_values(to_grey(data, self.path.name), self.ds, *self.rescale[k])


def _frames_placed(path, ds):
    """Where the header ``ds`` of the multi-frame file ``path`` places its frames (see :class:`_Frames`)."""
    count = frame_count(ds)
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
    row_spacing, column_spacing = pixel_spacing(ds, path, pixel)
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
    meta.update(padding_of(ds))
    spacing = check_spacing((column_spacing, row_spacing, abs(spacing_z)), path)
    return _Frames(path, ds, order, rescale, spacing, meta, direction)
