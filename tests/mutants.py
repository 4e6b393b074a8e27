"""The mutation gate (``make mutants``): small deliberate bugs, one at a time, each of which the suite must catch.

Every mutant is one exact edit of one production file, applied to a scratch copy of the project (with
``../shared`` beside it, as in CI).  The suite runs against each and stops at its first failure: first the tests
named after the mutated module and its own doctests, which catch most mutants in seconds, then, when those pass,
the whole suite.  A mutant that no test fails on *survives*, and the gate fails.  It prints the test that caught
each mutant, so a newcomer sees what guards what; ``--every-catch`` runs the whole suite on each mutant instead and
lists every test that catches it (the suite once per mutant: over an hour).

The unmutated suite runs once first; then each mutant costs the time to its first failing test.  Measured on two
idle cores on 2026-12-06: about 10 minutes in all (the unmutated suite 198 s, the 29 mutants 382 s together).  It
is not part of ``make test``.

    python tests/mutants.py [--every-catch] [NAME ...]   # all mutants, or those whose name contains NAME
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Mutant:
    name: str
    path: str
    old: str
    new: str


MUTANTS = [
    Mutant("pixel-centre offset", "voxrender/space/view.py",
           "return ((columns + 0.5 - width / 2) / self.scale", "return ((columns + 0.4 - width / 2) / self.scale"),
    Mutant("span edge one pixel short", "voxrender/_render/geometry.py",
           "last = np.minimum(np.floor(right + EPS).astype(np.int64), width - 1)",
           "last = np.minimum(np.floor(right + EPS).astype(np.int64) - 1, width - 1)"),
    Mutant("ftb depth +0.5", "voxrender/_render/ftb.py",
           "_, entry = ray_box_entry(x - xc, y - yc, self.matrix, half_x)\n        return zc + entry",
           "_, entry = ray_box_entry(x - xc, y - yc, self.matrix, half_x)\n        return zc + entry + 0.5"),
    Mutant("MERGE comparison (case 1)", "voxrender/_render/ftb.py",
           "case = 1 + ((key_last > before) & (finish < reach)) * (1 + inside + 2 * ends_at)",
           "case = 1 + ((key_last > before) & (finish <= reach)) * (1 + inside + 2 * ends_at)"),
    Mutant("MERGE calls of a scanline made back to front", "voxrender/_render/ftb.py",
           'merged = np.argsort(_small(rank), kind="stable")', 'merged = np.argsort(-rank, kind="stable")'),
    Mutant("an unlit segment's end taken as before the span's last key when at it", "voxrender/_render/ftb.py",
           "on_hi[1] = last_in - ((last_in > 0) & (end >= after - 1))",
           "on_hi[1] = last_in - ((last_in > 0) & (end >= after))"),
    Mutant("painter order reversed", "voxrender/_render/btf.py",
           "order = back_to_front(segments.shape[0], direction[2])",
           "order = back_to_front(segments.shape[0], direction[2])[::-1]"),
    Mutant("threshold not inclusive", "voxrender/object/prep.py",
           "np.greater_equal(values, lo, out=inside)", "np.greater(values, lo, out=inside)"),
    Mutant("window's upper bound not inclusive", "voxrender/object/prep.py",
           "inside &= np.less_equal(values, hi)", "inside &= np.less(values, hi)"),
    Mutant("label tie goes to the larger label", "voxrender/pictures/labels.py",
           "np.minimum(best_label, label)", "np.maximum(best_label, label)"),
    Mutant("label lookup takes the run before", "voxrender/object/segments.py",
           'run = np.searchsorted(keys, row * (nx + 1) + x, side="right") - 1',
           'run = np.searchsorted(keys, row * (nx + 1) + x, side="left") - 1'),
    Mutant("label map resampled by rounding down", "voxrender/object/prep.py",
           "np.rint(np.arange(n) * voxel / s)", "np.floor(np.arange(n) * voxel / s)"),
    Mutant("a jump lands one step short", "voxrender/space/lines.py",
           "q = self.q + np.stack([k, *moves], axis=1)", "q = self.q + np.stack([k - (k > 0), *moves], axis=1)"),
    Mutant("an octree cell is full with seven children", "voxrender/object/octree.py",
           "full[k - 1] = parents[first][np.diff(np.r_[first, len(parents)]) == 8]",
           "full[k - 1] = parents[first][np.diff(np.r_[first, len(parents)]) >= 7]"),
    Mutant("face adjacency loses the pairs of equal leaves", "voxrender/object/octree.py",
           "((size[found] >= size) if from_low else (size[found] > size))",
           "((size[found] > size) if from_low else (size[found] > size))"),
    Mutant("tie rule: first face wins", "voxrender/_render/octree_ftb.py",
           "np.minimum.at(image, pixels, depths)          # the nearest where two faces share an edge",
           "image[pixels] = np.where(np.isfinite(image[pixels]), image[pixels], depths)"),
    Mutant("gamma neighbour search: the nearest pre-image pixel only", "voxrender/_render/preimage.py",
           "for dv in (-1, 0, 1):\n        for du in (-1, 0, 1):", "for dv in (0,):\n        for du in (0,):"),
    Mutant("octree blocking test ignores the lit leaves", "voxrender/_render/octree_ftb.py",
           "unblocked = lit[nodes] | (face_open != 0)", "unblocked = face_open != 0"),
    Mutant("Q' complement on the wrong side", "voxrender/_render/octree_sort.py",
           "if vpn[axis] < 0:\n            string = ~string", "if vpn[axis] > 0:\n            string = ~string"),
    Mutant("26->6 switch band: the object, not its dilation", "voxrender/_render/raycast.py",
           "band = proximity_band(mask) if connectivity == \"adaptive\" else None",
           "band = mask if connectivity == \"adaptive\" else None"),
    Mutant("line decision variable", "voxrender/space/lines.py",
           "        if e_y < 0:\n            e_y += 2 * b", "        if e_y <= 0:\n            e_y += 2 * b"),
    Mutant("cut plane keeps the near side", "voxrender/_render/clip.py",
           "keep &= view.to_image(x, y, z, shape)[2] >= self.cut_depth - 1e-9",
           "keep &= view.to_image(x, y, z, shape)[2] <= self.cut_depth - 1e-9"),
    Mutant("normals point inward", "voxrender/object/normals.py",
           "return keep, _octahedral_of(-gx[keep] / scale, -gy[keep] / scale, -gz[keep] / scale)",
           "return keep, _octahedral_of(gx[keep] / scale, gy[keep] / scale, gz[keep] / scale)"),
    Mutant("framing ignores the object's centre", "voxrender/space/view.py",
           "centre=((x0 + x1) / 2, (y0 + y1) / 2))", "centre=(0.0, 0.0))"),
    Mutant("ray-box entry ignores the box's y extent", "voxrender/_render/geometry.py",
           "for k, half in enumerate((half_x, half_y, half_z)):", "for k, half in enumerate((half_x, 0.5, half_z)):"),
    Mutant("linear octree in ascending Morton order", "voxrender/object/octree.py",
           "codes, level = codes[black][::-1], self.level[leaves[black]][::-1]",
           "codes, level = codes[black], self.level[leaves[black]]"),
    Mutant("a run that reaches the row's end is cut short", "voxrender/object/segments.py",
           "np.flatnonzero(lines[:, -1]) * (nx + 1) + nx])", "np.flatnonzero(lines[:, -1]) * (nx + 1) + nx - 1])"),
    Mutant("band blocks do not see the slice after them", "voxrender/object/normals.py",
           "below, above = max(first - 1, 0), min(last + 1, nz)", "below, above = max(first - 1, 0), min(last, nz)"),
    Mutant("separable gradient: y derivative smoothed instead", "voxrender/object/normals.py",
           "_add(found[1], kind(derive[dy] * smooth[dz]), across)",
           "_add(found[1], kind(smooth[dy] * smooth[dz]), across)"),
    Mutant("separable gradient: the stencil's views shifted a voxel too far", "voxrender/object/normals.py",
           "row, values_of = corner, flat[(dz * ny + dy) * nx:]",
           "row, values_of = corner, flat[(dz * ny + dy) * nx + 1:]"),
    Mutant("band bitmap: a voxel's place counts its own bit", "voxrender/object/normals.py",
           "np.bitwise_count(word & ((np.uint64(1) << bit) - np.uint64(1)))",
           "np.bitwise_count(word & ((np.uint64(1) << bit) | ((np.uint64(1) << bit) - np.uint64(1))))"),
    Mutant("cut faces face inward", "voxrender/object/normals.py",
           "face[np.arange(len(step)), axis] = np.sign(step[np.arange(len(step)), axis])",
           "face[np.arange(len(step)), axis] = -np.sign(step[np.arange(len(step)), axis])"),
]


def scratch_copy(folder):
    """The project's tracked files (as they are in the work tree) under ``folder/repo``, ``shared`` beside it."""
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    repo = folder / "repo"
    for name in files:
        target = repo / name
        target.parent.mkdir(parents=True, exist_ok=True)
        if (ROOT / name).is_file():
            shutil.copy2(ROOT / name, target)
    shared = ROOT.parent / "shared"
    if shared.exists():
        (folder / "shared").symlink_to(shared)
    return repo


