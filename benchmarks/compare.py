"""The key figures of the working tree beside a reference commit's, interleaved in one run (``make bench-compare``).

    python -m benchmarks.compare REF [--repeat 3] [--data ../shared/data] [--studies 6]

REF is checked out with ``git worktree add`` under a temporary folder (removed at the end). Every figure is a fresh
process of this venv's Python with the tree's own ``voxrender`` first on ``PYTHONPATH`` (checked before the run),
the working tree and REF alternating (A B, then B A), and the medians and their ratio printed as a table:

* the whole command: ``voxrender render vhf_head`` (DICOM folder to PNG, 300 HU, 512 x 512, scale 1), its wall time
  and the stages it reports (``--stats-json``);
* ``ftb`` from a ``.vxs`` (each tree encodes its own), one view: wall and render seconds;
* ``raycast`` (adaptive rays) on the skull at 512 x 512: render seconds;
* ``voxrender encode vhf_head``;
* ``voxrender encode`` of the head's object stacked four times (a uint8 ``.npy``, 512 x 512 x 936), plain and with
  ``--octree``;
* ``voxrender batch --jobs 2`` over the first studies of ``benchmarks.studies.write_studies``, 4 views each.

A figure that fails on one side (an option REF lacks, an error) is shown as failed there, with its reason; the
others go on.
"""

from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import click
import numpy as np

from benchmarks import compile_bytecode
from benchmarks.studies import DEFAULT_DATA, HERE, VHF_THRESHOLD, write_manifest, write_studies

TIMEOUT = 600            # seconds a run may take before it counts as failed
SIDES = ("working", "ref")


def figures(data, side_folder, big, manifest):
    """name -> (argv after ``python -m voxrender.cli`` for a run ``r``, what to read: ``"wall"`` or the stats' stage).

    ``side_folder`` holds the side's own files (its ``head.vxs``); several figures come from one command (the whole
    command's wall and its stages): they share the command and are measured once per run.
    """
    head = Path(data) / "vhf_head"
    picture = ["--alpha", "30", "--beta", "10", "--size", "512", "--scale", "1"]
    threshold = ["--threshold", f"{VHF_THRESHOLD:g}"]
    commands = {
        "whole command": ["render", head, *threshold, *picture, "--stats-json", "{out}/whole.json", "-o",
                          "{out}/whole.png"],
        "ftb from .vxs": ["render", side_folder / "head.vxs", "--method", "ftb", *picture, "--stats-json",
                          "{out}/ftb.json", "-o", "{out}/ftb.png"],
        "raycast adaptive": ["render", side_folder / "head.vxs", "--method", "raycast", "--connectivity", "adaptive",
                             *picture, "--stats-json", "{out}/raycast.json", "-o", "{out}/raycast.png"],
        "encode vhf_head": ["encode", head, *threshold, "-o", "{out}/encoded.vxs"],
    }
    if big is not None:
        commands["encode head x4"] = ["encode", big, "--threshold", "1", "-o", "{out}/big.vxs"]
        commands["encode --octree head x4"] = ["encode", big, "--threshold", "1", "--octree", "-o", "{out}/big.vxo"]
    if manifest is not None:
        commands["batch of studies --jobs 2"] = ["batch", "--manifest", manifest, "-o", "{out}/batch", "--jobs", "2",
                                                 "--size", "512"]
    return commands


STAGES = ("load", "prepare", "render", "shade", "write")
READS = {"whole command": [("whole command", "wall"), *((f"  whole command: {s}", s) for s in STAGES)],
         "ftb from .vxs": [("ftb from .vxs", "wall"), ("  ftb render (its --stats-json)", "render")],
         "raycast adaptive": [("raycast adaptive 512 (render, its --stats-json)", "render")]}


def run_once(python, tree, argv, folder):
    """One fresh ``python -m voxrender.cli argv`` with ``tree`` first on the path, in the empty ``folder``:
    ``(wall seconds, stats dict or None, None)`` or ``(None, None, reason)``."""
    folder.mkdir(parents=True, exist_ok=True)
    args = [str(a).replace("{out}", str(folder)) for a in argv]
    env = {**os.environ, "PYTHONPATH": str(tree)}
    started = time.perf_counter()
    try:
        done = subprocess.run([python, "-m", "voxrender.cli", *args], capture_output=True, text=True, env=env,
                              timeout=TIMEOUT, cwd=folder)
    except subprocess.TimeoutExpired:
        return None, None, f"over {TIMEOUT} s"
    wall = time.perf_counter() - started
    if done.returncode != 0:
        lines = (done.stderr or done.stdout).strip().splitlines()
        return None, None, f"exit {done.returncode}: {lines[-1][:120] if lines else ''}"
    stats = None
    for a in args:
        if a.endswith(".json") and Path(a).is_file():
            stats = json.loads(Path(a).read_text()).get("seconds")
    return wall, stats, None


def measure(python, trees, commands, repeat, scratch):
    """Every command on every tree, interleaved (A B, then B A); returns figure -> side -> list of seconds, and
    figure -> side -> the reason it failed."""
    seconds = {}
    failed = {}
    for r in range(repeat):
        for name, argv in commands.items():
            order = SIDES if r % 2 == 0 else SIDES[::-1]
            for side in order:
                tree, side_argv = trees[side], argv[side]
                folder = Path(scratch) / side / f"{name.replace(' ', '_')}-{r}"
                wall, stats, reason = run_once(python, tree, side_argv, folder)
                shutil.rmtree(folder, ignore_errors=True)
                for figure, read in READS.get(name, [(name, "wall")]):
                    per_side = seconds.setdefault(figure, {s: [] for s in SIDES})
                    if reason is not None:
                        failed.setdefault(figure, {})[side] = reason
                    elif read == "wall":
                        per_side[side].append(wall)
                    elif stats is not None and read in stats:
                        per_side[side].append(float(stats[read]))
                    else:
                        failed.setdefault(figure, {})[side] = f"no '{read}' in its --stats-json"
    return seconds, failed


