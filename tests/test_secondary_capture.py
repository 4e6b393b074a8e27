"""The DICOM Secondary Capture output: a picture of a CT series, in a new series of its study."""

import os
import stat
import warnings

import highdicom as hd
import numpy as np
import pydicom
import pytest
from dicom_files import write_enhanced, write_series
from pydicom.uid import SecondaryCaptureImageStorage
from seg_files import SOURCE_DEFAULTS, blobs, write_ct

import voxrender
from voxrender.errors import InputError
from voxrender.io import Volume
from voxrender.object.pipeline import PrepOptions, load_segments
from voxrender.object.prep import LabelSelection
from voxrender.outputs import output_kinds
from voxrender.outputs.picture_outputs import Outputs, about, write_outputs
from voxrender.outputs.secondary_capture import DicomStudy, describe, dicom_study, write_secondary_capture
from voxrender.pictures._picture import RenderOptions, picture

SHAPE = (12, 20, 24)


@pytest.fixture
def ct(tmp_path):
    """A CT series of a ball (1000 HU in -1000 HU), its patient and study completed as a real series has them."""
    z, y, x = np.mgrid[:SHAPE[0], :SHAPE[1], :SHAPE[2]]
    values = np.where((x - 12) ** 2 + (y - 10) ** 2 + ((z - 6) * 2) ** 2 <= 40, 1000, -1000)
    folder = tmp_path / "ct"
    write_ct(folder, SHAPE, values=values)
    sources = []
    for path in sorted(folder.iterdir()):
        ds = pydicom.dcmread(path)
        ds.AccessionNumber, ds.Manufacturer, ds.SeriesNumber = "ACC42", "Scanner Co", 3
        ds.save_as(path, enforce_file_format=True)
        sources.append(ds)
    return folder, sources


def test_a_picture_of_a_ct_joins_its_study_in_a_new_series(ct, tmp_path):
    folder, sources = ct
    study = dicom_study(folder)
    assert len(study.images) == SHAPE[0] and study.series_uid == sources[0].SeriesInstanceUID
    encoded = load_segments(folder, prepare=PrepOptions(threshold=300))
    options = RenderOptions(size=(48, 64))
    result = picture(encoded, options.view(*voxrender.space.view.PRESETS["anterior"]), options)
    report = {**about(encoded.segments), "dicom_study": study}
    out = tmp_path / "ball.dcm"
    write_outputs(result, Outputs(tmp_path / "ball.png", dicom=out), report)

    sc = pydicom.dcmread(out)
    np.testing.assert_array_equal(sc.pixel_array, result.rgb)
    for keyword in ("PatientID", "PatientName", "StudyInstanceUID", "AccessionNumber", "StudyDate"):
        assert sc[keyword].value == sources[0][keyword].value, keyword
    assert sc.AccessionNumber == "ACC42"
    # the single-frame Secondary Capture Image Storage: highdicom's SCImage writes that class (one RGB frame is all
    # a picture is; the multi-frame true colour SC would be for a stack of them)
    assert sc.SOPClassUID == SecondaryCaptureImageStorage == sc.file_meta.MediaStorageSOPClassUID
    assert sc.SeriesInstanceUID != sources[0].SeriesInstanceUID
    assert sc.SOPInstanceUID not in {ds.SOPInstanceUID for ds in sources}
    assert sc.SeriesInstanceUID.is_valid and sc.SOPInstanceUID.is_valid
    assert list(sc.ImageType)[:2] == ["DERIVED", "SECONDARY"]
    assert sc.ConversionType == "WSD" and sc.Manufacturer == "voxrender"
    assert sc.SoftwareVersions == voxrender.__version__
    assert sc.SeriesNumber == 1003
    assert sc.DerivationDescription == f"voxrender {voxrender.__version__}: ftb, view alpha 90 beta 0 gamma 0, " \
                                       "threshold 300"
    assert list(sc.PatientOrientation) == ["L", "F"]            # from the front: rows to the left, columns down
    assert sc.PhotometricInterpretation == "RGB" and sc.SamplesPerPixel == 3
    # the scanner that made the source is kept, as equipment that contributed to the picture
    assert "Scanner Co" in [item.Manufacturer for item in sc.ContributingEquipmentSequence]
    source_uids = {ds.SOPInstanceUID for ds in sources}
    assert {item.ReferencedSOPInstanceUID for item in sc.SourceImageSequence} == source_uids
    (series,) = sc.ReferencedSeriesSequence
    assert series.SeriesInstanceUID == sources[0].SeriesInstanceUID
    assert {item.ReferencedSOPInstanceUID for item in series.ReferencedInstanceSequence} == source_uids
    assert {item.ReferencedSOPClassUID for item in sc.SourceImageSequence} == {sources[0].SOPClassUID}

    image = hd.imread(out)          # highdicom 0.28 reads an SC as its general Image (SCImage has no reader)
    assert image.SOPClassUID == SecondaryCaptureImageStorage
    np.testing.assert_array_equal(image.get_frame(1), result.rgb)


