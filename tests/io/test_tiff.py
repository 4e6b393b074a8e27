"""voxrender.io.tiff: multi-page TIFF."""

import imageio.v3 as iio
import numpy as np
import pytest
from formats import random_stack, refused_cuts

from voxrender import io
from voxrender.errors import InputError


def test_multipage_tiff(tmp_path):
    stack = random_stack()
    iio.imwrite(tmp_path / "v.tif", stack)
    volume = io.read_volume(tmp_path / "v.tif")
    assert np.array_equal(volume.values, stack) and volume.meta["format"] == "tiff"
    iio.imwrite(tmp_path / "page.tif", stack[0])
    with pytest.raises(InputError, match="single 2-D image"):
        io.read_volume(tmp_path / "page.tif")


def test_tiff_spacing_from_imagej_metadata(tmp_path):
    import tifffile

    stack = np.zeros((4, 5, 6), np.uint16)
    tifffile.imwrite(tmp_path / "stack.tif", stack, imagej=True, resolution=(1 / 0.25, 1 / 0.5),
                     metadata={"spacing": 2.0, "unit": "mm"})
    volume = io.read_volume(tmp_path / "stack.tif")
    assert volume.spacing == (0.25, 0.5, 2.0) and volume.meta["spacing_from"] == "ImageJ metadata"


def test_ome_tiff(tmp_path):
    import tifffile

    stack = np.zeros((3, 4, 5), np.uint16)
    tifffile.imwrite(tmp_path / "ome.ome.tif", stack, ome=True,
                     metadata={"axes": "ZYX", "PhysicalSizeX": 0.5, "PhysicalSizeY": 0.25, "PhysicalSizeZ": 2.0,
                               "PhysicalSizeXUnit": "mm", "PhysicalSizeYUnit": "mm", "PhysicalSizeZUnit": "mm"})
    volume = io.read_volume(tmp_path / "ome.ome.tif")
    assert volume.spacing == (0.5, 0.25, 2.0) and volume.meta["spacing_from"] == "OME metadata"


@pytest.mark.parametrize("compression", [None, "zlib"])
def test_cut_tiffs_are_bad_input(tmp_path, compression):
    import tifffile

    tifffile.imwrite(tmp_path / "v.tif", random_stack(), imagej=True, compression=compression)
    assert refused_cuts(tmp_path / "v.tif", lambda: io.read_volume(tmp_path / "v.tif")) >= 20


def test_pages_too_big_for_memory_are_refused_with_their_size(tmp_path, monkeypatch):
    import tifffile

    from voxrender.io import _shared

    tifffile.imwrite(tmp_path / "v.tif", np.zeros((3, 10, 10), np.uint16))
    monkeypatch.setattr(_shared, "free_memory", lambda: 100)
    with pytest.raises(InputError, match=r"its 3x10x10 uint16 voxels take 600 bytes, more than the 100 bytes"):
        io.read_volume(tmp_path / "v.tif")


def test_a_cut_tiff_is_one_error_without_tifffiles_log(tmp_path, capfd):
    """tifffile logged 'invalid page offset' before the error: two lines (found by the fuzzing gate)."""
    import tifffile

    tifffile.imwrite(tmp_path / "x.tif", random_stack((6, 20, 20)))
    whole = (tmp_path / "x.tif").read_bytes()
    (tmp_path / "x.tif").write_bytes(whole[:len(whole) * 2 // 5])
    with pytest.raises(InputError, match="x.tif"):
        io.read_volume(tmp_path / "x.tif")
    assert capfd.readouterr().err == ""


def test_a_first_page_without_its_width_is_bad_input(tmp_path):
    """tifffile divides by the first page's size when it reads a shaped series: a page that lost its ImageWidth
    tag (its code garbled) was a ZeroDivisionError, exit 1 (the fuzzing gate)."""
    import tifffile

    tifffile.imwrite(tmp_path / "v.tif", random_stack((5, 6, 7)))
    whole = bytearray((tmp_path / "v.tif").read_bytes())
    first_tag = 10                                  # the 8-byte header, the count of tags, then tag 256: ImageWidth
    assert whole[first_tag:first_tag + 2] == (256).to_bytes(2, "little")
    whole[first_tag] = 124
    (tmp_path / "v.tif").write_bytes(bytes(whole))
    with pytest.raises(InputError, match="v.tif: its page shapes, tags or series description are damaged"):
        io.read_volume(tmp_path / "v.tif")


def test_a_first_page_of_no_known_type_is_bad_input(tmp_path):
    """151 bits per sample: tifffile asserts a page type when it reads a shaped series (AssertionError, exit 1)."""
    import tifffile

    tifffile.imwrite(tmp_path / "v.tif", random_stack((5, 6, 7)))
    whole = bytearray((tmp_path / "v.tif").read_bytes())
    bits = 42                                       # the value of the third tag, 258: BitsPerSample
    assert whole[bits - 8:bits - 6] == (258).to_bytes(2, "little") and whole[bits] == 16
    whole[bits] = 151
    (tmp_path / "v.tif").write_bytes(bytes(whole))
    with pytest.raises(InputError, match="v.tif"):
        io.read_volume(tmp_path / "v.tif")


def test_a_stack_written_page_by_page_is_a_stack_and_a_cut_one_is_cut(tmp_path):
    """tifffile writes each page of a page-by-page stack as a series of its own: it read as 'a single 2-D image'.
    An ImageJ stack cut after its first page read as one too; it is cut short, and says so."""
    import tifffile

    values = (np.arange(10 * 20 * 20) % 1000).astype(np.uint16).reshape(10, 20, 20)
    with tifffile.TiffWriter(tmp_path / "pages.tif") as writer:
        for page in values:
            writer.write(page, contiguous=False)
    np.testing.assert_array_equal(io.read_volume(tmp_path / "pages.tif", reorient=False).values, values)
    tifffile.imwrite(tmp_path / "imagej.tif", values, imagej=True)
    whole = (tmp_path / "imagej.tif").read_bytes()
    (tmp_path / "cut.tif").write_bytes(whole[:len(whole) // 2])
    with pytest.raises(InputError, match="cut.tif is cut short or damaged: its list of pages breaks off after 1 page"):
        io.read_volume(tmp_path / "cut.tif")