def table(seconds, failed, labels=("working", "ref")):
    """The markdown table: figure, median seconds of each side (or why it failed), working / ref."""
    lines = [f"| figure | {labels[0]} s | {labels[1]} s | {SIDES[0]}/{SIDES[1]} |", "|---|---|---|---|"]
    for figure, sides in seconds.items():
        cells, medians = [], {}
        for side in SIDES:
            values = sides.get(side) or []
            reason = failed.get(figure, {}).get(side)
            if values and not reason:
                medians[side] = statistics.median(values)
                cells.append(f"{medians[side]:.3f}")
            else:
                cells.append(f"failed ({reason})" if reason else "failed")
        ratio = f"{medians['working'] / medians['ref']:.2f}" if len(medians) == 2 and medians["ref"] > 0 else "-"
        lines.append(f"| {figure} | {cells[0]} | {cells[1]} | {ratio} |")
    return lines


def which_voxrender(python, tree, cwd):
    """Where a run on ``tree`` imports voxrender from (in ``cwd``, as the runs: not the checkout, which ``-c``
    would put first on the path)."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    done = subprocess.run([python, "-c", "import voxrender; print(voxrender.__file__)"], capture_output=True,
                          text=True, env=env, check=True, cwd=cwd)
    return done.stdout.strip()


def stacked_head(data, path, copies=4):
    """The head's object at 300 HU stacked ``copies`` times along z, as a uint8 ``.npy`` (written once)."""
    if not path.exists():
        from voxrender import io

        mask = (io.read_volume(Path(data) / "vhf_head").values >= VHF_THRESHOLD).astype(np.uint8)
        np.save(path, np.concatenate([mask] * copies, axis=0))
    return path


def git(*args, check=True):
    return subprocess.run(["git", "-C", str(HERE), *args], capture_output=True, text=True, check=check).stdout.strip()


@click.command()
@click.argument("ref")
@click.option("--repeat", default=3, show_default=True, type=click.IntRange(1, 100))
@click.option("--data", default=str(DEFAULT_DATA), show_default=True, help="Folder holding vhf_head/ and headsq/.")
@click.option("--studies", "study_count", default=6, show_default=True, type=click.IntRange(0, 24),
              help="Studies in the batch figure (0: leave it out).")
@click.option("--big/--no-big", default=True, show_default=True, help="The head stacked four times (encode figures).")
def main(ref, repeat, data, study_count, big):
    """Time the key figures of the working tree and of REF (a commit), interleaved, and print their ratios."""
    python = sys.executable
    commit = git("rev-parse", "--short", f"{ref}^{{commit}}", check=False)
    if not commit:
        raise SystemExit(f"error: {ref!r} is not a commit of {HERE}")
    head = git("rev-parse", "--short", "HEAD")
    dirty = " + uncommitted changes" if git("status", "--porcelain", "--untracked-files=no") else ""
    with tempfile.TemporaryDirectory(prefix="bench-compare-") as scratch:
        scratch = Path(scratch)
        worktree = scratch / "ref-tree"
        git("worktree", "add", "--detach", str(worktree), commit)
        try:
            trees = {"working": HERE, "ref": worktree}
            for side, tree in trees.items():
                where = which_voxrender(python, tree, scratch)
                if not Path(where).resolve().is_relative_to(Path(tree).resolve()):
                    raise SystemExit(f"error: the {side} side imports voxrender from {where}, not from {tree}")
                click.echo(f"{side}: voxrender from {where}")
                compile_bytecode(tree)    # both start as an installed package does
            manifest = None
            if study_count:
                manifest = write_manifest(scratch / "manifest.csv", write_studies(data=data)[:study_count])
            big_path = stacked_head(data, scratch / "head_x4.npy") if big else None
            commands = {}
            for side, tree in trees.items():      # each side's own .vxs of the head, by its own encode
                folder = scratch / f"{side}-files"
                folder.mkdir()
                _, _, reason = run_once(python, tree, ["encode", Path(data) / "vhf_head", "--threshold",
                                                       f"{VHF_THRESHOLD:g}", "-o", folder / "head.vxs"], folder)
                if reason:
                    click.echo(f"{side}: encoding head.vxs failed ({reason}); its .vxs figures will fail")
                for name, argv in figures(data, folder, big_path, manifest).items():
                    commands.setdefault(name, {})[side] = argv
            click.echo(f"load before: {os.getloadavg()[0]:.2f}")
            seconds, failed = measure(python, trees, commands, repeat, scratch / "runs")
            click.echo(f"load after: {os.getloadavg()[0]:.2f}")
        finally:
            git("worktree", "remove", "--force", str(worktree), check=False)
            git("worktree", "prune", check=False)
    labels = (f"working ({head}{dirty})", f"ref ({commit})")
    click.echo(f"\nMedians of {repeat} interleaved fresh runs; {len(os.sched_getaffinity(0))} cores:\n")
    click.echo("\n".join(table(seconds, failed, labels)))


if __name__ == "__main__":
    main()
