"""Slab readers (issue 24): raw slices, image folders, multi-page TIFFs and DICOM series opened as a stack and read a
slab at a time give read_volume's values, type, spacing, direction and meta; a slice of another size or a file cut
short met on the way is bad input, naming the file."""

import imageio.v3 as iio
import numpy as np
import pydicom
import pytest
import tifffile
from dicom_files import write_enhanced, write_series
from formats import phantom, random_stack, stored, write_dicom

from voxrender import io
from voxrender.errors import InputError
from voxrender.io import _shared


def assert_slabs_are_the_volume(path, **options):
    """Slabs of 1, 2 and 3 canonical slices, put together, are read_volume's values, with its type, spacing,
    direction and meta; the stored stack too (not reoriented)."""
    for reorient in (True, False):
        volume = io.read_volume(path, reorient=reorient, **options)
        stack = io.open_stack(path, reorient=reorient, **options)
        assert stack.shape == volume.shape and stack.dtype == volume.values.dtype
        assert stack.spacing == volume.spacing and stack.meta == volume.meta
        assert (stack.direction is None) == (volume.direction is None)
        assert volume.direction is None or np.array_equal(stack.direction, volume.direction)
        count = volume.shape[0]
        for size in (1, 2, 3):
            slabs = [stack.read_slices(z, min(z + size, count)) for z in range(0, count, size)]
            assert all(slab.dtype == volume.values.dtype for slab in slabs)
            np.testing.assert_array_equal(np.concatenate(slabs), volume.values)
    return stack


def read_all(stack):
    return stack.read_slices(0, stack.shape[0])


def assert_refused_naming(path, name, *sizes, **options):
    """Opening ``path`` or reading its slices is bad input whose message names ``name`` (and ``sizes``)."""
    with pytest.raises(InputError, match=name) as info:
        read_all(io.open_stack(path, **options))
    assert all(size in str(info.value) for size in sizes), info.value


# ---------------------------------------------------------------- raw


def test_raw_slabs_across_files_holding_several_slices(tmp_path):
    values = random_stack((7, 5, 6))
    folder = tmp_path / "slices"
    folder.mkdir()
    for name, part in (("q.1", values[:3]), ("q.2", values[3:4]), ("q.10", values[4:])):
        part.astype(">u2").tofile(folder / name)
    (folder / "notes.txt").write_text("not slices")
    assert_slabs_are_the_volume(folder, raw=io.RawLayout(6, 5, np.dtype(">u2")))
    values.astype("<u2").tofile(tmp_path / "all.raw")
    stack = assert_slabs_are_the_volume(tmp_path / "all.raw", raw=io.RawLayout(6, 5, np.dtype("<u2")))
    assert stack.stored_bytes == values.nbytes


def test_half_floats_become_floats_as_read_volume_makes_them(tmp_path):
    values = np.random.default_rng(4).random((4, 5, 6)).astype(np.float16)
    values.tofile(tmp_path / "half.raw")
    stack = assert_slabs_are_the_volume(tmp_path / "half.raw", raw=io.RawLayout(6, 5, np.dtype("<f2")))
    assert stack.dtype == np.float32 and stack.stored_bytes == values.nbytes
    tifffile.imwrite(tmp_path / "half.tif", values, photometric="minisblack")
    assert assert_slabs_are_the_volume(tmp_path / "half.tif").dtype == np.float32


def test_a_raw_file_cut_short_after_it_was_opened_is_named(tmp_path):
    folder = tmp_path / "slices"
    folder.mkdir()
    for z, plane in enumerate(random_stack((4, 5, 6))):
        plane.astype("<u2").tofile(folder / f"s{z}.raw")
    stack = io.open_stack(folder, raw=io.RawLayout(6, 5, np.dtype("<u2")))
    (folder / "s2.raw").write_bytes((folder / "s2.raw").read_bytes()[:-7])
    assert stack.read_slices(0, 2).shape == (2, 5, 6)
    with pytest.raises(InputError, match="s2.raw ends within its slice 0.*truncated"):
        stack.read_slices(1, 4)


