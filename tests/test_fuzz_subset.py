"""The fuzzing gate's share of ``make test``: a fixed small subset of its cases (one of each format, seed 0), and
every misbehaving case it kept under tests/fuzz_cases, replayed (``make fuzz`` runs the whole gate)."""

import json
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import pytest
from fuzz import cases
from fuzz.run import GOOD, KEPT, replay, run_case, run_seed

SUBSET = range(len(cases.FORMATS))          # case n is of format n modulo their number: one of each
# Subset cases that misbehave while their fix is in another engineer's hands: {case number: reason}.
SUBSET_PENDING = {}

# Kept cases whose fix is in another engineer's hands: {folder name: reason}.  Remove an entry when its fix lands
# (the strict xfail then fails, to say so).
PENDING = {}


@pytest.fixture(scope="module")
def subset_outcomes():
    """The subset's outcomes, run two at a time (each case is a few voxrender subprocesses)."""
    with ProcessPoolExecutor(2) as pool:
        return {number: (name, outcome, tail) for number, name, _, outcome, tail in
                pool.map(run_case, [0] * len(SUBSET), SUBSET, [None] * len(SUBSET))}


@pytest.mark.parametrize("number", [
    pytest.param(n, marks=[pytest.mark.xfail(strict=True, reason=SUBSET_PENDING[n])] if n in SUBSET_PENDING else [])
    for n in SUBSET])
def test_subset_case_ends_in_a_picture_or_one_error_line(subset_outcomes, number):
    name, outcome, tail = subset_outcomes[number]
    assert outcome in GOOD, f"case {number} of seed 0 ({name}): {outcome}: {tail}"


# Valid seeds that voxrender refuses while the fix is in another engineer's hands: {format: reason}.
SEED_PENDING = {}


@pytest.fixture(scope="module")
def seed_outcomes():
    with ProcessPoolExecutor(2) as pool:
        return dict(zip(sorted(cases.FORMATS), pool.map(run_seed, sorted(cases.FORMATS)), strict=True))


@pytest.mark.parametrize("name", [
    pytest.param(n, marks=[pytest.mark.xfail(strict=True, reason=SEED_PENDING[n])] if n in SEED_PENDING else [])
    for n in sorted(cases.FORMATS)])
def test_every_seed_file_renders_a_picture(seed_outcomes, name):
    """The gate damages valid files: each format's undamaged seed must make a picture, and be encoded streamed."""
    outcome, tail, _ = seed_outcomes[name]
    assert outcome == "picture", f"{name}: {outcome}: {tail}"


def test_cases_are_reproducible(tmp_path):
    """Case n of seed s is always the same file."""
    first, second = tmp_path / "first", tmp_path / "second"
    for number in (4, 11, 16):
        made = [cases.make_case(0, number, folder / str(number)) for folder in (first, second)]
        assert made[0] == made[1]
        files = [sorted((p.relative_to(folder / str(number)), p.read_bytes())
                        for p in (folder / str(number)).rglob("*") if p.is_file() and p.suffix != ".dcm")
                 for folder in (first, second)]
        assert files[0] == files[1]


KEPT_CASES = sorted(p.parent for p in KEPT.glob("*/*/case.json"))


@pytest.fixture(scope="module")
def kept_outcomes():
    """The kept cases' outcomes, replayed two at a time."""
    with ProcessPoolExecutor(2) as pool:
        return dict(zip(KEPT_CASES, pool.map(replay, KEPT_CASES), strict=True))


@pytest.mark.parametrize("kept", [
    pytest.param(path, id=path.name, marks=[pytest.mark.xfail(strict=True, reason=PENDING[path.name])]
                 if path.name in PENDING else []) for path in KEPT_CASES])
def test_kept_case_ends_in_a_picture_or_one_error_line(kept_outcomes, kept):
    outcome, tail, _ = kept_outcomes[kept]
    assert outcome in GOOD, f"{json.loads((kept / 'case.json').read_text())['name']}: {outcome}: {tail}"


def test_every_kept_case_is_small():
    for kept in KEPT_CASES:
        assert sum(p.stat().st_size for p in Path(kept).rglob("*") if p.is_file()) < 200_000, kept
