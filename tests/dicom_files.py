"""Small DICOM series written with pydicom, for reader tests."""

import numpy as np
from pydicom.dataset import FileDataset, FileMetaDataset
from pydicom.uid import CTImageStorage, ExplicitVRLittleEndian, generate_uid


def write_series(folder, volume, spacing=(0.5, 0.6, 2.0), series_uid=None, slope=1, intercept=-1024,
                 names=None, shuffle_seed=0, positions=True, instance_numbers=True, description="test",
                 direction=None):
    """Write ``volume[z, y, x]`` (stored integers) as one CT slice per file, file names shuffled.

    ``direction`` (3 x 3, columns: the LPS directions of x, y and the slice order; axial by default) sets
    ImageOrientationPatient and the slice positions.
    """
    direction = np.eye(3) if direction is None else np.asarray(direction, dtype=float)
    folder.mkdir(parents=True, exist_ok=True)
    series_uid = series_uid or generate_uid()
    order = np.random.default_rng(shuffle_seed).permutation(len(volume))
    paths = []
    for z in range(len(volume)):
        meta = FileMetaDataset()
        meta.MediaStorageSOPClassUID = CTImageStorage
        meta.MediaStorageSOPInstanceUID = generate_uid()
        meta.TransferSyntaxUID = ExplicitVRLittleEndian
        name = names[z] if names else f"img{order[z]:04d}.dcm"
        ds = FileDataset(str(folder / name), {}, file_meta=meta, preamble=b"\0" * 128)
        ds.SOPClassUID = CTImageStorage
        ds.SOPInstanceUID = meta.MediaStorageSOPInstanceUID
        ds.Modality = "CT"
        ds.SeriesInstanceUID = series_uid
        ds.SeriesDescription = description
        ds.StudyInstanceUID = "1.2.3"
        if instance_numbers:
            ds.InstanceNumber = z + 1
        if positions:
            ds.ImagePositionPatient = [float(v) for v in (np.array([0, 0, -100]) + z * spacing[2] * direction[:, 2])]
            ds.ImageOrientationPatient = [float(v) for v in (*direction[:, 0], *direction[:, 1])]
        ds.PixelSpacing = [spacing[1], spacing[0]]
        ds.SliceThickness = spacing[2]
        _signed_16_bit_pixels(ds, volume.shape[1:])
        ds.RescaleSlope = slope
        ds.RescaleIntercept = intercept
        ds.PixelData = np.ascontiguousarray(volume[z], dtype=np.int16).tobytes()
        ds.save_as(folder / name, enforce_file_format=True)
        paths.append(folder / name)
    return paths


def write_enhanced(path, volume, spacing=(0.5, 0.6, 2.0), slope=1, intercept=-1024, direction=None,
                   shuffle_seed=0, positions=True, series_uid=None):
    """Write ``volume[z, y, x]`` as one enhanced multi-frame CT file (functional groups), frames shuffled."""
    from pydicom.dataset import Dataset
    from pydicom.sequence import Sequence

    direction = np.eye(3) if direction is None else np.asarray(direction, dtype=float)
    order = np.random.default_rng(shuffle_seed).permutation(len(volume))
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = "1.2.840.10008.5.1.4.1.1.2.1"      # Enhanced CT Image Storage
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds = FileDataset(str(path), {}, file_meta=meta, preamble=b"\0" * 128)
    ds.SOPClassUID = meta.MediaStorageSOPClassUID
    ds.SOPInstanceUID = meta.MediaStorageSOPInstanceUID
    ds.Modality = "CT"
    ds.SeriesInstanceUID = series_uid or generate_uid()
    ds.StudyInstanceUID = "1.2.3"
    ds.NumberOfFrames = len(volume)
    _signed_16_bit_pixels(ds, volume.shape[1:])
    shared = Dataset()
    measures, plane = Dataset(), Dataset()
    measures.PixelSpacing = [spacing[1], spacing[0]]
    measures.SliceThickness = spacing[2]
    plane.ImageOrientationPatient = [float(v) for v in (*direction[:, 0], *direction[:, 1])]
    shared.PixelMeasuresSequence = Sequence([measures])
    shared.PlaneOrientationSequence = Sequence([plane])
    ds.SharedFunctionalGroupsSequence = Sequence([shared])
    frames = []
    for z in order:
        group, position, rescale = Dataset(), Dataset(), Dataset()
        if positions:
            corner = np.array([0, 0, -100]) + z * spacing[2] * direction[:, 2]
            position.ImagePositionPatient = [float(v) for v in corner]
            group.PlanePositionSequence = Sequence([position])
        rescale.RescaleSlope, rescale.RescaleIntercept, rescale.RescaleType = slope, intercept, "HU"
        group.PixelValueTransformationSequence = Sequence([rescale])
        frames.append(group)
    ds.PerFrameFunctionalGroupsSequence = Sequence(frames)
    ds.PixelData = np.ascontiguousarray(volume[order], dtype=np.int16).tobytes()
    ds.save_as(path, enforce_file_format=True)
    return path


def _signed_16_bit_pixels(ds, rows_columns):
    """The image pixel module of signed 16-bit greyscale slices of ``rows_columns``."""
    ds.Rows, ds.Columns = rows_columns
    ds.SamplesPerPixel = 1
    ds.PhotometricInterpretation = "MONOCHROME2"
    ds.BitsAllocated = ds.BitsStored = 16
    ds.HighBit = 15
    ds.PixelRepresentation = 1
