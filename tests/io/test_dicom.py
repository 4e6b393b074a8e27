"""voxrender.io.dicom: DICOM series, classic and enhanced."""

import subprocess
import sys
import warnings

import numpy as np
import pydicom
import pytest
from conftest import data_path
from dicom_files import write_enhanced, write_series
from formats import refused_cuts

from voxrender import io
from voxrender.errors import InputError


def test_dicom_series_sorted_by_position_and_rescaled(tmp_path):
    stored = np.random.default_rng(3).integers(0, 2000, size=(6, 4, 5))
    write_series(tmp_path, stored, spacing=(0.5, 0.6, 2.0))
    volume = io.read_volume(tmp_path)
    assert volume.meta["format"] == "dicom" and volume.meta["sorted_by"] == "ImagePositionPatient"
    assert np.array_equal(volume.values, stored - 1024)
    assert volume.spacing == (0.5, 0.6, 2.0)
    assert volume.meta["units"] == "HU"


def test_dicom_falls_back_to_instance_number(tmp_path):
    stored = np.random.default_rng(4).integers(0, 2000, size=(4, 3, 3))
    write_series(tmp_path, stored, positions=False)
    volume = io.read_volume(tmp_path)
    assert volume.meta["sorted_by"] == "InstanceNumber"
    assert np.array_equal(volume.values, stored - 1024)


def test_dicom_fractional_rescale_gives_float(tmp_path):
    stored = np.arange(2 * 3 * 3).reshape(2, 3, 3)
    write_series(tmp_path, stored, slope=0.5, intercept=1.25)
    values = io.read_volume(tmp_path).values
    assert values.dtype == np.float32 and np.allclose(values, stored * 0.5 + 1.25)


def test_two_series_need_a_choice(tmp_path):
    write_series(tmp_path, np.zeros((2, 3, 3)), series_uid="1.2.3.1", names=["a1.dcm", "a2.dcm"])
    write_series(tmp_path, np.ones((3, 3, 3)), series_uid="1.2.3.2", names=["b1.dcm", "b2.dcm", "b3.dcm"])
    with pytest.raises(InputError, match="choose one by its UID") as info:
        io.read_volume(tmp_path)
    assert info.value.parameter == "series"
    assert "1.2.3.1 (2 slices" in str(info.value) and "1.2.3.2 (3 slices" in str(info.value)
    assert io.read_volume(tmp_path, series="1.2.3.2").shape == (3, 3, 3)
    with pytest.raises(InputError, match="no series 9.9"):
        io.read_volume(tmp_path, series="9.9")


def test_truncated_dicom(tmp_path):
    paths = write_series(tmp_path, np.zeros((3, 8, 8)))
    paths[1].write_bytes(paths[1].read_bytes()[:-60])
    with pytest.raises(InputError, match="DICOM file"):
        io.read_volume(tmp_path)


def test_corrupt_dicom_header(tmp_path):
    paths = write_series(tmp_path, np.zeros((3, 8, 8)))
    paths[0].write_bytes(b"\0" * 128 + b"DICM" + b"\xff" * 50)
    with pytest.raises(InputError, match="DICOM file"):
        io.read_volume(tmp_path)


def test_one_dicom_file_points_to_its_folder(tmp_path):
    paths = write_series(tmp_path, np.zeros((2, 4, 4)))
    with pytest.raises(InputError, match="folder that holds the whole series"):
        io.read_volume(paths[0])


def test_dicom_in_nested_folders(tmp_path):
    stored = np.random.default_rng(6).integers(0, 2000, size=(4, 5, 6))
    write_series(tmp_path / "export" / "patient" / "study", stored)
    (tmp_path / "export" / "README.txt").write_text("exported")
    volume = io.read_volume(tmp_path / "export")
    assert np.array_equal(volume.values, stored - 1024)


