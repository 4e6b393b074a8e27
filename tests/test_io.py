import zlib
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from conftest import data_path
from dicom_files import write_series
from voxrender import io
from voxrender.errors import InputError


@pytest.fixture
def stack():
    rng = np.random.default_rng(0)
    return rng.integers(0, 3000, size=(5, 6, 7)).astype(np.uint16)


# ------------------------------------------------------------------ image folders

def test_image_folder_in_natural_order(tmp_path, stack):
    for z, plane in enumerate(stack):
        iio.imwrite(tmp_path / f"s.{z + 1}.png", plane)  # s.10 would sort before s.2 as text
    (tmp_path / "README.txt").write_text("not a slice")
    volume = io.read_volume(tmp_path)
    assert volume.meta["format"] == "images"
    assert np.array_equal(volume.values, stack)


def test_natural_key_orders_numbers():
    names = [f"quarter.{i}" for i in (10, 2, 1, 93, 11)]
    assert sorted(names, key=io.natural_key) == ["quarter.1", "quarter.2", "quarter.10", "quarter.11", "quarter.93"]


@pytest.mark.parametrize("suffix", [".tif", ".bmp"])
def test_other_image_types(tmp_path, suffix):
    planes = np.random.default_rng(1).integers(0, 255, size=(3, 8, 9)).astype(np.uint8)
    for z, plane in enumerate(planes):
        iio.imwrite(tmp_path / f"{z}{suffix}", plane)
    assert np.array_equal(io.read_volume(tmp_path).values, planes)


def test_colour_slices_become_grey(tmp_path):
    grey = np.random.default_rng(2).integers(0, 255, size=(2, 4, 5)).astype(np.uint8)
    for z, plane in enumerate(grey):
        iio.imwrite(tmp_path / f"{z}.png", np.stack([plane] * 3, axis=-1))
    assert np.array_equal(io.read_volume(tmp_path).values, grey)


def test_slices_of_different_sizes(tmp_path):
    iio.imwrite(tmp_path / "1.png", np.zeros((4, 4), np.uint8))
    iio.imwrite(tmp_path / "2.png", np.zeros((4, 5), np.uint8))
    with pytest.raises(InputError, match="same size"):
        io.read_volume(tmp_path)


def test_corrupt_image(tmp_path):
    iio.imwrite(tmp_path / "1.png", np.zeros((4, 4), np.uint8))
    (tmp_path / "2.png").write_bytes(b"\x89PNG garbage")
    with pytest.raises(InputError, match="cannot read image"):
        io.read_volume(tmp_path)


# ------------------------------------------------------------------ DICOM

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


# ------------------------------------------------------------------ MetaImage, raw, npy, tiff

def _write_mhd(path, values, compressed=False, local=False, msb=False):
    dtype = values.dtype.newbyteorder(">" if msb else "<")
    payload = values.astype(dtype).tobytes()
    if compressed:
        payload = zlib.compress(payload)
    nz, ny, nx = values.shape
    header = (f"ObjectType = Image\nNDims = 3\nDimSize = {nx} {ny} {nz}\nElementSpacing = 0.5 0.7 2\n"
              f"ElementType = MET_SHORT\nElementByteOrderMSB = {msb}\nCompressedData = {compressed}\n")
    if compressed:
        header += f"CompressedDataSize = {len(payload)}\n"
    if local:
        path.write_bytes((header + "ElementDataFile = LOCAL\n").encode() + payload)
    else:
        path.with_suffix(".raw").write_bytes(payload)
        path.write_text(header + f"ElementDataFile = {path.with_suffix('.raw').name}\n")


@pytest.mark.parametrize("compressed,local,msb", [(False, False, False), (True, False, False),
                                                  (False, True, True), (True, True, False)])
def test_metaimage(tmp_path, compressed, local, msb):
    values = np.random.default_rng(5).integers(-1000, 1000, size=(3, 4, 5)).astype(np.int16)
    path = tmp_path / ("v.mha" if local else "v.mhd")
    _write_mhd(path, values, compressed, local, msb)
    volume = io.read_volume(path)
    assert np.array_equal(volume.values, values) and volume.spacing == (0.5, 0.7, 2.0)


