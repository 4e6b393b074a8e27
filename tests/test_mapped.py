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
