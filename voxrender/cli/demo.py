"""``voxrender demo`` (a sheet of the quarter head shipped with voxrender) and ``voxrender samples``."""

from __future__ import annotations

import time
from pathlib import Path

import click
import numpy as np

from .. import io, samples
from .._shared.files import check_writable
from ..errors import InputError
from ..object.pipeline import PrepOptions, ReadOptions, load_segments
from ..outputs import output
from ..pictures import RenderOptions, picture
from ..qc.sheet import sheet
from ..space.view import PRESETS
from ._main import main, progress


@main.command("samples")
@click.argument("folder", default="samples", type=click.Path(path_type=Path))
@click.option("--name", "names", multiple=True, type=click.Choice(list(samples.SAMPLES)),
              help="Which samples (default: all).")
def samples_command(folder, names):
    """Write small synthetic CT-like stacks (threshold 500) into FOLDER: PNG slice folders, NIfTI and NRRD."""
    if folder.exists() and not folder.is_dir():
        raise InputError(f"{folder} is a file; give a folder for the samples")
    folder.mkdir(parents=True, exist_ok=True)
    for name in names or samples.SAMPLES:
        values = samples.SAMPLES[name]()
        path = output.write_slices(values, folder / name)
        output.write_nifti(folder / f"{name}.nii.gz", values)
        output.write_nrrd(folder / f"{name}.nrrd", values)
        click.echo(f"{path}: {len(values)} slices, and {name}.nii.gz, {name}.nrrd beside it")


# The demo: the VTK quarter head shipped as package data in voxrender/data/headsq (its README and licence beside it).
DEMO_READ = ReadOptions(raw=io.RawLayout(64, 64, np.dtype("<u2")), spacing=(3.2, 3.2, 1.5), orientation="LPI")
DEMO_TISSUES = (("skin", 500), ("bone", 1150))
DEMO_VIEWS = (("anterior", PRESETS["anterior"]), ("left", PRESETS["left"]), ("posterior", PRESETS["posterior"]),
              ("oblique", (65.0, -35.0, 0.0)))


@main.command("demo")
@click.option("-o", "--output", "output_path", default="demo.png", show_default=True,
              type=click.Path(path_type=Path))
@click.option("--headsq", default=samples.headsq_path, show_default="the quarter head shipped with voxrender",
              type=click.Path(path_type=Path), help="A folder of the quarter-resolution head's slices.")
@click.option("--size", default=192, show_default=True, type=click.IntRange(32, 2048), help="Pixels per picture.")
def demo_command(output_path, headsq, size):
    """Render a sheet of a real CT, skin and bone from four views, to OUTPUT."""
    check_writable(output_path)
    if not (headsq / "quarter.1").is_file():
        raise InputError(f"{headsq} does not hold the quarter head (quarter.1 ... quarter.93)", parameter="headsq")
    options = RenderOptions(size=(size, size))
    started = time.perf_counter()
    rows, captions = [], []
    for tissue, threshold in DEMO_TISSUES:
        loaded = load_segments(headsq, DEMO_READ, PrepOptions(threshold=threshold), progress)
        pictures = [picture(loaded.segments, options.view(*angles), options).rgb
                    for _, angles in DEMO_VIEWS]
        rows.append(pictures)
        captions.append([f"{tissue}, {name}" for name, _ in DEMO_VIEWS])
    output.write_png(output_path, sheet(rows, captions))
    click.echo(f"{output_path}: {headsq} (CT, 64 x 64 x 93), skin and bone from {len(DEMO_VIEWS)} views, "
               f"in {time.perf_counter() - started:.1f} s")