# ---------------------------------------------------------------- images


@pytest.mark.parametrize("suffix, dtype", [(".png", np.uint16), (".tif", np.uint16), (".bmp", np.uint8),
                                           (".png", np.uint8)])
def test_image_slabs(tmp_path, suffix, dtype):
    planes = random_stack((5, 8, 9)).astype(dtype)
    for z, plane in enumerate(planes):
        iio.imwrite(tmp_path / f"s.{z + 1}{suffix}", plane)
    assert_slabs_are_the_volume(tmp_path)


def test_colour_image_slabs(tmp_path):
    colour = np.random.default_rng(2).integers(0, 255, size=(4, 5, 6, 3)).astype(np.uint8)
    for z, plane in enumerate(colour):
        iio.imwrite(tmp_path / f"{z}.png", plane)
    assert assert_slabs_are_the_volume(tmp_path).dtype == np.float32


def test_only_the_first_image_is_read_when_opened(tmp_path, monkeypatch):
    for z, plane in enumerate(random_stack((4, 5, 6)).astype(np.uint8)):
        iio.imwrite(tmp_path / f"{z}.png", plane)
    read = []
    imread = iio.imread
    monkeypatch.setattr(iio, "imread", lambda f, **kwargs: read.append(f.name) or imread(f, **kwargs))
    stack = io.open_stack(tmp_path)
    assert read == ["0.png"] and stack.shape == (4, 5, 6)
    stack.read_slices(2, 4)
    assert read == ["0.png", "2.png", "3.png"]


def test_an_image_of_another_size_part_way_is_named_with_both_sizes(tmp_path):
    for z in range(3):
        iio.imwrite(tmp_path / f"{z}.png", np.zeros((4, 5 if z < 2 else 7), np.uint8))
    stack = io.open_stack(tmp_path)
    assert stack.read_slices(0, 2).shape == (2, 4, 5)
    assert_refused_naming(tmp_path, "slice 2.png", "7x4", "0.png is 5x4")


def test_an_image_of_a_wider_type_part_way_is_named_with_both_types(tmp_path):
    iio.imwrite(tmp_path / "0.png", np.zeros((4, 5), np.uint8))
    iio.imwrite(tmp_path / "1.png", np.full((4, 5), 1000, np.uint16))
    assert io.read_volume(tmp_path).values.dtype == np.uint16         # read whole, the volume widens
    assert_refused_naming(tmp_path, "slice 1.png holds uint16 values but 0.png holds uint8")


def test_an_image_cut_short_is_named(tmp_path):
    for z, plane in enumerate(random_stack((3, 30, 40)).astype(np.uint8)):
        iio.imwrite(tmp_path / f"{z}.png", plane)
    stack = io.open_stack(tmp_path)
    (tmp_path / "1.png").write_bytes((tmp_path / "1.png").read_bytes()[:200])
    with pytest.raises(InputError, match="cannot read image .*1.png"):
        stack.read_slices(0, 3)


# ---------------------------------------------------------------- multi-page TIFF


def write_pages(path, values, **options):
    with tifffile.TiffWriter(path) as writer:
        for page in values:
            writer.write(page, contiguous=False, **options)
    return path


@pytest.mark.parametrize("write", [
    lambda path, v: tifffile.imwrite(path, v, photometric="minisblack"),              # one block of pages
    lambda path, v: tifffile.imwrite(path, v, photometric="minisblack", byteorder=">"),
    lambda path, v: tifffile.imwrite(path, v, photometric="minisblack", compression="zlib"),
    lambda path, v: tifffile.imwrite(path, v, imagej=True, resolution=(2.0, 4.0), metadata={"spacing": 3.0}),
    lambda path, v: write_pages(path, v),                                              # a series a page
    lambda path, v: write_pages(path, v, compression="zlib"),
    lambda path, v: iio.imwrite(path, v),
], ids=["block", "big-endian", "zlib", "imagej", "pages", "zlib-pages", "imageio"])
def test_tiff_slabs(tmp_path, write):
    write(tmp_path / "v.tif", random_stack((7, 5, 6)))
    assert_slabs_are_the_volume(tmp_path / "v.tif")


