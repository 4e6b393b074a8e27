"""DICOM RTSTRUCT files written with pydicom, from contours or traced from masks, for tests.

An RTSTRUCT is written the way planning systems write one (DICOM PS3.3 C.8.8.5 and C.8.8.6): a structure set of
ROIs (StructureSetROISequence), their contours in patient coordinates (ROIContourSequence > ContourSequence, LPS
mm, CLOSED_PLANAR with the first point not repeated) and the series they were drawn on
(ReferencedFrameOfReferenceSequence > RTReferencedStudySequence > RTReferencedSeriesSequence).
"""

from dataclasses import dataclass, field

import numpy as np
import pydicom
from pydicom.dataset import Dataset, FileDataset, FileMetaDataset
from pydicom.sequence import Sequence
from pydicom.uid import CTImageStorage, ExplicitVRLittleEndian, RTStructureSetStorage, generate_uid

STUDY_COMPONENT = "1.2.840.10008.3.1.2.3.1"      # Detached Study Management: what RTReferencedStudySequence names


@dataclass
class Roi:
    """One ROI: its ``name``, ``contours`` (each an (N, 3) array of LPS points in mm, or a ``(points, type)`` pair
    for another ContourGeometricType than CLOSED_PLANAR), its ``colour`` (ROIDisplayColor, none when ``None``), its
    ROINumber (by default its place in the list, from 1) and its RTROIInterpretedType (``kind``).
    """

    name: str
    contours: list = field(default_factory=list)
    colour: tuple | None = None
    number: int | None = None
    kind: str = "ORGAN"


def rtstruct_dataset(rois, series_uid=None, frame_of_reference=None, study_uid="1.2.3", image_uids=()):
    """The RTSTRUCT data set of ``rois`` (a list of :class:`Roi`), drawn on series ``series_uid`` (none referenced
    when ``None``) whose slices are ``image_uids``; edit it to damage it, then save it with ``save``.
    """
    frame_of_reference = frame_of_reference or generate_uid()
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = RTStructureSetStorage
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds = FileDataset("rtstruct.dcm", {}, file_meta=meta, preamble=b"\0" * 128)
    ds.SOPClassUID, ds.SOPInstanceUID = RTStructureSetStorage, meta.MediaStorageSOPInstanceUID
    ds.Modality = "RTSTRUCT"
    ds.PatientName, ds.PatientID, ds.PatientBirthDate, ds.PatientSex = "Test^Phantom", "P1", "", "O"
    ds.StudyInstanceUID, ds.SeriesInstanceUID = study_uid, generate_uid()
    ds.StudyDate, ds.StudyTime, ds.StudyID, ds.AccessionNumber = "20240101", "120000", "1", ""
    ds.ReferringPhysicianName, ds.SeriesNumber, ds.InstanceNumber, ds.Manufacturer = "", 2, 1, "voxrender-tests"
    ds.StructureSetLabel, ds.StructureSetDate, ds.StructureSetTime = "test", "20240101", "120000"
    frame = Dataset()
    frame.FrameOfReferenceUID = frame_of_reference
    if series_uid is not None:
        series = Dataset()
        series.SeriesInstanceUID = series_uid
        series.ContourImageSequence = Sequence([_image_item(uid) for uid in image_uids])
        study = Dataset()
        study.ReferencedSOPClassUID, study.ReferencedSOPInstanceUID = STUDY_COMPONENT, study_uid
        study.RTReferencedSeriesSequence = Sequence([series])
        frame.RTReferencedStudySequence = Sequence([study])
    ds.ReferencedFrameOfReferenceSequence = Sequence([frame])
    ds.StructureSetROISequence, ds.ROIContourSequence, ds.RTROIObservationsSequence = Sequence(), Sequence(), \
        Sequence()
    for place, roi in enumerate(rois, start=1):
        number = roi.number if roi.number is not None else place
        item = Dataset()
        item.ROINumber, item.ReferencedFrameOfReferenceUID, item.ROIName = number, frame_of_reference, roi.name
        item.ROIGenerationAlgorithm = "AUTOMATIC"
        ds.StructureSetROISequence.append(item)
        contours = Dataset()
        contours.ReferencedROINumber = number
        if roi.colour is not None:
            contours.ROIDisplayColor = [int(v) for v in roi.colour]
        contours.ContourSequence = Sequence([_contour_item(c) for c in roi.contours])
        ds.ROIContourSequence.append(contours)
        observation = Dataset()
        observation.ObservationNumber, observation.ReferencedROINumber = number, number
        observation.RTROIInterpretedType, observation.ROIInterpreter = roi.kind, ""
        ds.RTROIObservationsSequence.append(observation)
    return ds


