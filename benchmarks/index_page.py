"""Building the index page of a cohort: ``write_index`` of 10,000 synthetic studies (each with a sheet, two views,
three labels and a flag), from their rows alone, no rendering; :func:`bench_index_page` is called by
``benchmarks/bench.py``.

    python -m benchmarks.index_page [--studies 10000]
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from benchmarks import median_seconds


def cohort(count):
    """``count`` study rows as a batch of TotalSegmentator-like studies gives them."""
    from voxrender.qc.index_page import StudyRow

    labels = [{"label": k, "name": name, "colour": [40 * k, 120, 200], "voxels": 1000 * k, "ml": 1.5 * k}
              for k, name in enumerate(("liver", "spleen", "kidney_left"), start=1)]
    return [StudyRow(f"study-{n:05d}", f"/data/cohort/study-{n:05d}", sheet=f"sheets/study-{n:05d}.png",
                     pictures=[("anterior", f"study-{n:05d}/anterior.png"), ("left", f"study-{n:05d}/left.png")],
                     labels=labels, flags=["liver: volume 300 mL, the cohort 1500 (z -9.1)"] if n % 50 == 0 else [],
                     severity=(1.0, -1, -9.1) if n % 50 == 0 else ())
            for n in range(count)]


def bench_index_page(studies=10_000, repeat=3):
    """Median seconds of writing the index of ``studies`` studies, and the page's size.

    Returns
    -------
    dict
        ``studies``, ``seconds``, ``megabytes``, ``bytes_per_study``.
    """
    from voxrender.qc.index_page import write_index

    rows = cohort(studies)
    with tempfile.TemporaryDirectory() as folder:
        page = Path(folder) / "index.html"
        seconds = median_seconds(lambda: write_index(page, rows), repeat)[0]
        size = page.stat().st_size
    return {"studies": studies, "seconds": seconds, "megabytes": size / 1e6,
            "bytes_per_study": size / studies}


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--studies", type=int, default=10_000)
    print(bench_index_page(parser.parse_args().studies))