def test_a_labelled_picture_keeps_its_colours_and_names_its_labels(ct, tmp_path):
    folder, _ = ct
    labels = Volume(blobs(SHAPE), (0.7, 0.8, 2.5), {"source": "blobs.nii.gz"})
    encoded = load_segments(folder, prepare=PrepOptions(threshold=None, labels=LabelSelection(None, True, labels)))
    result = picture(encoded, RenderOptions(size=(40, 40)).view(90, 90, 0), RenderOptions(size=(40, 40)))
    assert len(np.unique(result.rgb.reshape(-1, 3), axis=0)) > 20         # coloured, shaded
    out = tmp_path / "labels.dcm"
    output_kinds.OUTPUTS["dicom"].write(out, result, {**about(encoded.segments), "dicom_study": dicom_study(folder)})
    sc = pydicom.dcmread(out)
    np.testing.assert_array_equal(sc.pixel_array, result.rgb)
    assert sc.DerivationDescription.endswith("view alpha 90 beta 90 gamma 0, labels 1, 2, 3 of blobs.nii.gz")
    assert list(sc.PatientOrientation) == ["P", "F"]            # from the left: rows toward the back


def test_pictures_of_a_study_can_share_a_series(ct, tmp_path):
    folder, _ = ct
    study = dicom_study(folder)
    uid = pydicom.uid.generate_uid()
    for k in (1, 2):
        write_secondary_capture(tmp_path / f"{k}.dcm", np.full((8, 8, 3), k, np.uint8), study, "test",
                                series_uid=uid, instance_number=k)
    first, second = (pydicom.dcmread(tmp_path / f"{k}.dcm") for k in (1, 2))
    assert first.SeriesInstanceUID == second.SeriesInstanceUID == uid
    assert first.SOPInstanceUID != second.SOPInstanceUID
    assert (first.InstanceNumber, second.InstanceNumber) == (1, 2)
    assert "PatientOrientation" in first and first.PatientOrientation == ""      # type 2: present, unknown


def test_one_slice_or_an_enhanced_file_names_the_series(ct, tmp_path):
    folder, sources = ct
    one_slice = dicom_study(sorted(folder.iterdir())[3])
    assert set(one_slice.images) == set(dicom_study(folder).images)

    path = write_enhanced(tmp_path / "enhanced.dcm", np.zeros((5, 6, 7), np.int16))
    ds = pydicom.dcmread(path)
    for key, value in SOURCE_DEFAULTS.items():
        setattr(ds, key, value)
    ds.save_as(path, enforce_file_format=True)
    study = dicom_study(path)
    assert study.images == ((ds.SOPClassUID, ds.SOPInstanceUID),)
    write_secondary_capture(tmp_path / "sc.dcm", np.zeros((4, 4, 3), np.uint8), study, "enhanced")
    sc = pydicom.dcmread(tmp_path / "sc.dcm")
    assert sc.SourceImageSequence[0].ReferencedSOPClassUID == "1.2.840.10008.5.1.4.1.1.2.1"   # Enhanced CT
    assert sc.StudyInstanceUID == ds.StudyInstanceUID and sc.PatientID == "P1"


def test_a_folder_of_two_series_is_chosen_from(ct, tmp_path):
    folder, sources = ct
    seg = pydicom.Dataset()             # a segmentation beside the slices is not one of the series to choose from
    seg.SOPClassUID, seg.SOPInstanceUID = "1.2.840.10008.5.1.4.1.1.66.4", pydicom.uid.generate_uid()
    seg.SeriesInstanceUID, seg.Modality = pydicom.uid.generate_uid(), "SEG"
    seg.save_as(folder / "seg.dcm", implicit_vr=True, little_endian=True)
    assert len(dicom_study(folder).images) == SHAPE[0]
    write_series(folder, np.zeros((2, 4, 4)), names=["other1.dcm", "other2.dcm"])
    with pytest.raises(InputError, match="holds 2 DICOM series") as error:
        dicom_study(folder)
    assert error.value.parameter == "series"
    chosen = dicom_study(folder, series=sources[0].SeriesInstanceUID)
    assert len(chosen.images) == SHAPE[0]


def test_what_is_not_dicom_has_no_study_to_join(tmp_path):
    nifti = tmp_path / "ct.nii.gz"
    voxrender.outputs.output.write_nifti(nifti, np.zeros((2, 3, 4), np.int16))
    pngs = tmp_path / "pngs"
    voxrender.outputs.output.write_slices(np.zeros((2, 3, 4), np.uint16), pngs)
    for path in (nifti, pngs, tmp_path / "missing"):
        with pytest.raises(InputError) as error:
            dicom_study(path)
        assert error.value.parameter == "dicom_study_from"
        assert str(error.value.message) == f"{path} is not DICOM, so the picture has no study to join; name the " \
                                           "DICOM series it was made from"
        assert "\n" not in str(error.value)


