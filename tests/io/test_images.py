"""voxrender.io.images: a folder of 2-D images."""

import imageio.v3 as iio
import numpy as np
import pytest
from formats import random_stack, refused_cuts

from voxrender import io
from voxrender.errors import InputError


def test_image_folder_in_natural_order(tmp_path):
    stack = random_stack()
    for z, plane in enumerate(stack):
        iio.imwrite(tmp_path / f"s.{z + 1}.png", plane)  # s.10 would sort before s.2 as text
    (tmp_path / "README.txt").write_text("not a slice")
    volume = io.read_volume(tmp_path)
    assert volume.meta["format"] == "images"
    assert np.array_equal(volume.values, stack)


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


@pytest.mark.parametrize("suffix", [".png", ".tif", ".bmp", ".jpg"])
def test_cut_images_are_bad_input(tmp_path, suffix):
    """Pillow's and tifffile's errors for a cut-off slice (SyntaxError, struct.error, zlib.error ...) are bad input."""
    for z in range(2):
        iio.imwrite(tmp_path / f"{z}{suffix}", np.random.default_rng(z).integers(0, 255, (30, 40)).astype(np.uint8))
    assert refused_cuts(tmp_path / f"1{suffix}", lambda: io.read_volume(tmp_path)) >= 20
