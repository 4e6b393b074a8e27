"""The memory helpers of voxrender._shared.memory."""

import os

import numpy as np
import pytest

from voxrender._shared.memory import _glibc, memory_reused


def _resident_bytes():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


@pytest.mark.skipif(_glibc() is None or not os.path.exists("/proc/self/statm"), reason="glibc on Linux only")
def test_memory_freed_within_memory_reused_stays_until_its_end():
    """A large array freed inside keeps its touched pages for the next one (no new memory to touch); freed
    outside, or at the end, they go back to the system."""
    size = 256 << 20

    def touched_then_freed():
        array = np.ones(size, np.uint8)
        del array
        return _resident_bytes()

    before = _resident_bytes()
    assert touched_then_freed() < before + size // 2            # glibc's default: its own pages, given back
    with memory_reused():
        kept = touched_then_freed()
        assert kept > before + size // 2                          # kept for the next array
        again = touched_then_freed()
        assert again < kept + size // 2                          # which reuses them
    assert _resident_bytes() < kept - size // 2                  # and given back at the end
