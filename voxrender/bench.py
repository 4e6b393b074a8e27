"""The benchmark behind ``make benchmark``: medians of repeated runs, ratios measured in the same run.

Runs on ``../shared/data/vhf_head`` (or ``--data``); writes a Markdown table
and the raw numbers as JSON into ``benchmark-results/``.

    python -m voxrender.bench [--repeat 5] [--data ../shared/data] [--out benchmark-results]
"""

from __future__ import annotations

import json
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import click
import numpy as np

from . import io, prep, segments
from .render import METHODS, render
from .view import View

# The dynamic-screen paper's Fig. 10 orientations (alpha, beta), then a few fixed "random" ones.
PAPER_VIEWS = [(-45.0, 15.0), (60.0, 120.0), (30.0, 10.0)]
RANDOM_VIEWS = [tuple(float(round(a, 1)) for a in pair)
                for pair in np.random.default_rng(2026).uniform(-180, 180, size=(3, 2))]


def median_seconds(work, repeat):
    """Median wall time of ``repeat`` calls of ``work()`` and the last result."""
    times, result = [], None
    for _ in range(repeat):
        started = time.perf_counter()
        result = work()
        times.append(time.perf_counter() - started)
    return statistics.median(times), result


def bench_encode(volume, threshold, repeat):
    seconds, encoded = median_seconds(lambda: segments.encode(prep.binarize(volume, threshold)[0]), repeat)
    return {"threshold_and_encode_s": seconds, "voxels": encoded.voxel_count, "segments": encoded.segment_count,
            "grid": list(encoded.shape)}, encoded


def bench_render(encoded, repeat, size=512, scale=1.0):
    rows = []
    for alpha, beta in PAPER_VIEWS + RANDOM_VIEWS:
        view = View(alpha, beta, 0.0, (size, size), scale)
        row = {"alpha": alpha, "beta": beta}
        for method in METHODS:
            seconds, image = median_seconds(lambda: render(encoded, view, method), repeat)
            row[method] = {"seconds": seconds, "stats": image.stats, "covered": int(image.coverage.sum())}
        rows.append(row)
    return rows


def bench_pipeline(path, threshold, repeat):
    """The whole command, from DICOM folder to PNG, as a user runs it (a fresh process each time)."""
    with tempfile.TemporaryDirectory() as folder:
        command = [sys.executable, "-m", "voxrender.cli", "render", str(path), "--threshold", str(threshold),
                   "--alpha", "30", "--beta", "10", "--size", "512", "--scale", "1", "-o", f"{folder}/out.png"]
        seconds, _ = median_seconds(lambda: subprocess.run(command, check=True, capture_output=True), repeat)
    return {"command": "voxrender render vhf_head --threshold 300 --alpha 30 --beta 10 --size 512 --scale 1",
            "seconds": seconds}


def markdown(results):
    lines = [f"voxrender benchmark, {results['when']}, {results['machine']}", "",
             f"vhf_head at {results['threshold']} HU: grid {results['encode']['grid'][::-1]} (x, y, z), "
             f"{results['encode']['voxels']} object voxels, {results['encode']['segments']} segments; "
             f"read DICOM {results['read_s']:.2f} s, threshold + encode {results['encode']['threshold_and_encode_s']:.3f} s "
             f"(median of {results['repeat']})", "",
             "| alpha | beta | " + " | ".join(f"{m} s" for m in METHODS) + " |",
             "|---|---|" + "---|" * len(METHODS)]
    for row in results["render"]:
        lines.append(f"| {row['alpha']:g} | {row['beta']:g} | " +
                     " | ".join(f"{row[m]['seconds']:.3f}" for m in METHODS) + " |")
    lines += ["", f"whole pipeline, DICOM folder to PNG, one process: {results['pipeline']['seconds']:.2f} s "
              f"(`{results['pipeline']['command']}`)"]
    return "\n".join(lines)


@click.command()
@click.option("--data", default=str(Path(__file__).resolve().parents[1].parent / "shared" / "data"),
              show_default=True, help="Folder holding vhf_head/.")
@click.option("--repeat", default=5, show_default=True, type=click.IntRange(1, 100))
@click.option("--out", default="benchmark-results", show_default=True, type=click.Path())
@click.option("--threshold", default=300.0, show_default=True)
def main(data, repeat, out, threshold):
    """Time every renderer on vhf_head and write benchmark-results/."""
    path = Path(data) / "vhf_head"
    if not path.is_dir():
        raise SystemExit(f"error: {path} is absent; the benchmark needs ../shared/data (or --data)")
    started = time.perf_counter()
    volume = io.read_volume(path)
    read_s = time.perf_counter() - started
    encode, encoded = bench_encode(volume, threshold, repeat)
    results = {"when": time.strftime("%Y-%m-%d %H:%M"), "machine": f"{platform.machine()}, {platform.python_version()}, "
               f"numpy {np.__version__}", "repeat": repeat, "threshold": threshold, "read_s": read_s,
               "encode": encode, "render": bench_render(encoded, repeat),
               "pipeline": bench_pipeline(path, threshold, max(1, repeat // 2))}
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps(results, indent=2, default=float))
    (out / "results.md").write_text(markdown(results) + "\n")
    click.echo(markdown(results))


if __name__ == "__main__":
    main()
