"""The index page of a cohort: writing it for 10,000 synthetic studies (each with a sheet, two views, three labels,
one in fifty flagged) from their rows alone, opening it in headless Chromium, moving and giving verdicts in it; and a
real batch of 300 studies with turntables, opened.  :func:`bench_index_page` and :func:`bench_index_browser` are
called by ``benchmarks/bench.py``.

    python -m benchmarks.index_page [--studies 10000] [--batch 300]
"""

from __future__ import annotations

import contextlib
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks import median_seconds

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]


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


def chromium_absent():
    """Why the browser measures cannot run here (no playwright package, no system Chromium), or ``""``."""
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "the playwright package is not installed (pip install 'voxrender[test]')"
    return "" if Path(CHROMIUM).exists() else f"{CHROMIUM} is absent (apt-get install chromium)"


@contextlib.contextmanager
def chromium():
    """Headless Chromium (the system's, driven by Playwright), closed on leaving."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            yield browser
        finally:
            browser.close()


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


def _open(browser, page_path):
    """Open the page in a fresh context: the wall seconds to its load event, the pictures it asked for by half a
    second after it (lazy pictures are asked for once the layout is done), the page."""
    context = browser.new_context(viewport={"width": 1280, "height": 800})
    pictures = []
    context.on("request", lambda request: request.url.endswith(".png") and pictures.append(request.url))
    page = context.new_page()
    started = time.perf_counter()
    page.goto(Path(page_path).as_uri())
    load_s = time.perf_counter() - started
    page.wait_for_timeout(500)
    return load_s, list(pictures), page


def _in_page_ms(page, key, times):
    """Milliseconds a key's handling takes inside the page, without the browser's frame: ``times`` keydowns, mean."""
    return page.evaluate("""([key, times]) => { const started = performance.now();
        for (let i = 0; i < times; i++) document.dispatchEvent(new KeyboardEvent("keydown", {key, bubbles: true}));
        return (performance.now() - started) / times; }""", [key, times])


def bench_index_browser(studies=10_000, batch=300, repeat=3):
    """The page of ``studies`` synthetic studies in headless Chromium, and that of a real batch of ``batch`` small
    studies with six-frame turntables; each measure the median of ``repeat`` fresh openings.

    Returns
    -------
    dict
        ``{"skipped": why}`` without a browser; else ``studies``, ``load_s`` (to the load event), ``rows_s`` (to the
        rows built, the first screen), ``pictures`` (asked for at load), ``j200_s`` (200 presses of j through
        Playwright), ``j_ms`` and ``verdict_ms`` (a key's handling in the page), ``flagged_s`` (showing the flagged),
        and ``batch``: ``studies``, ``load_s``, ``pictures``, ``turns`` (the first turntable's frames under the mouse,
        all different), ``batch_s`` (making the batch), ``bytes_per_study``.
    """
    absent = chromium_absent()
    if absent:
        return {"skipped": absent}
    from voxrender.qc.index_page import write_index

    measures = []
    with tempfile.TemporaryDirectory() as folder, chromium() as browser:
        page_path = Path(folder) / "index.html"
        write_index(page_path, cohort(studies))
        for _ in range(repeat):
            load_s, pictures, page = _open(browser, page_path)
            rows_s = page.evaluate("() => performance.getEntriesByType('navigation')[0].domContentLoadedEventEnd")
            started = time.perf_counter()
            for _ in range(200):
                page.keyboard.press("j")
            j200_s = time.perf_counter() - started
            j_ms, verdict_ms = _in_page_ms(page, "j", 50), _in_page_ms(page, "p", 20)
            started = time.perf_counter()
            page.locator("#show").select_option("flagged")
            measures.append({"load_s": load_s, "rows_s": rows_s / 1000, "pictures": len(pictures), "j200_s": j200_s,
                             "j_ms": j_ms, "verdict_ms": verdict_ms, "flagged_s": time.perf_counter() - started})
            page.context.close()
        result = {"studies": studies, **{name: statistics.median(m[name] for m in measures) for name in measures[0]}}
        result["batch"] = _bench_real_batch(browser, Path(folder) / "batch", batch, repeat)
    return result


def make_cohort_batch(folder, count):
    """``count`` small TotalSegmentator-like studies in ``folder``: a CT (``.nii.gz``) and a folder of masks (liver,
    spleen, kidney_left) each, of sizes that vary, every 30th without its spleen, every 45th with a liver three times
    the size (touching the spleen), every 60th a missing file; and ``studies.csv``, their manifest.  Written by
    nibabel, as the tools write them."""
    import nibabel as nib
    import numpy as np

    z, y, x = np.mgrid[:32, :32, :32].astype(np.float32)
    organs = {"liver": (11, 16, 16, 7.0), "spleen": (24, 12, 16, 4.0), "kidney_left": (22, 23, 10, 3.5)}
    lines = ["name,input,labels"]
    for n in range(count):
        name = f"study-{n:03d}"
        lines.append(f"{name},{name}/ct.nii.gz,{name}/segmentations")
        if n % 60 == 59:
            continue                                                 # a failed study: its files were never made
        masks = folder / name / "segmentations"
        masks.mkdir(parents=True)
        ct = np.full(x.shape, -100, np.int16)
        for organ, (cx, cy, cz, radius) in organs.items():
            radius *= 1 + 0.1 * np.sin(n * (1 + len(organ)))         # each study its own size
            if organ == "liver" and n % 45 == 20:
                radius *= 3 ** (1 / 3)
            inside = (x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2 <= radius ** 2
            ct[inside] = 60
            if not (organ == "spleen" and n % 30 == 10):
                nib.save(nib.Nifti1Image(inside.astype(np.uint8), np.diag([1.5, 1.5, 1.5, 1])),
                         masks / f"{organ}.nii.gz")
        nib.save(nib.Nifti1Image(ct, np.diag([1.5, 1.5, 1.5, 1])), folder / name / "ct.nii.gz")
    (folder / "studies.csv").write_text("\n".join(lines) + "\n")


def _bench_real_batch(browser, folder, count, repeat):
    """:func:`make_cohort_batch` through ``voxrender batch --turntable 6 --sheet``, and its page opened."""
    folder.mkdir()
    make_cohort_batch(folder, count)
    started = time.perf_counter()
    subprocess.run([sys.executable, "-m", "voxrender.cli", "batch", "--manifest", str(folder / "studies.csv"),
                    "--turntable", "6", "--size", "64", "--sheet", "--slices", "axial", "-o", str(folder / "out")],
                   capture_output=True)                              # exit 2: the failed studies
    batch_s = time.perf_counter() - started
    loads, turns = [], []
    for _ in range(repeat):
        load_s, pictures, page = _open(browser, folder / "out" / "index.html")
        turntable = page.locator("img.turntable").first
        box = turntable.bounding_box()
        for k in range(6):
            page.mouse.move(box["x"] + (k + 0.5) * box["width"] / 6, box["y"] + box["height"] / 2)
            turns.append(turntable.get_attribute("src"))
        loads.append((load_s, len(pictures)))
        page.context.close()
    return {"studies": count, "load_s": statistics.median(s for s, _ in loads),
            "pictures": statistics.median(n for _, n in loads), "turns": len(set(turns)), "batch_s": batch_s,
            "bytes_per_study": (folder / "out" / "index.html").stat().st_size / count}


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--studies", type=int, default=10_000)
    parser.add_argument("--batch", type=int, default=300)
    parser.add_argument("--repeat", type=int, default=3)
    arguments = parser.parse_args()
    print(bench_index_page(arguments.studies, arguments.repeat))
    print(bench_index_browser(arguments.studies, arguments.batch, arguments.repeat))
