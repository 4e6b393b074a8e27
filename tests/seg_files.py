"""DICOM SEG files written with highdicom from CT series written by ``dicom_files.write_series``, for tests."""

from pathlib import Path

import numpy as np
import pydicom
from dicom_files import write_series
from pydicom.uid import generate_uid

# What highdicom needs of its source images beyond the slices write_series writes (patient, study, series and
# frame-of-reference modules); a real series has them already.
SOURCE_DEFAULTS = {"PatientName": "Test^Phantom", "PatientID": "P1", "PatientBirthDate": "", "PatientSex": "O",
                   "StudyDate": "20240101", "StudyTime": "120000", "StudyID": "1", "AccessionNumber": "",
                   "ReferringPhysicianName": "", "SeriesNumber": 1}


SHAPE = (12, 20, 24)                                    # [z, y, x] of the test SEGs' CT


def blobs(shape=SHAPE):
    """A label map [z, y, x] of three blobs: a ball, a box and a slab on two slices only (a SEG stores only the
    frames that hold a segment, so its grid is shorter than its CT's)."""
    z, y, x = np.mgrid[:shape[0], :shape[1], :shape[2]]
    labels = np.zeros(shape, np.uint8)
    labels[(x - 8) ** 2 + (y - 9) ** 2 + ((z - 5) * 2.5) ** 2 <= 36] = 1
    labels[2:9, 3:8, 15:21] = 2
    labels[8:10, 12:18, 2:22] = 3
    return labels


def complete_sources(paths, frame_of_reference=None):
    """The CT slices in ``paths``, completed on disk with what highdicom asks of a SEG's source images (only what
    they lack, one FrameOfReferenceUID for the series), read back as data sets in the order of ``paths``.
    """
    frame_of_reference = frame_of_reference or generate_uid()
    datasets = []
    for path in paths:
        ds = pydicom.dcmread(path)
        missing = {key: value for key, value in SOURCE_DEFAULTS.items() if key not in ds}
        if missing or "FrameOfReferenceUID" not in ds:
            for key, value in missing.items():
                setattr(ds, key, value)
            ds.FrameOfReferenceUID = ds.get("FrameOfReferenceUID", frame_of_reference)
            ds.save_as(path, enforce_file_format=True)
        datasets.append(ds)
    return datasets


def write_ct(folder, shape, spacing=(0.7, 0.8, 2.5), direction=None, values=None):
    """A CT series of ``shape`` [z, y, x] (``values``, else a flat -1000 HU) in ``folder``, ready to be a SEG's
    source: its data sets, slice z at index z.
    """
    stored = np.zeros(shape, np.int16) if values is None else np.asarray(values, np.int16) + 1024
    paths = write_series(Path(folder), stored, spacing=spacing, direction=direction)
    return complete_sources(paths)


def segment_description(number, name, colour=None):
    """A highdicom segment description: ``number``, SegmentLabel ``name``, and ``colour`` (sRGB 0..255) as its
    RecommendedDisplayCIELabValue, when given.
    """
    import highdicom as hd
    from pydicom.sr.codedict import codes

    algorithm = hd.AlgorithmIdentificationSequence(name="voxrender-tests", version="1",
                                                   family=codes.cid7162.ArtificialIntelligence)
    colour = None if colour is None else hd.color.CIELabColor.from_rgb(*colour)
    return hd.seg.SegmentDescription(segment_number=number, segment_label=name,
                                     segmented_property_category=codes.SCT.Tissue,
                                     segmented_property_type=codes.SCT.Tissue,
                                     algorithm_type=hd.seg.SegmentAlgorithmTypeValues.AUTOMATIC,
                                     algorithm_identification=algorithm, display_color=colour)


def write_seg(path, sources, segments, names, kind="BINARY", colours=None, numbers=None, **options):
    """Write a SEG of ``sources`` (the CT's data sets, slice z at index z) to ``path`` with highdicom.

    ``segments`` is a label map [z, y, x] of segment numbers, or stacked masks (or fractions, for FRACTIONAL)
    [z, y, x, k] of segment ``numbers[k]`` (1, 2 ... by default); ``names`` and ``colours`` (sRGB, or ``None``)
    describe them in that order.  ``options`` go to ``highdicom.seg.Segmentation`` (``omit_empty_frames`` ...).
    """
    import highdicom as hd

    numbers = numbers or list(range(1, len(names) + 1))
    colours = colours or [None] * len(names)
    descriptions = [segment_description(n, name, colour)
                    for n, name, colour in zip(numbers, names, colours, strict=True)]
    seg = hd.seg.Segmentation(source_images=sources, pixel_array=segments, segmentation_type=kind,
                              segment_descriptions=descriptions, series_instance_uid=hd.UID(), series_number=100,
                              sop_instance_uid=hd.UID(), instance_number=1, manufacturer="voxrender",
                              manufacturer_model_name="tests", software_versions="1", device_serial_number="0",
                              **options)
    seg.save_as(path)
    return Path(path)


def write_ct_and_seg(folder, labels, names, kind="BINARY", spacing=(0.7, 0.8, 2.5), direction=None, **options):
    """A CT series (``folder / "ct"``) of the shape of ``labels`` [z, y, x] and its SEG (``folder / "seg.dcm"``)
    of those labels: ``(ct_folder, seg_path)``.
    """
    folder = Path(folder)
    sources = write_ct(folder / "ct", labels.shape, spacing, direction)
    return folder / "ct", write_seg(folder / "seg.dcm", sources, labels, names, kind, **options)
