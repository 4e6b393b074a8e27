"""Prove that a refactoring left every renderer's output alone: depth images and statistics, case by case.

    python -m benchmarks.equivalence record OUT.npz [--head ../shared/data/vhf_head]
    python -m benchmarks.equivalence compare BEFORE.npz AFTER.npz

``record`` renders a fixed grid of cases (the synthetic phantoms and, with ``--head``, ``vhf_head`` at
300 HU at the benchmark's views) with every method and saves each depth image and its statistics.
Run it once with the code before a change and once after (``PYTHONPATH`` picks the tree), then
``compare``: coverage and statistics must be identical and depths within ``1e-5`` voxels.
It uses only ``segments.encode``, ``view.View``, ``render.render`` and ``render.Clip``, which keep
their signatures, so the same script runs on both sides.  ``tests/test_equivalence.py`` keeps the
phantom part as a test against ``tests/data/equivalence.npz`` (see that test for when it was recorded).
"""

from __future__ import annotations

import json
import sys

import numpy as np

METHODS = ("ftb", "btf", "raycast", "octree-btf", "octree-ftb", "octree-sort", "zbuffer")
TOLERANCE = 1e-5
# Statistics that are seconds, not counts: they differ from run to run.  And the loop iterations a ray caster
# runs, which is how it does the work, not what it finds: skipping empty space cut them, the steps stay.
TIMINGS = {"black_seconds", "reference_seconds", "iterations"}


def phantom_cases():
    """(name, mask, view kwargs, clip kwargs) of the small cases: every method, gamma, clip and cut."""
    from voxrender import samples

    masks = {"sphere": samples.sphere(14) > 500, "torus": samples.torus(20) > 500,
             "staircase": np.zeros((4, 4, 4), bool)}
    for x, y, z in samples.STAIRCASE_VOXELS:
        masks["staircase"][z, y, x] = True
    views = {"a30b10": dict(alpha=30, beta=10), "a-45b15g30": dict(alpha=-45, beta=15, gamma=30),
             "vpn1-21": dict(alpha=-63.43494882292201, beta=24.094842552110702),
             "axis": dict(alpha=90, beta=0)}
    clips = {"none": {}, "clip": dict(x=(2, None), z=(None, 11)), "cut": dict(cut_depth=0.5)}
    for name, mask in masks.items():
        for view_name, angles in views.items():
            for clip_name, clip in clips.items():
                if clip_name != "none" and (name != "sphere" or view_name == "axis"):
                    continue
                yield f"{name}/{view_name}/{clip_name}", mask, dict(angles, size=(40, 40), scale=1.7), clip


def head_cases(folder):
    """vhf_head at 300 HU, 512 x 512 at scale 1, the benchmark's views."""
    from voxrender import io
    from voxrender.object import prep

    mask = prep.binarize(io.read_volume(folder), 300)[0]
    views = [(-45.0, 15.0), (60.0, 120.0), (30.0, 10.0), (-115.6, 50.4), (-11.8, -46.6), (-52.2, 104.6)]
    for alpha, beta in views:
        yield f"head/{alpha:g},{beta:g}", mask, dict(alpha=alpha, beta=beta, size=(512, 512), scale=1.0), {}


def record(cases, methods=METHODS):
    from voxrender._render import Clip, render
    from voxrender.object import segments
    from voxrender.space.view import View

    result = {}
    encoded_masks = {}
    for name, mask, view, clip in cases:
        key = id(mask)
        if key not in encoded_masks:
            encoded_masks[key] = (mask, segments.encode(mask))
        encoded = encoded_masks[key][1]
        for method in methods:
            if method == "raycast" and view["size"][0] > 64:
                continue  # seconds a picture at 512 x 512: the phantoms cover it
            options = {"compare": True} if method == "raycast" else {}     # with the leaks, misses and late hits
            image = render(encoded, View(**view), method, clip=Clip(**clip) if clip else None, **options)
            stats = {k: v for k, v in image.stats.items() if k not in TIMINGS}
            result[f"{name}/{method}/depth"] = image.depth
            result[f"{name}/{method}/stats"] = np.array(json.dumps(stats, sort_keys=True, default=float))
    return result


def _counts(stats):
    """A record's statistics without the timings (records made before a key joined TIMINGS may hold it)."""
    return {k: v for k, v in json.loads(str(stats)).items() if k not in TIMINGS}


def compare(before, after):
    """Lines describing every difference; empty when the two records agree."""
    problems = []
    worst = 0.0
    for key in sorted(set(before) | set(after)):
        if key not in before or key not in after:
            problems.append(f"{key}: only in {'after' if key in after else 'before'}")
            continue
        if key.endswith("/stats"):
            if _counts(before[key]) != _counts(after[key]):
                problems.append(f"{key}: statistics differ: {before[key]} != {after[key]}")
            continue
        a, b = before[key], after[key]
        if not np.array_equal(np.isfinite(a), np.isfinite(b)):
            problems.append(f"{key}: coverage differs on {int((np.isfinite(a) != np.isfinite(b)).sum())} pixels")
            continue
        covered = np.isfinite(a)
        difference = float(np.abs(a[covered] - b[covered]).max()) if covered.any() else 0.0
        worst = max(worst, difference)
        if difference > TOLERANCE:
            problems.append(f"{key}: depths differ by up to {difference:.3g} voxels")
    return problems, worst


def main(argv):
    if argv[:1] == ["record"] and len(argv) >= 2:
        cases = list(phantom_cases())
        if "--head" in argv:
            cases += list(head_cases(argv[argv.index("--head") + 1]))
        np.savez_compressed(argv[1], **record(cases))
        return 0
    if argv[:1] == ["compare"] and len(argv) == 3:
        before, after = (dict(np.load(path)) for path in argv[1:])
        problems, worst = compare(before, after)
        print("\n".join(problems) or f"{len(before) // 2} cases: identical coverage and statistics, "
                                      f"depths within {worst:.3g} voxels")
        return 1 if problems else 0
    print(__doc__)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
