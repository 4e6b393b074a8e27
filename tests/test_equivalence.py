"""Refactorings leave the renderers alone: every method's depth image and statistics on the phantoms, compared
with a record (``tests/data/equivalence.npz``, made by ``python -m benchmarks.equivalence record``; the same
script compares two records of vhf_head at the benchmark's views).

The record was made before issue 10's refactoring, and made again when issue 15 changed two outputs on
purpose: ``btf`` became a true painter (on rays along faces between voxels it keeps the voxel painted last),
and discrete rays along the volume's boundary faces are no longer cut short.  Make it again only after an
intended change, and say in the commit which outputs changed and why."""

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
