"""``voxrender batch``: many inputs from many views, their summary, index page, sheet and animations."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import click

from ..batch import parse, spec
from ..batch.run import run_batch
from ..errors import InputError
from ..space.view import PRESETS
from ._main import main
from ._options import (
    check_study_from,
    check_window,
    output_paths_of,
    prep_flags,
    prep_options_of,
    read_flags,
    read_options_of,
    render_flags,
    render_options_of,
    slice_flags,
    slice_options_of,
)


class _BatchBar:
    """A click progress bar over a whole batch (stderr, terminals only)."""

    def __init__(self, length):
        self.bar = click.progressbar(length=length, label="batch", file=sys.stderr) if sys.stderr.isatty() else None
        if self.bar:
            self.bar.__enter__()

    def update(self, n):
        if self.bar:
            self.bar.update(n)

    def close(self):
        if self.bar:
            self.bar.__exit__(None, None, None)


@main.command("batch")
@click.argument("inputs", nargs=-1, metavar="[INPUT|GLOB]...")
@click.option("-o", "--out", "out_dir", required=True, type=click.Path(path_type=Path),
              help="Folder for the pictures and summary.csv.")
@click.option("--manifest", type=click.Path(path_type=Path),
              help="CSV or TOML: input, threshold, views, method, output.")
@read_flags
@prep_flags
@click.option("--view", "views", multiple=True, type=click.Choice(list(PRESETS)), help="A named view (repeatable).")
@click.option("--angles", multiple=True, metavar="A,B,G", help="alpha,beta,gamma in degrees (repeatable).")
@click.option("--turntable", type=click.IntRange(1, 3600), metavar="N",
              help="N views turning the object about --axis, from the first view given (default anterior).")
@click.option("--axis", default="z", show_default=True, type=click.Choice(["x", "y", "z"]))
@click.option("--pattern", default="{name}/{view}.png", show_default=True,
              help="Output names under --out: {name}, {view}, {method}, {index}.")
@render_flags
@click.option("--per-label", is_flag=True,
              help="Also write each label the picture shows alone, beside it ({view}-label{N}.png).")
@click.option("--sheet", "make_sheet", is_flag=True,
              help="Also each input's QC sheet in OUT/sheets/NAME.png (its views, --projection, --slices and labels) "
                   "and all pictures laid out in OUT/sheet.png.")
@slice_flags
@click.option("--gif", is_flag=True, help="Also write each input's views as an animated GIF.")
@click.option("--mp4", is_flag=True, help="Also write each input's views as an MP4 (extra 'video').")
@click.option("--fps", default=12, show_default=True, type=click.IntRange(1, 120))
@click.option("--jobs", type=click.IntRange(1, 1024), help="Worker processes (default: the machine's cores).")
@click.option("--scheduler", metavar="ADDRESS|local", help="Run on a Dask cluster ('local' starts one here).")
@click.option("--cache", type=click.Path(path_type=Path),
              help="Cache of encoded objects (default OUT/.voxrender-cache).")
@click.option("--reference", type=click.Path(path_type=Path), metavar="REF",
              help="A reference segmentation each input's labels are held to (a manifest's reference column gives "
                   "one a row): OUT/agreement.csv, and Dice and NSD flags.")
@click.option("--tolerance-mm", default=2.0, show_default=True, type=click.FloatRange(0),
              help="The normalised surface Dice's tolerance.")
@click.option("--min-dice", default=0.8, show_default=True, type=click.FloatRange(0, 1),
              help="With a reference: a label under this Dice is flagged.")
@click.option("--min-nsd", type=click.FloatRange(0, 1), help="With a reference: a label under this NSD is flagged.")
@click.option("--verdicts", type=click.Path(path_type=Path), metavar="FILE.csv",
              help="An earlier review's verdicts.csv (exported from an index page): put into this index.")
def batch_command(inputs, out_dir, manifest, views, angles, turntable, axis, pattern, per_label, make_sheet, gif,
                  mp4, fps, jobs, scheduler, cache, reference, tolerance_mm, min_dice, min_nsd, verdicts, **options):
    """Render many inputs from many views: pictures, summary.csv, index.html, and optionally a sheet or animation.

    Each input is encoded once (and cached); a failing input is reported and the others go on;
    a re-run skips the pictures already made.  The render options are those of 'voxrender render';
    --depth-out, --depth-png and --stats-json are patterns like --pattern.
    """
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"--out {out_dir} is a file; give a folder")
    patterns = spec.Patterns(pattern, **{name: str(path) for name, path in output_paths_of(options).items()})
    slice_options = slice_options_of(options)
    render_options = render_options_of(options)
    check_window(render_options, slice_options)
    if per_label and not render_options.drawn.labels:
        raise InputError("a projection draws grey values, not labels one by one; drop --per-label, or the projection",
                         parameter="per_label")
    if slice_options is not None and not make_sheet:
        raise InputError("slices are drawn on each input's QC sheet; give --sheet too", parameter="planes")
    check_study_from(options, options.get("dicom"))
    items = spec.items_from(spec.expand_inputs(inputs), spec.read_manifest(manifest) if manifest else [],
                             read_options_of(options), prep_options_of(options), render_options,
                             spec.parse_views(views, [parse.vector(a, "angles") for a in angles], turntable, axis),
                             patterns, per_label, make_sheet, slice_options, options["dicom_study_from"],
                             reference, tolerance_mm)
    animations = [kind for kind, wanted in (("gif", gif), ("mp4", mp4)) if wanted]
    started = time.perf_counter()
    from ..qc.index_page import read_verdicts

    earlier = read_verdicts(verdicts) if verdicts is not None else None
    summary = run_batch(items, out_dir, jobs, scheduler, cache, animations, fps, _BatchBar, make_sheet,
                              min_dice, min_nsd, earlier)
    made = sum(r["status"] == "ok" for r in summary)
    earlier = sum(r["status"] == "done earlier" for r in summary)
    failed = {r["input"]: r["error"] for r in summary if r["status"] == "failed"}
    click.echo(f"{out_dir}: {made} pictures made, {earlier} done earlier, {len(summary) - made - earlier} failed, "
               f"in {time.perf_counter() - started:.1f} s; summary in {out_dir / 'summary.csv'}")
    for path, error in failed.items():
        click.echo(f"failed: {path}: {error}", err=True)
    if failed:
        sys.exit(2)