def test_truncated_metaimage(tmp_path):
    values = np.zeros((3, 4, 5), np.int16)
    _write_mhd(tmp_path / "v.mhd", values)
    (tmp_path / "v.raw").write_bytes(b"\0" * 10)
    with pytest.raises(InputError, match="truncated"):
        io.read_volume(tmp_path / "v.mhd")


def test_headmr_metaimage():
    volume = io.read_volume(data_path("headmr") / "HeadMRVolume.mhd")
    assert volume.shape == (42, 62, 48) and volume.spacing == (4.0, 4.0, 4.0)
    assert volume.values.dtype == np.uint8


def test_raw_folder_and_single_file(tmp_path, stack):
    folder = tmp_path / "slices"
    folder.mkdir()
    for z, plane in enumerate(stack):
        plane.astype(">u2").tofile(folder / f"q.{z + 1}")
    (folder / "q.nhdr").write_text("NRRD0004\n")  # headers beside raw slices are not slices
    volume = io.read_volume(folder, raw=io.RawLayout(7, 6, np.dtype(">u2")))
    assert np.array_equal(volume.values, stack)
    stack.astype("<u2").tofile(tmp_path / "all.raw")
    assert np.array_equal(io.read_volume(tmp_path / "all.raw", raw=io.RawLayout(7, 6, np.dtype("<u2"))).values, stack)


def test_raw_size_mismatch(tmp_path, stack):
    stack.astype("<u2").tofile(tmp_path / "all.raw")
    with pytest.raises(InputError, match="not a multiple"):
        io.read_volume(tmp_path / "all.raw", raw=io.RawLayout(8, 6, np.dtype("<u2")))


@pytest.mark.parametrize("width, height, dtype", [(0, 4, "u1"), (4, 4, "complex64"), (4, -1, "u2")])
def test_raw_layout_errors(width, height, dtype):
    with pytest.raises(InputError) as info:
        io.RawLayout(width, height, np.dtype(dtype))
    assert info.value.parameter == "raw"


def test_a_format_refuses_options_it_does_not_take(tmp_path, stack):
    np.save(tmp_path / "v.npy", stack)
    with pytest.raises(InputError, match="npy input takes no series") as info:
        io.read_volume(tmp_path / "v.npy", series="1.2.3")
    assert info.value.parameter == "series"


def test_headsq_raw():
    volume = io.read_volume(data_path("headsq"), raw=io.RawLayout(64, 64, np.dtype("<u2")), spacing=(3.2, 3.2, 1.5))
    assert volume.shape == (93, 64, 64) and volume.spacing == (3.2, 3.2, 1.5)
    assert 3000 < volume.values.max() < 5000


def test_npy_and_multipage_tiff(tmp_path, stack):
    np.save(tmp_path / "v.npy", stack)
    assert np.array_equal(io.read_volume(tmp_path / "v.npy").values, stack)
    iio.imwrite(tmp_path / "v.tif", stack)
    assert np.array_equal(io.read_volume(tmp_path / "v.tif").values, stack)
    np.save(tmp_path / "flat.npy", stack[0])
    with pytest.raises(InputError, match="3-D"):
        io.read_volume(tmp_path / "flat.npy")


def test_spacing_override(tmp_path, stack):
    np.save(tmp_path / "v.npy", stack)
    assert io.read_volume(tmp_path / "v.npy", spacing=(1, 2, 3)).spacing == (1.0, 2.0, 3.0)
    with pytest.raises(InputError):
        io.read_volume(tmp_path / "v.npy", spacing=(1, 0, 3))


# ------------------------------------------------------------------ paths

def test_missing_and_empty_and_unknown(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        io.read_volume(tmp_path / "nope")
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError, match="empty folder"):
        io.read_volume(empty)
    notes = tmp_path / "notes"
    notes.mkdir()
    (notes / "a.txt").write_text("hello")
    with pytest.raises(InputError, match="headerless slices give their layout") as info:
        io.read_volume(notes)
    assert info.value.parameter == "raw"
    (tmp_path / "thing.xyz").write_text("?")
    with pytest.raises(InputError, match="cannot tell the format"):
        io.read_volume(tmp_path / "thing.xyz")


