import os

import numpy as np
import pytest

from voxrender._shared.files import PARTIAL, atomic_output, check_folder_writable, check_writable, remove_partials
from voxrender.errors import InputError
from voxrender.outputs import output


def test_atomic_output_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "out.png"
    with pytest.raises(RuntimeError):
        with atomic_output(target) as tmp:
            tmp.write_bytes(b"half")
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_atomic_output_has_the_usual_permissions(tmp_path):
    target = tmp_path / "out.bin"
    with atomic_output(target) as tmp:
        tmp.write_bytes(b"x")
    mask = os.umask(0)
    os.umask(mask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~mask


def test_check_writable(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        check_writable(tmp_path / "no" / "out.png")
    with pytest.raises(InputError, match="is a folder"):
        check_writable(tmp_path)


def test_writers_round_trip(tmp_path):
    import json

    import imageio.v3 as iio

    depth = np.array([[1.5, np.inf]], np.float32)
    output.write_npy(tmp_path / "d.npy", depth)
    assert np.array_equal(np.load(tmp_path / "d.npy"), depth)
    output.write_json(tmp_path / "s.json", {"a": np.float32(0.5)})
    assert json.loads((tmp_path / "s.json").read_text()) == {"a": 0.5}
    slices = np.arange(24, dtype=np.uint16).reshape(2, 3, 4) * 1000
    folder = output.write_slices(slices, tmp_path / "stack")
    assert np.array_equal(np.stack([iio.imread(folder / f"slice_00{z}.png") for z in range(2)]), slices)


def test_atomic_output_writes_beside_its_target_and_a_failed_write_leaves_nothing(tmp_path):
    import errno

    target = tmp_path / "out.png"
    with pytest.raises(OSError):
        with atomic_output(target) as tmp:
            assert tmp.parent == tmp_path and PARTIAL in tmp.name       # renamed in the same folder
            tmp.write_bytes(b"half")
            raise OSError(errno.ENOSPC, "No space left on device")
    assert list(tmp_path.iterdir()) == []


def test_remove_partials_clears_what_a_killed_writer_left(tmp_path):
    (tmp_path / "a").mkdir()
    left = tmp_path / "a" / f".x.png{PARTIAL}k1ll3d.png"
    left.write_bytes(b"half")
    (tmp_path / "a" / "x.png").write_bytes(b"whole")
    (tmp_path / ".hidden.png").write_bytes(b"the user's")
    assert remove_partials(tmp_path / "a") == 1
    assert sorted(p.name for p in tmp_path.rglob("*")) == [".hidden.png", "a", "x.png"]


def test_check_folder_writable_tries_a_real_write(tmp_path):
    check_folder_writable(tmp_path)
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(InputError, match="cannot write in .*: No such file or directory"):
        check_folder_writable(tmp_path / "missing")
