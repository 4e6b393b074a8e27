import os
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
sys.path.insert(0, str(Path(__file__).resolve().parent))


def absent(message):
    """Skip the test, saying what is absent; fail it in CI (CI=true), which provides everything the tests need, so
    that the suite cannot pass there without them."""
    if os.environ.get("CI") == "true":
        pytest.fail(f"{message}; CI=true needs it")
    pytest.skip(message)


def data_path(name):
    """A real stack from ../shared/data, or :func:`absent`."""
    path = DATA / name
    if not path.exists():
        absent(f"real data {path} is absent (it lives in ../shared/data beside the checkout)")
    return path


@pytest.fixture
def ball():
    """A small off-centre ball with a detached speck and a slab: a phantom with several parts."""
    zz, yy, xx = np.mgrid[:12, :10, :11]
    mask = (xx - 5) ** 2 + (yy - 4.5) ** 2 + (zz - 6) ** 2 <= 16
    mask[2, 2, 2] = True
    mask[9, 1:9, 1:9] = True
    return mask