def test_colour_and_boolean_tiff_slabs(tmp_path):
    colour = np.random.default_rng(5).integers(0, 255, size=(4, 5, 6, 3)).astype(np.uint8)
    tifffile.imwrite(tmp_path / "colour.tif", colour, photometric="rgb")
    assert assert_slabs_are_the_volume(tmp_path / "colour.tif").dtype == np.float32
    tifffile.imwrite(tmp_path / "grey.tif", np.repeat(colour[..., :1], 3, axis=-1), photometric="rgb")
    assert assert_slabs_are_the_volume(tmp_path / "grey.tif").dtype == np.uint8
    tifffile.imwrite(tmp_path / "mask.tif", random_stack((3, 4, 5)) > 1500)
    assert assert_slabs_are_the_volume(tmp_path / "mask.tif").dtype == np.uint8


@pytest.mark.parametrize("compression", [None, "zlib"])
def test_a_tiff_cut_short_is_named(tmp_path, compression):
    path = write_pages(tmp_path / "v.tif", random_stack((6, 20, 20)), compression=compression)
    stack = io.open_stack(path)
    whole = path.read_bytes()
    path.write_bytes(whole[:len(whole) * 3 // 4])
    with pytest.raises(InputError, match="v.tif"):
        read_all(stack)
    assert_refused_naming(path, "v.tif")                                  # cut before it is opened


@pytest.mark.parametrize("format", ["raw", "images", "tiff", "tiff-zlib"])
def test_a_stack_larger_than_the_free_memory_opens(tmp_path, monkeypatch, format):
    values = random_stack((6, 20, 30))
    options = {}
    if format == "raw":
        path, options = tmp_path / "v.raw", {"raw": io.RawLayout(30, 20, np.dtype("<u2"))}
        values.tofile(path)
    elif format == "images":
        path = tmp_path
        for z, plane in enumerate(values):
            iio.imwrite(tmp_path / f"{z}.png", plane)
    else:
        path = tmp_path / "v.tif"
        tifffile.imwrite(path, values, photometric="minisblack", compression="zlib" if "zlib" in format else None)
    monkeypatch.setattr(_shared, "free_memory", lambda: 2000)                     # a slice, not the stack
    with pytest.raises(InputError, match="more than the 2 kB of memory free"):
        io.read_volume(path, **options)
    stack = io.open_stack(path, **options)
    np.testing.assert_array_equal(np.concatenate([stack.read_slices(z, z + 1) for z in range(6)]), values)


# ---------------------------------------------------------------- DICOM


@pytest.mark.parametrize("code, how", [("LPS", "stored order"), ("RPI", "from the far end"),
                                       ("PIR", "across the stored slices"), ("LIP", "across the stored slices"),
                                       ("RAS", "stored order")])
def test_dicom_slabs_in_any_orientation(tmp_path, code, how):
    write_dicom(tmp_path, *stored(phantom(), code))
    stack = assert_slabs_are_the_volume(tmp_path)
    stack = io.open_stack(tmp_path)
    assert stack.how == how and stack.meta["orientation"] == code
    np.testing.assert_array_equal(read_all(stack), phantom())


@pytest.mark.parametrize("intercept, slope, dtype", [(-1024, 1, np.int16), (0, 1, np.int16), (1.25, 0.5, np.float32),
                                                     (-40000, 1, np.int32)])
def test_dicom_slab_types_are_read_volumes(tmp_path, intercept, slope, dtype):
    values = np.random.default_rng(3).integers(-500, 2000, size=(5, 4, 6))
    write_series(tmp_path, values, slope=slope, intercept=intercept)
    assert assert_slabs_are_the_volume(tmp_path).dtype == dtype


def test_dicom_slices_whose_types_differ_give_the_widest(tmp_path):
    """read_volume widens the volume to a later slice's type: the stack's type, from the slices' range, is that one."""
    values = np.zeros((4, 3, 3), np.int16)
    values[:, 1, 1] = 30000                                             # -1024 + 30000 fits int16
    paths = write_series(tmp_path, values, intercept=-1024)
    rewrite(paths[2], RescaleIntercept=10000)                           # 40000 does not
    assert io.read_volume(tmp_path).values.dtype == np.int32
    assert assert_slabs_are_the_volume(tmp_path).dtype == np.int32


def rewrite(path, **elements):
    """Change some elements of a DICOM file (pydicom)."""
    ds = pydicom.dcmread(path)
    for keyword, value in elements.items():
        setattr(ds, keyword, value)
    ds.save_as(path)


def test_dicom_headers_that_tell_the_type_spare_a_pass_over_the_pixels(tmp_path, monkeypatch):
    write_series(tmp_path, random_stack((4, 3, 5)).astype(np.int16), intercept=0)          # int16 whatever it holds
    write_series(tmp_path / "ct", random_stack((4, 3, 5)).astype(np.int16), intercept=-1024)
    read = []
    from voxrender.io import _dicom_header, _dicom_values

    for module, name in ((_dicom_values, "dicom_pixels"), (_dicom_header, "read_plain")):   # decoded, or read straight
        function = getattr(module, name)
        monkeypatch.setattr(module, name, lambda path, *args, function=function: read.append(path) or
                            function(path, *args))
    assert io.open_stack(tmp_path).dtype == np.int16 and read == []
    assert io.open_stack(tmp_path / "ct").dtype == np.int16 and len(read) == 4     # a signed 16-bit CT: its range


def test_a_dicom_stack_larger_than_the_free_memory_opens(tmp_path, monkeypatch):
    write_dicom(tmp_path, *stored(phantom(), "LPS"))
    monkeypatch.setattr(_shared, "free_memory", lambda: 4000)                     # a slice, not the volume
    with pytest.raises(InputError, match="more than the 4 kB of memory free"):
        io.read_volume(tmp_path)
    stack = io.open_stack(tmp_path)
    assert stack.nbytes > 4000
    np.testing.assert_array_equal(np.concatenate([stack.read_slices(z, z + 1) for z in range(18)]), phantom())


def test_a_dicom_slice_of_another_size_is_named_when_opened(tmp_path):
    paths = write_series(tmp_path, np.zeros((3, 4, 5)), names=["a.dcm", "b.dcm", "c.dcm"])
    rewrite(paths[2], Columns=7, PixelData=np.zeros((4, 7), np.int16).tobytes())
    assert_refused_naming(tmp_path, "slice c.dcm is 7x4 but a.dcm is 5x4")


def test_a_dicom_file_cut_short_after_it_was_opened_is_named(tmp_path):
    paths = write_dicom(tmp_path, *stored(phantom(), "LPS"))
    stack = io.open_stack(tmp_path)
    paths[5].write_bytes(paths[5].read_bytes()[:-60])
    with pytest.raises(InputError, match=f"DICOM file {paths[5]}"):
        read_all(stack)
    assert_refused_naming(tmp_path, paths[5].name)


@pytest.mark.parametrize("code, slope, intercept", [("LPS", 1, -1024), ("RPI", 0.5, 1.25), ("PIR", 1, 0)])
def test_enhanced_dicom_slabs(tmp_path, code, slope, intercept):
    values, spacing, direction = stored(phantom(), code)
    write_enhanced(tmp_path / "enhanced.dcm", values, spacing, slope=slope, intercept=intercept, direction=direction)
    assert_slabs_are_the_volume(tmp_path)


def test_an_enhanced_dicom_cut_short_after_it_was_opened_is_named(tmp_path):
    path = write_enhanced(tmp_path / "enhanced.dcm", phantom(), intercept=0)
    stack = io.open_stack(tmp_path)
    path.write_bytes(path.read_bytes()[:-500])
    with pytest.raises(InputError, match="DICOM file .*enhanced.dcm"):
        read_all(stack)
