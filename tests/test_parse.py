import numpy as np
import pytest

from voxrender.batch import parse
from voxrender.errors import InputError
from voxrender.object import prep


@pytest.mark.parametrize("text", ["1,2", "a,b,c", "1,2,3,4", "1,nan,2"])
def test_vector_errors(text):
    with pytest.raises(InputError) as info:
        parse.vector(text, "light")
    assert info.value.parameter == "light"


@pytest.mark.parametrize("text", ["300", "1,2", "reddish", "#12345g", "-1"])
def test_colour_errors(text):
    with pytest.raises(InputError):
        parse.colour(text)


def test_crop_text_is_xyz_and_becomes_array_order():
    assert parse.crop("1:3,2:,:2") == (slice(None, 2), slice(2, None), slice(1, 3))


@pytest.mark.parametrize("text", ["1:2,:", "a:b,:,:", "5,:,:"])
def test_crop_text_errors(text):
    with pytest.raises(InputError) as info:
        parse.crop(text)
    assert info.value.parameter == "crop"


@pytest.mark.parametrize("text", ["abc", "", "inf", "nan"])
def test_threshold_rejects(text):
    with pytest.raises(InputError):
        parse.threshold(text)


def test_threshold_otsu_is_the_function():
    assert parse.threshold(" OTSU ") is prep.otsu_threshold and parse.threshold("-300") == -300.0


@pytest.mark.parametrize("text", ["64x64", "64:uint16", "0x4:uint8", "4x4:complex64", "4x4:uint16:middle",
                                  "4x4:nonsense"])
def test_raw_layout_errors(text):
    with pytest.raises(InputError) as info:
        parse.raw_layout(text)
    assert info.value.parameter == "raw"


def test_raw_layout_byte_order():
    assert parse.raw_layout("7x6:uint16:big").dtype == np.dtype(">u2")
    assert parse.raw_layout("7x6:int16").dtype == np.dtype("<i2")


@pytest.mark.parametrize("text", ["5", "3:2", "a:", "1:b"])
def test_clip_range_errors(text):
    with pytest.raises(InputError) as info:
        parse.clip_range(text, "clip_x")
    assert info.value.parameter == "clip_x"


@pytest.mark.parametrize("text", ["0", "x4", "4x0", "40000"])
def test_size_errors(text):
    with pytest.raises(InputError):
        parse.size(text)
