"""voxrender.io.raw: headerless slices."""

import numpy as np
import pytest
from conftest import data_path
from formats import random_stack

from voxrender import io
from voxrender.errors import InputError


def test_raw_folder_and_single_file(tmp_path):
    stack = random_stack()
    folder = tmp_path / "slices"
    folder.mkdir()
    for z, plane in enumerate(stack):
        plane.astype(">u2").tofile(folder / f"q.{z + 1}")
    (folder / "q.nhdr").write_text("NRRD0004\n")  # headers beside raw slices are not slices
    volume = io.read_volume(folder, raw=io.RawLayout(7, 6, np.dtype(">u2")))
    assert np.array_equal(volume.values, stack)
    stack.astype("<u2").tofile(tmp_path / "all.raw")
    assert np.array_equal(io.read_volume(tmp_path / "all.raw", raw=io.RawLayout(7, 6, np.dtype("<u2"))).values, stack)


def test_raw_size_mismatch(tmp_path):
    stack = random_stack()
    stack.astype("<u2").tofile(tmp_path / "all.raw")
    with pytest.raises(InputError, match="not a multiple"):
        io.read_volume(tmp_path / "all.raw", raw=io.RawLayout(8, 6, np.dtype("<u2")))


@pytest.mark.parametrize("width, height, dtype", [(0, 4, "u1"), (4, 4, "complex64"), (4, -1, "u2")])
def test_raw_layout_errors(width, height, dtype):
    with pytest.raises(InputError) as info:
        io.RawLayout(width, height, np.dtype(dtype))
    assert info.value.parameter == "raw"


def test_headsq_raw():
    volume = io.read_volume(data_path("headsq"), raw=io.RawLayout(64, 64, np.dtype("<u2")), spacing=(3.2, 3.2, 1.5))
    assert volume.shape == (93, 64, 64) and volume.spacing == (3.2, 3.2, 1.5)
    assert 3000 < volume.values.max() < 5000


def test_raw_slices_need_their_layout(tmp_path):
    random_stack().tofile(tmp_path / "all.raw")
    with pytest.raises(InputError, match="raw slices need their layout") as info:
        io.read_volume(tmp_path / "all.raw", format="raw")
    assert info.value.parameter == "raw"


def test_slices_too_big_for_memory_are_refused_with_their_size(tmp_path, monkeypatch):
    from voxrender.io import _shared

    random_stack().astype("<u2").tofile(tmp_path / "all.raw")
    monkeypatch.setattr(_shared, "free_memory", lambda: 100)
    with pytest.raises(InputError, match=r"its 5x6x7 uint16 voxels take 420 bytes, more than the 100 bytes of memory"):
        io.read_volume(tmp_path / "all.raw", raw=io.RawLayout(7, 6, np.dtype("<u2")))