# ------------------------------------------------------------------ the recipe "add a reader" (docs/design.md)

def read_toy(path, progress):
    """A toy format written by the recipe: JSON with ``values`` [z][y][x] and ``spacing`` (x, y, z)."""
    import json

    data = json.loads(Path(path).read_text())
    values = np.asarray(data["values"], np.int16)
    return io.Volume(values, tuple(data["spacing"]), {"spacing_from": "toy header"})


def test_a_toy_reader_added_by_the_recipe(tmp_path, monkeypatch):
    import json

    from voxrender.pipeline import PrepOptions, load_segments

    monkeypatch.setitem(io.READERS, "toy", io.Reader(read_toy, suffixes=(".toy",)))
    values = np.zeros((3, 4, 5), int)
    values[1, 1:3, 1:4] = 100
    (tmp_path / "box.toy").write_text(json.dumps({"values": values.tolist(), "spacing": [1, 1, 2]}))
    volume = io.read_volume(tmp_path / "box.toy")
    assert volume.meta["format"] == "toy" and volume.spacing == (1, 1, 2)
    assert np.array_equal(volume.values, values)
    encoded = load_segments(tmp_path / "box.toy", prepare=PrepOptions(threshold=50, resample=False))
    assert encoded.segments.voxel_count == 6
    with pytest.raises(InputError, match="toy input takes no series"):
        io.read_volume(tmp_path / "box.toy", series="1.2")


# ------------------------------------------------------------------ NIfTI, NRRD, enhanced DICOM, TIFF spacing

def test_enhanced_ct_gives_the_same_volume_as_its_classic_series(tmp_path):
    from dicom_files import write_enhanced

    stored = np.random.default_rng(5).integers(0, 2000, (6, 7, 8)).astype(np.int16)
    write_series(tmp_path / "classic", stored, intercept=-1024)
    write_enhanced(tmp_path / "enhanced" / "ct.dcm", stored, intercept=-1024) if (tmp_path / "enhanced").mkdir() \
        is None else None
    classic, enhanced = io.read_volume(tmp_path / "classic"), io.read_volume(tmp_path / "enhanced")
    assert np.array_equal(classic.values, enhanced.values) and classic.spacing == enhanced.spacing
    assert enhanced.meta["units"] == "HU" and enhanced.meta["sorted_by"] == "per-frame ImagePositionPatient"


def test_a_folder_with_a_classic_and_an_enhanced_series_lists_both(tmp_path):
    from dicom_files import write_enhanced

    stored = np.zeros((3, 4, 4), np.int16)
    write_series(tmp_path, stored, series_uid="1.2.3.7")
    write_enhanced(tmp_path / "enhanced.dcm", stored, series_uid="1.2.3.8")
    with pytest.raises(InputError, match="2 DICOM series") as info:
        io.read_volume(tmp_path)
    assert "1.2.3.7" in str(info.value) and "1.2.3.8" in str(info.value)
    assert io.read_volume(tmp_path, series="1.2.3.8").shape == (3, 4, 4)


def test_an_enhanced_dicom_without_positions_is_refused(tmp_path):
    from dicom_files import write_enhanced

    write_enhanced(tmp_path / "ct.dcm", np.zeros((3, 4, 4), np.int16), positions=False)
    with pytest.raises(InputError, match="frames lack ImagePositionPatient"):
        io.read_volume(tmp_path)