def write_rtstruct(path, rois, **references):
    """Write the RTSTRUCT of ``rois`` (see :func:`rtstruct_dataset` for ``references``) to ``path``."""
    save(rtstruct_dataset(rois, **references), path)
    return path


def save(ds, path):
    ds.save_as(path, enforce_file_format=True)
    return path


def references_of(ct_paths):
    """What an RTSTRUCT drawn on the CT slices ``ct_paths`` references: ``series_uid``, ``frame_of_reference``,
    ``study_uid`` and ``image_uids``, from their headers (for :func:`rtstruct_dataset`).
    """
    headers = [pydicom.dcmread(p, stop_before_pixels=True) for p in ct_paths]
    first = headers[0]
    return {"series_uid": str(first.SeriesInstanceUID), "study_uid": str(first.get("StudyInstanceUID", "1.2.3")),
            "frame_of_reference": str(first.get("FrameOfReferenceUID", "")) or None,
            "image_uids": [str(h.SOPInstanceUID) for h in headers]}


def circle(centre, radius, z, points=64):
    """A closed axial contour: ``points`` points on the circle of ``radius`` mm around ``centre`` (x, y), at ``z``."""
    angle = np.linspace(0, 2 * np.pi, points, endpoint=False)
    return np.stack([centre[0] + radius * np.cos(angle), centre[1] + radius * np.sin(angle),
                     np.full(points, float(z))], axis=1)


def square(centre, width, z):
    """A closed axial contour: the square of ``width`` mm around ``centre`` (x, y), at ``z``."""
    half = width / 2
    corners = np.array([[-half, -half], [half, -half], [half, half], [-half, half]]) + np.asarray(centre, float)
    return np.column_stack([corners, np.full(4, float(z))])


def series_affine(spacing, direction=None, origin=(0.0, 0.0, -100.0)):
    """The stored voxel (x, y, z, 1) -> LPS matrix of a series written by ``dicom_files.write_series`` with
    ``spacing`` and ``direction``: what its ImagePositionPatient, ImageOrientationPatient and PixelSpacing say.
    """
    direction = np.eye(3) if direction is None else np.asarray(direction, dtype=float)
    affine = np.eye(4)
    affine[:3, :3] = direction * np.asarray(spacing, dtype=float)[None, :]
    affine[:3, 3] = origin
    return affine


def traced_contours(values, affine, level=0.5, outside=0):
    """The contours of ``values[z, y, x] > level``, slice by slice (one plane of constant z each), traced with
    ``skimage.measure.find_contours`` at ``level`` (the slice padded with ``outside``, so that every contour
    closes) and taken to LPS mm by ``affine`` (voxel (x, y, z, 1) -> LPS); each without its repeated last point.
    """
    from skimage.measure import find_contours

    contours = []
    for z, plane in enumerate(values):
        padded = np.pad(np.asarray(plane, dtype=float), 1, constant_values=outside)
        for traced in find_contours(padded, level):
            rows, columns = traced[:-1, 0] - 1, traced[:-1, 1] - 1
            voxel = np.stack([columns, rows, np.full(len(rows), float(z)), np.ones(len(rows))], axis=1)
            contours.append((voxel @ np.asarray(affine, dtype=float).T)[:, :3])
    return contours


def write_rtstruct_of_labels(path, labels, affine, names, colours=None, outline=None, **references):
    """Write an RTSTRUCT whose ROI k (ROINumber k) outlines ``labels == k``, traced slice by slice
    (:func:`traced_contours`), named ``names[k - 1]``; with ``outline`` (a mask), a last ROI "BODY" of type
    EXTERNAL outlines it.
    """
    rois = [Roi(name, traced_contours(labels == k, affine), None if colours is None else colours[k - 1], k)
            for k, name in enumerate(names, start=1)]
    if outline is not None:
        rois.append(Roi("BODY", traced_contours(outline, affine), (0, 255, 0), len(names) + 1, "EXTERNAL"))
    return write_rtstruct(path, rois, **references)


def _image_item(uid):
    item = Dataset()
    item.ReferencedSOPClassUID, item.ReferencedSOPInstanceUID = CTImageStorage, uid
    return item


def _contour_item(contour):
    points, kind = contour if isinstance(contour, tuple) else (contour, "CLOSED_PLANAR")
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    item = Dataset()
    item.ContourGeometricType = kind
    item.NumberOfContourPoints = len(points)
    item.ContourData = [f"{v:.10g}" for v in points.ravel()]           # DS: at most 16 characters a value
    return item
