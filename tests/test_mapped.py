"""The reading of memory-mapped arrays: a file's arrays asked of the disk ahead (``prefetch``)."""

import os

import numpy as np
import pytest

from voxrender._shared import mapped
from voxrender.errors import InputError
from voxrender.object import segments, vxs


@pytest.mark.skipif(not hasattr(os, "posix_fadvise"), reason="this system has no posix_fadvise")
def test_prefetch_asks_for_the_bytes_of_each_mapped_array_alone(tmp_path, monkeypatch):
    encoded = segments.encode(np.random.default_rng(3).random((5, 6, 7)) < 0.5)
    vxs.save(encoded, tmp_path / "o.vxs")
    loaded = vxs.load(tmp_path / "o.vxs")
    asked = []
    monkeypatch.setattr(os, "posix_fadvise", lambda fd, offset, length, advice: asked.append(
        (os.pread(fd, length, offset), advice)))
    plain = np.arange(4)
    mapped.prefetch(loaded.starts, plain, loaded.ends)
    # the bytes advised are the arrays' own, read back from the file; a plain array is left alone
    assert asked == [(loaded.starts.tobytes(), os.POSIX_FADV_WILLNEED), (loaded.ends.tobytes(), os.POSIX_FADV_WILLNEED)]
    asked.clear()
    loaded.prefetch()
    assert [data for data, _ in asked] == [a.tobytes() for a in (loaded.offsets, loaded.starts, loaded.ends)]


@pytest.mark.parametrize("kernel_copy", ["used", "refused"])
def test_a_mapped_object_saved_again_is_copied_from_its_file_the_same(tmp_path, monkeypatch, kernel_copy):
    """A .vxs saved from a mapped one (``encode X.vxs --levels``) copies each mapped array's bytes from its file,
    within the kernel or, where it refuses, through a buffer: the same file as one saved from memory."""
    from voxrender.object.levels import build_levels
    from voxrender.object.normals import surface_normals

    mask = np.random.default_rng(5).random((9, 10, 11)) < 0.4
    encoded = segments.encode(mask)
    encoded.normals = surface_normals(mask)
    vxs.save(encoded, tmp_path / "o.vxs")
    loaded = vxs.load(tmp_path / "o.vxs")
    name, offset = mapped.file_span(loaded.ends)
    with open(name, "rb") as f:
        f.seek(offset)
        assert f.read(loaded.ends.nbytes) == loaded.ends.tobytes()
    assert mapped.file_span(np.arange(3)) is None
    if kernel_copy == "refused":
        monkeypatch.setattr(os, "copy_file_range", lambda *args: (_ for _ in ()).throw(OSError(18, "EXDEV")))
    loaded.levels = encoded.levels = build_levels(encoded)
    vxs.save(loaded, tmp_path / "again.vxs")
    vxs.save(encoded, tmp_path / "memory.vxs")
    assert (tmp_path / "again.vxs").read_bytes() == (tmp_path / "memory.vxs").read_bytes()


def test_block_reads_give_a_mapped_array_whole_in_blocks_with_their_overlap(tmp_path):
    values = np.arange(10, dtype=np.int32)
    values.tofile(tmp_path / "v.bin")
    on_file = np.memmap(tmp_path / "v.bin", np.int32, "r")[2:]
    reads = mapped.block_reads(on_file, overlap=1, count=3)
    assert [read().tolist() for read in reads] == [[2, 3, 4, 5], [5, 6, 7, 8], [8, 9]]
    assert [read().tolist() for read in mapped.block_reads(values[2:], count=3)] == [list(range(2, 10))]


def test_a_file_whose_runs_leave_their_grid_in_a_later_block_is_damaged(tmp_path, monkeypatch):
    """The runs are checked a block at a time on threads: a bad run past the first block is found too."""
    mask = np.zeros((4, 5, 6), bool)
    mask[:, :, 1:4] = True
    vxs.save(segments.encode(mask), tmp_path / "o.vxs")
    ends = vxs.load(tmp_path / "o.vxs").ends
    with open(tmp_path / "o.vxs", "r+b") as file:        # the last run's end set past the grid's last column
        file.seek(mapped.file_span(ends)[1] + ends.itemsize * (len(ends) - 1))
        file.write(np.array([6], ends.dtype).tobytes())
    monkeypatch.setattr(vxs, "block_reads", lambda array, overlap=0: mapped.block_reads(array, overlap, count=4))
    with pytest.raises(InputError, match="runs leave their grid"):
        vxs.load(tmp_path / "o.vxs")


def test_search_mapped_searches_in_the_arrays_own_type_and_finds_what_numpy_finds(tmp_path, monkeypatch):
    """NumPy searches int64 values in an int32 array by copying the whole array to int64 first (454 MB for the big
    stack's level 1, for each search): the values are searched as int32, those out of its range placed at the ends.
    """
    rng = np.random.default_rng(5)
    index = np.unique(rng.integers(-1000, 1000, 300)).astype(np.int32)
    index.tofile(tmp_path / "i.bin")
    on_file = np.memmap(tmp_path / "i.bin", np.int32, "r")
    values = np.concatenate([rng.integers(-1200, 1200, 200), [-2 ** 40, 2 ** 40, index[0], index[-1]]])
    expected = np.searchsorted(index.astype(np.int64), values)
    searched = []
    numpy_search = np.searchsorted
    monkeypatch.setattr(np, "searchsorted", lambda a, v, *args: searched.append((np.asarray(a).dtype,
                                                                                np.asarray(v).dtype))
                        or numpy_search(a, v, *args))
    for array in (index, on_file):
        assert mapped.search_mapped(array, values, block=16).tolist() == expected.tolist()
    assert searched and all(pair == (np.int32, np.int32) for pair in searched)