def test_nifti_scaling_and_4d_frames(tmp_path):
    import nibabel

    data = np.arange(4 * 5 * 6 * 2, dtype=np.int16).reshape(6, 5, 4, 2)      # [i, j, k, t]
    image = nibabel.Nifti1Image(data, np.diag([2.0, 3.0, 4.0, 1.0]))
    image.header.set_slope_inter(0.5, 10)
    nibabel.save(image, str(tmp_path / "four.nii.gz"))
    with pytest.raises(InputError, match="holds 2 volumes") as info:
        io.read_volume(tmp_path / "four.nii.gz")
    assert info.value.parameter == "frame"
    with pytest.raises(InputError, match="is not a volume") as info:
        io.read_volume(tmp_path / "four.nii.gz", frame=2)
    volume = io.read_volume(tmp_path / "four.nii.gz", frame=1, reorient=False)
    assert volume.shape == (4, 5, 6) and volume.spacing == (2.0, 3.0, 4.0)
    assert np.allclose(volume.values, data[..., 1].transpose(2, 1, 0) * 0.5 + 10)
    assert io.read_volume(tmp_path / "four.nii.gz", frame=1).meta["reoriented"] == "RAS -> LPS: flipped x, y"


def test_nifti_with_a_bad_pixdim_or_truncated(tmp_path):
    import nibabel

    nibabel.save(nibabel.Nifti1Image(np.zeros((4, 4, 4), np.int16), np.eye(4)), str(tmp_path / "flat.nii"))
    with open(tmp_path / "flat.nii", "r+b") as f:           # nibabel mends a zero pixdim when it saves an image,
        header = nibabel.Nifti1Header.from_fileobj(f)      # so the header is written back on its own
        header["pixdim"][2] = 0
        f.seek(0)
        header.write_to(f)
    with pytest.raises(InputError, match="pixdim"):
        io.read_volume(tmp_path / "flat.nii")
    nibabel.save(nibabel.Nifti1Image(np.random.default_rng(0).random((20, 20, 20)), np.eye(4)),
                 str(tmp_path / "whole.nii.gz"))
    (tmp_path / "cut.nii.gz").write_bytes((tmp_path / "whole.nii.gz").read_bytes()[:4000])
    with pytest.raises(InputError, match="cut.nii.gz"):
        io.read_volume(tmp_path / "cut.nii.gz")


def test_nifti_without_sform_or_qform_warns(tmp_path):
    import nibabel

    image = nibabel.Nifti1Image(np.zeros((3, 4, 5), np.int16), None)
    image.header.set_sform(None, code=0)
    image.header.set_qform(None, code=0)
    nibabel.save(image, str(tmp_path / "bare.nii"))
    with pytest.warns(UserWarning, match="neither sform nor qform"):
        volume = io.read_volume(tmp_path / "bare.nii")
    assert volume.shape == (5, 4, 3) and volume.meta["orientation_from"].startswith("unknown")


def test_nrrd_encodings_and_bad_files(tmp_path):
    import nrrd

    data = np.random.default_rng(1).integers(0, 100, (3, 4, 5)).astype(np.uint16)
    for encoding in ("raw", "gzip", "bzip2"):
        nrrd.write(str(tmp_path / f"{encoding}.nrrd"), data, {"encoding": encoding, "endian": "big"}, index_order="C")
        assert np.array_equal(io.read_volume(tmp_path / f"{encoding}.nrrd").values, data)
    nrrd.write(str(tmp_path / "detached.nhdr"), data, {"encoding": "gzip"}, index_order="C", detached_header=True)
    assert np.array_equal(io.read_volume(tmp_path / "detached.nhdr").values, data)
    next(tmp_path.glob("detached.raw*")).unlink()
    with pytest.raises(InputError, match="missing|cannot read"):
        io.read_volume(tmp_path / "detached.nhdr")
    text = (tmp_path / "raw.nrrd").read_bytes().replace(b"encoding: raw", b"encoding: magic")
    (tmp_path / "magic.nrrd").write_bytes(text)
    with pytest.raises(InputError, match="cannot read"):
        io.read_volume(tmp_path / "magic.nrrd")


@pytest.mark.parametrize("space,outcome", [("posterior-left-superior", "PLS -> LPS: axes yxz -> xyz"),
                                           ("left-right-superior", "names a patient axis twice")])