def likely_tests(repo, mutant):
    """The test files named after the mutated module (``lines.py``: ``tests/test_lines*.py``), and the module
    itself for its doctests: where a mutant is most likely caught first.
    """
    stem = Path(mutant.path).stem.lstrip("_")
    named = sorted(str(p.relative_to(repo)) for p in (repo / "tests").rglob(f"test_*{stem}*.py"))
    return [*named, mutant.path]


def run_suite(repo, paths=(), first_failure=False):
    """The names of the tests that fail in ``repo`` (of ``paths``, or the whole suite), and pytest's closing line;
    with ``first_failure``, it stops at the first.
    """
    environment = dict(os.environ, PYTHONPATH=str(repo), PYTHONDONTWRITEBYTECODE="1")
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "--tb=no", "-rf", "-p", "no:cacheprovider",
                           *(["-x"] if first_failure else []), *paths],
                          cwd=repo, env=environment, capture_output=True, text=True, timeout=1200)
    failed = re.findall(r"^FAILED (\S+)", done.stdout, re.MULTILINE)
    closing = done.stdout.strip().splitlines()[-1] if done.stdout.strip() else done.stderr.strip()[-200:]
    return failed, closing


def main(arguments):
    every_catch = "--every-catch" in arguments
    names = [a for a in arguments if a != "--every-catch"]
    chosen = [m for m in MUTANTS if not names or any(n in m.name for n in names)]
    survivors = []
    with tempfile.TemporaryDirectory(prefix="voxrender-mutants-") as folder:
        repo = scratch_copy(Path(folder))
        failed, closing = run_suite(repo)
        if failed:
            print(f"the suite fails without any mutant ({closing}): {', '.join(failed[:5])}")
            return 2
        print(f"unmutated: {closing}")
        for mutant in chosen:
            path = repo / mutant.path
            original = path.read_text()
            if original.count(mutant.old) != 1:
                print(f"{mutant.name}: the text to mutate occurs {original.count(mutant.old)} times in "
                      f"{mutant.path}; update the mutant")
                return 2
            path.write_text(original.replace(mutant.old, mutant.new))
            started = time.perf_counter()
            try:
                if every_catch:
                    failed, closing = run_suite(repo)
                else:
                    failed, closing = run_suite(repo, likely_tests(repo, mutant), first_failure=True)
                    if not failed:
                        failed, closing = run_suite(repo, first_failure=True)
            finally:
                path.write_text(original)
            status = "caught" if failed else "SURVIVED"
            print(f"\n{mutant.name} ({mutant.path}): {status}, {time.perf_counter() - started:.0f} s")
            shown = failed if every_catch else failed[:8]
            for test in shown:
                print(f"    {test}")
            if len(failed) > len(shown):
                print(f"    ... and {len(failed) - len(shown)} more")
            if not failed:
                survivors.append(mutant.name)
    print(f"\n{len(chosen) - len(survivors)} of {len(chosen)} mutants caught" +
          (f"; survived: {', '.join(survivors)}" if survivors else ""))
    return 1 if survivors else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