def test_the_dicom_output_needs_its_study(tmp_path):
    ball = voxrender.object.segments.encode(np.ones((3, 3, 3), bool))
    result = picture(ball, RenderOptions(size=(8, 8)).view())
    with pytest.raises(InputError, match="name that series") as error:
        write_outputs(result, Outputs(tmp_path / "p.png", dicom=tmp_path / "p.dcm"), about(ball))
    assert error.value.parameter == "dicom_study_from"
    assert not (tmp_path / "p.dcm").exists()


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes in a read-only folder")
def test_a_failed_write_leaves_no_file(ct, tmp_path):
    folder, _ = ct
    study = dicom_study(folder)
    out = tmp_path / "out"
    out.mkdir()
    out.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        with pytest.raises(InputError, match="not writable"):
            write_secondary_capture(out / "p.dcm", np.zeros((4, 4, 3), np.uint8), study, "test")
        assert list(out.iterdir()) == []
    finally:
        out.chmod(stat.S_IRWXU)


def test_a_write_that_fails_midway_leaves_no_file(ct, tmp_path, monkeypatch):
    study = dicom_study(ct[0])

    def fail(self, *args, **kwargs):
        with open(args[0], "wb") as f:
            f.write(b"half a file")
        raise OSError("disk full")

    monkeypatch.setattr(pydicom.Dataset, "save_as", fail)
    with pytest.raises(OSError, match="disk full"):
        write_secondary_capture(tmp_path / "p.dcm", np.zeros((4, 4, 3), np.uint8), study, "test")
    assert list(tmp_path.glob("*.dcm")) == [] and list(tmp_path.glob(".p.dcm*")) == []


def test_describe_and_its_limit(ct, tmp_path):
    from types import SimpleNamespace

    result = SimpleNamespace(image=SimpleNamespace(method="octree", view=voxrender.View(10, 20.5, 30)),
                             rgb=np.zeros((4, 4, 3), np.uint8))
    text = describe(result, {"object": {"threshold": "-100:300"}, "projection": "mip"})
    assert text == f"voxrender {voxrender.__version__}: octree, view alpha 10 beta 20.5 gamma 30, projection mip, " \
                   "threshold -100:300"
    projection = SimpleNamespace(image=SimpleNamespace(method="mip", view=voxrender.View(90, 0, 0)), projection="mip")
    assert describe(projection, {"object": {}}).endswith(": view alpha 90 beta 0 gamma 0, projection mip")
    long = "x" * 2000
    write_secondary_capture(tmp_path / "p.dcm", result.rgb, dicom_study(ct[0]), long)
    assert pydicom.dcmread(tmp_path / "p.dcm").DerivationDescription == long[:1024]


def test_rgb_must_be_8_bit_colour(ct, tmp_path):
    study = DicomStudy(pydicom.dcmread(sorted(ct[0].iterdir())[0], stop_before_pixels=True), (), "1.2", "ct")
    with pytest.raises(InputError, match=r"\(H, W, 3\) uint8") as error:
        write_secondary_capture(tmp_path / "p.dcm", np.zeros((4, 4), np.uint16), study, "grey")
    assert error.value.parameter == "rgb"


def test_the_source_names_are_copied_without_warnings(ct, tmp_path):
    source = pydicom.dcmread(sorted(ct[0].iterdir())[0], stop_before_pixels=True)
    source.PatientName, source.ReferringPhysicianName = "Eve", "Unknown"      # one word, as vhf_head has them
    study = DicomStudy(source, (), source.SeriesInstanceUID, "ct")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        write_secondary_capture(tmp_path / "p.dcm", np.zeros((4, 4, 3), np.uint8), study, "test")
    assert pydicom.dcmread(tmp_path / "p.dcm").PatientName == "Eve"


def test_the_outputs_are_written_all_or_none(tmp_path):
    """A composite picture (slices, a sheet) goes through OUTPUTS as a rendered one does; when one output fails
    (here the DICOM, which has no study to join), the PNG written before it is taken away."""
    from voxrender.outputs import Composite

    rgb = np.zeros((4, 6, 3), np.uint8)
    with pytest.raises(InputError, match="joins the study"):
        write_outputs(Composite(rgb, "slices axial"), Outputs(tmp_path / "p.png", dicom=tmp_path / "p.dcm"), {})
    assert list(tmp_path.iterdir()) == []
    write_outputs(Composite(rgb, "slices axial"), Outputs(tmp_path / "p.png"))
    assert [p.name for p in tmp_path.iterdir()] == ["p.png"]
    with pytest.raises(InputError, match="no depth"):                 # what a composite lacks is refused first
        write_outputs(Composite(rgb, "slices axial"), Outputs(tmp_path / "q.png", depth=tmp_path / "q.npy"))