def test_nrrd_space_names_the_axes(tmp_path, space, outcome):
    data = np.arange(60, dtype=np.uint8).reshape(3, 4, 5)
    header = (f"NRRD0004\ntype: uint8\ndimension: 3\nspace: {space}\nsizes: 5 4 3\n"
              "space directions: (1,0,0) (0,1,0) (0,0,2)\nencoding: raw\n\n")
    (tmp_path / "v.nrrd").write_bytes(header.encode() + data.tobytes())
    if "twice" in outcome:
        with pytest.raises(InputError, match=outcome):
            io.read_volume(tmp_path / "v.nrrd")
        return
    volume = io.read_volume(tmp_path / "v.nrrd")
    assert volume.meta["reoriented"] == outcome
    assert np.array_equal(volume.values, data.transpose(0, 2, 1)) and volume.spacing == (1.0, 1.0, 2.0)


def test_tiff_spacing_from_imagej_metadata(tmp_path):
    import tifffile

    stack = np.zeros((4, 5, 6), np.uint16)
    tifffile.imwrite(tmp_path / "stack.tif", stack, imagej=True, resolution=(1 / 0.25, 1 / 0.5),
                     metadata={"spacing": 2.0, "unit": "mm"})
    volume = io.read_volume(tmp_path / "stack.tif")
    assert volume.spacing == (0.25, 0.5, 2.0) and volume.meta["spacing_from"] == "ImageJ metadata"


def test_nifti_2_and_ome_tiff(tmp_path):
    import nibabel
    import tifffile

    data = np.random.default_rng(2).integers(0, 9, (5, 4, 3)).astype(np.int16)       # [i, j, k]
    nibabel.save(nibabel.Nifti2Image(data, np.diag([-1.0, -1.0, 2.0, 1.0])), str(tmp_path / "two.nii"))
    volume = io.read_volume(tmp_path / "two.nii")                  # stored LPS (negative x, y in RAS): as stored
    assert np.array_equal(volume.values, data.transpose(2, 1, 0)) and volume.spacing == (1.0, 1.0, 2.0)
    stack = np.zeros((3, 4, 5), np.uint16)
    tifffile.imwrite(tmp_path / "ome.ome.tif", stack, ome=True,
                     metadata={"axes": "ZYX", "PhysicalSizeX": 0.5, "PhysicalSizeY": 0.25, "PhysicalSizeZ": 2.0,
                               "PhysicalSizeXUnit": "mm", "PhysicalSizeYUnit": "mm", "PhysicalSizeZUnit": "mm"})
    volume = io.read_volume(tmp_path / "ome.ome.tif")
    assert volume.spacing == (0.5, 0.25, 2.0) and volume.meta["spacing_from"] == "OME metadata"


def test_nrrd_4d_takes_a_frame(tmp_path):
    import nrrd

    data = np.arange(2 * 3 * 4 * 5, dtype=np.int16).reshape(2, 3, 4, 5)       # [t, z, y, x]
    nrrd.write(str(tmp_path / "four.nrrd"), data, {"space": "left-posterior-superior", "kinds":
               ["domain", "domain", "domain", "list"], "space directions": [[1, 0, 0], [0, 1, 0], [0, 0, 2],
                                                                             [np.nan] * 3]}, index_order="C")
    with pytest.raises(InputError, match="holds 2 volumes") as info:
        io.read_volume(tmp_path / "four.nrrd")
    assert info.value.parameter == "frame"
    volume = io.read_volume(tmp_path / "four.nrrd", frame=1)
    assert np.array_equal(volume.values, data[1]) and volume.spacing == (1.0, 1.0, 2.0)
    with pytest.raises(InputError, match="is not a volume") as info:
        io.read_volume(tmp_path / "four.nrrd", frame=5)
    assert info.value.parameter == "frame"


@pytest.mark.parametrize("name", ["three.nii.gz", "three.nrrd"])
def test_a_frame_of_a_3d_file_is_refused(tmp_path, name):
    import nibabel
    import nrrd

    data = np.zeros((3, 4, 5), np.int16)
    if name.endswith(".nrrd"):
        nrrd.write(str(tmp_path / name), data)
    else:
        nibabel.save(nibabel.Nifti1Image(data, np.eye(4)), str(tmp_path / name))
    with pytest.raises(InputError, match="holds one volume; a frame number applies to 4-D files") as info:
        io.read_volume(tmp_path / name, frame=0)
    assert info.value.parameter == "frame"
