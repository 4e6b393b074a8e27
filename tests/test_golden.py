"""The golden pictures (tests/golden.py lists the cases): each command must make its picture again, equal or
at most one grey level off on at most 0.1 % of the pixels (room for a last-bit difference in shading)."""

import imageio.v3 as iio
import pytest

from conftest import data_path
from golden import CASES, GOLDEN, REAL_DATA, compare, render_case


@pytest.fixture(scope="module")
def samples(tmp_path_factory):
    return tmp_path_factory.mktemp("golden") / "samples"


@pytest.mark.parametrize("name", list(CASES))
def test_pictures_match_the_golden_ones(name, samples, tmp_path):
    data = data_path("headsq").parent if name in REAL_DATA else None
    output = tmp_path / f"{name}.png"
    render_case(name, output, samples, *([data] if data else []))
    picture, golden = iio.imread(output), iio.imread(GOLDEN / f"{name}.png")
    assert picture.shape == golden.shape
    largest, share = compare(picture, golden)
    assert largest <= 1 and share <= 0.001, (largest, share)


def test_the_comparison_sees_small_changes():
    golden = iio.imread(GOLDEN / "demo.png")
    blanked = golden.copy()
    covered = golden.any(axis=2)
    rows, columns = covered.nonzero()
    blanked[rows[:40], columns[:40]] = 0                       # 40 object pixels blanked
    assert compare(blanked, golden)[0] > 1
    brighter = golden.astype(int)
    brighter[covered] += 3                                      # ambient a little brighter
    assert compare(brighter, golden) == (3, covered.mean())
