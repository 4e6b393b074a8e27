"""Refactorings leave the renderers alone: every method's depth image and statistics on the phantoms, compared
with a record made by the code before issue 10's refactoring (``benchmarks/equivalence.py``, which also runs the
same comparison on vhf_head at the benchmark's views)."""

from pathlib import Path

import numpy as np

from benchmarks import equivalence

RECORD = Path(__file__).parent / "data" / "equivalence.npz"


def test_depths_and_statistics_match_the_record():
    before = dict(np.load(RECORD))
    after = equivalence.record(equivalence.phantom_cases())
    problems, worst = equivalence.compare(before, after)
    assert not problems, "\n".join(problems)
    assert len(after) == len(before) == 252 and worst <= equivalence.TOLERANCE


def test_the_comparison_sees_a_change():
    before = dict(np.load(RECORD))
    key = "sphere/a30b10/none/ftb/depth"
    moved = dict(before, **{key: before[key] + np.float32(1e-3)})
    assert any(key in line for line in equivalence.compare(before, moved)[0])
    stats_key = key.replace("/depth", "/stats")
    changed = dict(before, **{stats_key: np.array(str(before[stats_key]).replace("1", "2", 1))})
    assert any(stats_key in line for line in equivalence.compare(before, changed)[0])