@pytest.mark.parametrize("syntax", ["RLELossless", "JPEG2000Lossless"])
def test_compressed_dicom(tmp_path, syntax):
    import pydicom
    from pydicom import uid

    stored = np.random.default_rng(7).integers(0, 2000, size=(3, 64, 64))
    for path in write_series(tmp_path, stored):
        ds = pydicom.dcmread(path)
        ds.compress(getattr(uid, syntax), ds.pixel_array.astype(np.int16))
        ds.save_as(path)
    assert np.array_equal(io.read_volume(tmp_path).values, stored - 1024)


def test_dicom_positions_without_orientation(tmp_path):
    import pydicom

    stored = np.random.default_rng(8).integers(0, 2000, size=(4, 3, 3))
    for path in write_series(tmp_path, stored):
        ds = pydicom.dcmread(path)
        del ds.ImageOrientationPatient
        ds.save_as(path)
    volume = io.read_volume(tmp_path)
    assert volume.meta["sorted_by"] == "ImagePositionPatient" and np.array_equal(volume.values, stored - 1024)


def test_vhf_head_dicom():
    volume = io.read_volume(data_path("vhf_head"))
    assert volume.shape == (234, 512, 512) and volume.spacing == (1.0, 1.0, 1.0)
    assert volume.meta["units"] == "HU" and volume.values.dtype == np.int16
    assert volume.values.min() <= -1000 and volume.values.max() > 1000
    # Slices run from the neck up: the top slice holds less bone than the middle ones.
    bone = (volume.values >= 300).sum(axis=(1, 2))
    assert bone[-1] < bone[len(bone) // 2]


def test_enhanced_ct_gives_the_same_volume_as_its_classic_series(tmp_path):
    stored = np.random.default_rng(5).integers(0, 2000, (6, 7, 8)).astype(np.int16)
    write_series(tmp_path / "classic", stored, intercept=-1024)
    (tmp_path / "enhanced").mkdir()
    write_enhanced(tmp_path / "enhanced" / "ct.dcm", stored, intercept=-1024)
    classic, enhanced = io.read_volume(tmp_path / "classic"), io.read_volume(tmp_path / "enhanced")
    assert np.array_equal(classic.values, enhanced.values) and classic.spacing == enhanced.spacing
    assert enhanced.meta["units"] == "HU" and enhanced.meta["sorted_by"] == "per-frame ImagePositionPatient"


def test_a_folder_with_a_classic_and_an_enhanced_series_lists_both(tmp_path):
    stored = np.zeros((3, 4, 4), np.int16)
    write_series(tmp_path, stored, series_uid="1.2.3.7")
    write_enhanced(tmp_path / "enhanced.dcm", stored, series_uid="1.2.3.8")
    with pytest.raises(InputError, match="2 DICOM series") as info:
        io.read_volume(tmp_path)
    assert "1.2.3.7" in str(info.value) and "1.2.3.8" in str(info.value)
    assert io.read_volume(tmp_path, series="1.2.3.8").shape == (3, 4, 4)


def test_an_enhanced_dicom_without_positions_is_refused(tmp_path):
    write_enhanced(tmp_path / "ct.dcm", np.zeros((3, 4, 4), np.int16), positions=False)
    with pytest.raises(InputError, match="frames lack ImagePositionPatient"):
        io.read_volume(tmp_path)


def test_one_dicom_file_is_refused_whatever_names_it(tmp_path):
    paths = write_series(tmp_path, np.zeros((2, 4, 4)))
    bare = paths[0].rename(tmp_path / "slice")                  # no suffix: its magic bytes say DICOM
    assert io.detect_format(bare) == "dicom"
    for path, format in [(bare, "auto"), (paths[1], "dicom")]:
        with pytest.raises(InputError, match="one DICOM file; give the folder that holds the whole series"):
            io.read_volume(path, format=format)


@pytest.mark.parametrize("kind", ["classic", "RLELossless", "JPEG2000Lossless", "enhanced"])
def test_cut_dicom_files_are_bad_input(tmp_path, kind):
    """pydicom's errors for a cut-off file (struct.error, BytesLengthException, a decoder's RuntimeError ...) are bad
    input."""
    import pydicom
    from pydicom import uid

    stored = np.random.default_rng(9).integers(0, 2000, size=(3, 64, 64))
    if kind == "enhanced":
        victim = write_enhanced(tmp_path / "ct.dcm", stored.astype(np.int16))
    else:
        victim = write_series(tmp_path, stored)[-1]
    if kind not in ("classic", "enhanced"):
        ds = pydicom.dcmread(victim)
        ds.compress(getattr(uid, kind), ds.pixel_array.astype(np.int16))
        ds.save_as(victim)
    assert refused_cuts(victim, lambda: io.read_volume(tmp_path)) >= 30


def _edit(paths, **values):
    """Set header ``values`` (keyword: value; None deletes) in each of the DICOM files ``paths``."""
    import pydicom

    for path in paths:
        ds = pydicom.dcmread(path)
        for keyword, value in values.items():
            if value is None:
                delattr(ds, keyword)
            else:
                setattr(ds, keyword, value)
        ds.save_as(path)


def test_a_one_value_pixel_spacing_is_bad_input(tmp_path):
    """Was "'DSfloat' object is not iterable" (exit 1)."""
    import pydicom

    _edit(write_series(tmp_path / "classic", np.zeros((3, 4, 4))), PixelSpacing="0.5")
    with pytest.raises(InputError, match=r"its PixelSpacing 0.5 is not two numbers"):
        io.read_volume(tmp_path / "classic")
    (tmp_path / "enhanced").mkdir()
    path = write_enhanced(tmp_path / "enhanced" / "e.dcm", np.zeros((3, 4, 4)))
    ds = pydicom.dcmread(path)
    ds.SharedFunctionalGroupsSequence[0].PixelMeasuresSequence[0].PixelSpacing = "0.5"
    ds.save_as(path)
    with pytest.raises(InputError, match=r"its PixelSpacing 0.5 is not two numbers"):
        io.read_volume(tmp_path / "enhanced")


def test_a_one_value_image_position_falls_back_to_instance_numbers(tmp_path):
    _edit(write_series(tmp_path, np.zeros((3, 4, 4))), ImagePositionPatient="5")
    volume = io.read_volume(tmp_path)
    assert volume.meta["sorted_by"] == "InstanceNumber" and "origin" not in volume.meta


@pytest.mark.parametrize("slope", ["1e300", "inf", "nan"])
def test_a_huge_or_non_finite_rescale_slope_is_bad_input(tmp_path, slope):
    """One beyond float32 (or not finite) gave inf or NaN voxels."""
    _edit(write_series(tmp_path, np.ones((3, 4, 4))), RescaleSlope=slope)
    with pytest.raises(InputError, match=r"RescaleSlope .* take its values 1 to 1 beyond any number; the file is "
                                         "damaged"):
        io.read_volume(tmp_path)


@pytest.mark.parametrize("slope, intercept, dtype", [(100000, 0, np.int32), (10**12, 0, np.float32),
                                                     (1, 10**10, np.float32), (1e20, 0, np.float32)])
def test_a_large_rescale_that_fits_gives_its_values(tmp_path, slope, intercept, dtype):
    """A whole slope that overflowed int32 was an internal error (exit 1): beyond int32, the values are float32."""
    write_series(tmp_path, np.full((2, 3, 3), 7), slope=slope, intercept=intercept)
    values = io.read_volume(tmp_path).values
    assert values.dtype == dtype and np.allclose(values, 7 * float(slope) + intercept)


def test_a_padding_value_is_kept_in_the_volumes_units(tmp_path):
    """PixelPaddingValue (stored values) marks the outside of the scan circle; meta says it in HU."""
    import pydicom

    for path in write_series(tmp_path, np.full((2, 3, 3), 100)):
        ds = pydicom.dcmread(path)
        ds.add_new(0x00280120, "SS", -2000)                    # PixelPaddingValue, of the pixels' VR
        ds.save_as(path)
    assert io.read_volume(tmp_path).meta["padding_value"] == -3024
    write_series(tmp_path / "none", np.full((2, 3, 3), 100))
    assert "padding_value" not in io.read_volume(tmp_path / "none").meta


def test_slices_too_big_for_memory_are_refused_with_their_size(tmp_path, monkeypatch):
    from voxrender.io import _shared

    write_series(tmp_path, np.zeros((4, 20, 20)))
    monkeypatch.setattr(_shared, "free_memory", lambda: 1000)
    with pytest.raises(InputError, match=r"its 4x20x20 int16 voxels take 3.2 kB, more than the 1 kB of memory"):
        io.read_volume(tmp_path)


def test_an_element_longer_than_its_file_is_bad_input_without_allocating_it(tmp_path):
    """pydicom read an element by its length: a damaged one (here 2 GB, in a file of a few kB) was allocated
    before the file was found short, and ran out of memory (exit 1; the fuzzing gate's big-endian enhanced file)."""
    import pydicom

    path = write_series(tmp_path, np.zeros((1, 4, 4)))[0]
    ds = pydicom.dcmread(path)
    ds.add_new(0x00091010, "UT", "a note")                          # a private element with a 4-byte length
    ds.save_as(path)
    whole = path.read_bytes()
    at = whole.index(b"UT\0\0" + (6).to_bytes(4, "little"))
    path.write_bytes(whole[:at + 4] + (0x7FFFFFF0).to_bytes(4, "little") + whole[at + 8:])
    with pytest.raises(InputError, match="img0000.dcm"):
        io.read_volume(tmp_path)
    # and within 1 GB of address space, where reading 2 GB would have run out of memory
    limited = ("import resource, sys; resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30)); "
               "from voxrender import io; from voxrender.errors import InputError\n"
               "try: io.read_volume(sys.argv[1])\nexcept InputError: print('bad input')")
    done = subprocess.run([sys.executable, "-c", limited, str(tmp_path)], capture_output=True, text=True)
    assert done.stdout.strip() == "bad input", done.stderr[-500:]


def _non_image(path, sop_class, modality):
    """A DICOM object that holds no slice (a structure set, a report), written by pydicom."""
    from pydicom.dataset import FileDataset, FileMetaDataset
    from pydicom.uid import ExplicitVRLittleEndian, generate_uid

    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID, meta.MediaStorageSOPInstanceUID = sop_class, generate_uid()
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds = FileDataset(str(path), {}, file_meta=meta, preamble=b"\0" * 128)
    ds.SOPClassUID, ds.SOPInstanceUID, ds.Modality = sop_class, meta.MediaStorageSOPInstanceUID, modality
    ds.SeriesInstanceUID = generate_uid()
    ds.save_as(str(path), enforce_file_format=True)
    return path


def test_a_study_folder_with_a_structure_set_and_a_report_reads_its_slices(tmp_path):
    """A CT folder as a planning system exports it: the RTSTRUCT (which has no Rows) ended in 'holds no image'."""
    values = np.arange(4 * 5 * 6, dtype=np.int16).reshape(4, 5, 6)
    write_series(tmp_path / "study", values)
    rtstruct = _non_image(tmp_path / "study" / "rs.dcm", "1.2.840.10008.5.1.4.1.1.481.3", "RTSTRUCT")
    _non_image(tmp_path / "study" / "sr.dcm", "1.2.840.10008.5.1.4.1.1.88.11", "SR")
    volume = io.read_volume(tmp_path / "study")
    assert volume.shape == (4, 5, 6) and volume.meta["segmentations"] == [str(rtstruct)]
    assert volume.meta["frame_of_reference"] is not None
    (tmp_path / "alone").mkdir()
    rtstruct.rename(tmp_path / "alone" / "rs.dcm")
    with pytest.raises(InputError, match="holds no image slices, only RTSTRUCT rs.dcm; a segmentation is shown on"):
        io.read_volume(tmp_path / "alone")


def _moved(path, z):
    """The slice file at ``path`` moved to ``z`` mm along the normal (rewritten by pydicom)."""
    ds = pydicom.dcmread(path)
    ds.ImagePositionPatient = [0.0, 0.0, float(z)]
    ds.save_as(path)


def test_a_stray_slice_far_from_the_rest_is_set_aside_with_one_warning_that_names_it(tmp_path):
    """pydicom's CT2: slices at z -99.5, 103.0, 104.3 and 105.5 mm; stacked at the median step, three of the four
    were drawn 200 mm from where they are."""
    values = np.arange(5 * 4 * 3, dtype=np.int16).reshape(5, 4, 3) * 10
    paths = write_series(tmp_path / "ct", values, names=[f"s{k}.dcm" for k in range(5)])
    _moved(paths[0], -300.0)                                 # the first slice, 200 mm below the others
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        volume = io.read_volume(tmp_path / "ct")
    said = [str(w.message) for w in caught]
    assert len(said) == 1 and "s0.dcm" in said[0] and "slices 2 to 5 of 5" in said[0], said
    assert np.array_equal(volume.values, values[1:] - 1024)
    assert volume.spacing[2] == pytest.approx(2.0) and volume.meta["origin"][2] == pytest.approx(-98.0)


def test_a_series_of_two_regular_runs_reads_the_longer_and_says_so(tmp_path):
    values = np.arange(6 * 4 * 3, dtype=np.int16).reshape(6, 4, 3)
    paths = write_series(tmp_path / "ct", values, names=[f"s{k}.dcm" for k in range(6)])
    for k, path in enumerate(paths[4:]):
        _moved(path, 50.0 + 2.0 * k)                         # two slices after a gap
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        volume = io.read_volume(tmp_path / "ct")
    assert len(caught) == 1 and "slices 1 to 4 of 6" in str(caught[0].message) and "s4.dcm, s5.dcm" in \
        str(caught[0].message)
    assert np.array_equal(volume.values, values[:4] - 1024)


def test_another_run_of_an_uneven_series_is_read_when_asked_for(tmp_path):
    """The run after the gap, by run=2 (--run 2), read and opened as a stream alike; a run it has not is refused
    naming the parameter; and the command line says the warning once, though info reads the series twice."""
    from test_cli import assert_bad_input, run

    values = np.arange(6 * 4 * 3, dtype=np.int16).reshape(6, 4, 3)
    paths = write_series(tmp_path / "ct", values, names=[f"s{k}.dcm" for k in range(6)])
    for k, path in enumerate(paths[4:]):
        _moved(path, 50.0 + 2.0 * k)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        volume = io.read_volume(tmp_path / "ct", run=2)
        stack = io.open_stack(tmp_path / "ct", run=2)
    assert np.array_equal(volume.values, values[4:] - 1024)
    assert np.array_equal(stack.read_slices(0, 2), values[4:] - 1024)
    assert "reading regular run 2, slices 5 to 6 of 6" in str(caught[0].message)
    with pytest.raises(InputError, match="run 3 is not one of the series' 2 regular runs") as info:
        io.read_volume(tmp_path / "ct", run=3)
    assert info.value.parameter == "run"
    with pytest.raises(InputError, match="npy input takes no run"):
        np.save(tmp_path / "v.npy", values)
        io.read_volume(tmp_path / "v.npy", run=1)
    result = run("info", tmp_path / "ct")
    assert result.exit_code == 0 and result.stderr.count("warning:") == 1, result.stderr
    assert "choose another run with --run" in result.stderr
    assert run("info", tmp_path / "ct", "--run", "2").stdout.count("[3, 4, 2]") == 1
    assert_bad_input(run("info", tmp_path / "ct", "--run", "3"), "--run", "is not one of the series' 2")
