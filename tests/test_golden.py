"""The golden pictures (tests/golden.py lists the cases): each command must make its picture again, equal or
at most one grey level off on at most 0.1 % of the pixels (room for a last-bit difference in shading)."""

import imageio.v3 as iio
import pytest
from conftest import data_path
from golden import CASES, GOLDEN, REAL_DATA, render_case

from voxrender.pictures.compare import compare


@pytest.fixture(scope="module")
def samples(tmp_path_factory):
    return tmp_path_factory.mktemp("golden") / "samples"


@pytest.mark.parametrize("name", list(CASES))
def test_pictures_match_the_golden_ones(name, samples, tmp_path):
    data = data_path("headsq").parent if name in REAL_DATA else None
    output = tmp_path / f"{name}.png"
    render_case(name, output, samples, *([data] if data else []))
    picture, golden = iio.imread(output), iio.imread(GOLDEN / f"{name}.png")
    result = compare(picture, golden, tolerance=1, share=0.001)     # what 'voxrender compare' reports
    assert result["largest"] <= 1 and result["same"], result


def test_the_comparison_sees_small_changes():
    golden = iio.imread(GOLDEN / "shell-ftb.png")
    blanked = golden.copy()
    covered = golden > 0
    rows, columns = covered.nonzero()
    blanked[rows[:40], columns[:40]] = 0                       # 40 object pixels blanked (a grey picture)
    assert compare(blanked, golden)["largest"] > 1
    brighter = golden.astype(int)
    brighter[covered] += 3                                      # ambient a little brighter
    assert compare(brighter, golden)["largest"] == 3 and compare(brighter, golden)["share_off"] == covered.mean()
