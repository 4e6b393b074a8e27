import os
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
sys.path.insert(0, str(Path(__file__).resolve().parent))


def data_path(name):
    """A real stack from ../shared/data, or skip the test with the reason (fail it in CI, where CI=true:
    there the real data must be beside the clone, or the suite would pass without its real-data tests)."""
    path = DATA / name
    if not path.exists():
        message = f"real data {path} is absent (it lives in ../shared/data beside the checkout)"
        if os.environ.get("CI") == "true":
            pytest.fail(f"{message}; CI=true needs it")
        pytest.skip(message)
    return path


@pytest.fixture
def ball():
    """A small off-centre ball with a detached speck and a slab: a phantom with several parts."""
    zz, yy, xx = np.mgrid[:12, :10, :11]
    mask = (xx - 5) ** 2 + (yy - 4.5) ** 2 + (zz - 6) ** 2 <= 16
    mask[2, 2, 2] = True
    mask[9, 1:9, 1:9] = True
    return mask
