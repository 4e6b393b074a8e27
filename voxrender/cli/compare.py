"""``voxrender compare``: a picture against its golden image, for tests in a pipeline."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from ..pictures import compare
from ._main import main


@main.command("compare")
@click.argument("picture", type=click.Path(path_type=Path))
@click.argument("golden", type=click.Path(path_type=Path))
@click.option("--tolerance", default=1, show_default=True, type=click.IntRange(0, 65535),
              help="Grey levels a pixel may be off and still count as equal.")
@click.option("--share", default=0.001, show_default=True, type=click.FloatRange(0, 1),
              help="Share of pixels that may be off by more than the tolerance.")
def compare_command(picture, golden, tolerance, share):
    """Compare PICTURE with GOLDEN (golden-image tests): exit 0 when they match, 1 when they do not."""
    result = compare.compare(compare.read_picture(picture), compare.read_picture(golden), tolerance, share)
    click.echo(f"{picture} against {golden}: mean difference {result['mean_difference']:.3f}, largest "
               f"{result['largest']}, {100 * result['share_off']:.3f} % of pixels off by more than {tolerance} "
               f"(allowed {100 * share:g} %): {'same' if result['same'] else 'DIFFERENT'}")
    if not result["same"]:
        sys.exit(1)
