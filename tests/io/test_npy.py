"""voxrender.io.npy: 3-D NumPy arrays."""

import numpy as np
import pytest
from formats import random_stack, refused_cuts

from voxrender import io
from voxrender.errors import InputError


def test_npy(tmp_path):
    stack = random_stack()
    np.save(tmp_path / "v.npy", stack)
    assert np.array_equal(io.read_volume(tmp_path / "v.npy").values, stack)
    np.save(tmp_path / "flat.npy", stack[0])
    with pytest.raises(InputError, match="3-D"):
        io.read_volume(tmp_path / "flat.npy")


def test_booleans_become_zero_and_one(tmp_path):
    np.save(tmp_path / "mask.npy", random_stack() > 1500)
    values = io.read_volume(tmp_path / "mask.npy").values
    assert values.dtype == np.uint8 and set(np.unique(values)) == {0, 1}


def test_cut_npy_files_are_bad_input(tmp_path):
    np.save(tmp_path / "v.npy", random_stack())
    assert refused_cuts(tmp_path / "v.npy", lambda: io.read_volume(tmp_path / "v.npy")) >= 30


def test_a_header_promising_more_than_the_file_holds_says_both(tmp_path):
    """30000³ int16 over 64 bytes: was numpy's 'mmap length is greater than file size'."""
    header = "{'descr': '<i2', 'fortran_order': False, 'shape': (30000, 30000, 30000), }"
    header += " " * (117 - len(header)) + "\n"
    (tmp_path / "huge.npy").write_bytes(b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header.encode()
                                        + bytes(64))
    with pytest.raises(InputError, match=r"holds 64 bytes of voxels, of the 54 TB its header promises"):
        io.read_volume(tmp_path / "huge.npy")


def test_an_object_array_is_bad_input(tmp_path):
    np.save(tmp_path / "objects.npy", np.array([[[None]]], dtype=object), allow_pickle=True)
    with pytest.raises(InputError, match="objects.npy"):
        io.read_volume(tmp_path / "objects.npy")


@pytest.mark.parametrize("version", [(1, 0), (2, 0), (3, 0)])
def test_a_damaged_shape_in_any_header_version_is_bad_input(tmp_path, version):
    """Was "internal error: OverflowError: memory mapped length must be positive" (exit 1): numpy writes version 3.0
    headers, which were not checked before the mapping."""
    with open(tmp_path / "v.npy", "wb") as f:
        np.lib.format.write_array(f, np.zeros((2, 3, 4), np.int16), version=version)
    data = (tmp_path / "v.npy").read_bytes()
    end = data.index(b"\n")
    damaged = data[:end].replace(b"(2, 3, 4)", b"(4294967296, 4294967296, 4)").replace(b"                  ", b"", 1)
    (tmp_path / "v.npy").write_bytes(damaged + data[end:])
    with pytest.raises(InputError, match="its header promises"):
        io.read_volume(tmp_path / "v.npy")
