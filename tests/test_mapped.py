"""The reading of memory-mapped arrays: a file's arrays asked of the disk ahead (``prefetch``)."""

import os

import numpy as np
import pytest

from voxrender._shared import mapped
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
