"""``voxrender info`` (what :func:`voxrender.describe` says of an input) and ``voxrender presets``."""

from __future__ import annotations

import json

import click

from ..pictures import colours
from ..qc.description import describe
from ._main import main, progress
from ._options import check_vxs_options, input_flags, prep_flags, prep_options_of, read_options_of


@main.command("info")
@input_flags
@prep_flags
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
def info_command(input_path, as_json, **options):
    """Describe INPUT: size, spacing, values, a suggested threshold, the object at a threshold."""
    check_vxs_options(input_path, options)
    summary = describe(input_path, read_options_of(options), prep_options_of(options), progress)
    if as_json:
        click.echo(json.dumps(summary, indent=2, default=float))
        return
    for key, value in summary.items():
        if key == "labels":                                    # a line a label, the number a reader compares first
            click.echo(f"labels: {len(value)}")
            for label, row in value.items():
                click.echo(f"  {label} {row['name']}: {row['voxels']} voxels, {row['ml']:g} mL")
        elif key == "overlaps":
            click.echo(f"overlaps: {len(value)} pair{'s' * (len(value) > 1)} of labels (each keeps its own voxels; "
                       "the pictures show the smaller)")
            for pair in value:
                inside = f", {pair['inside']} lies inside the other" if pair.get("inside") else ""
                click.echo(f"  {' and '.join(pair['names'])}: {pair['voxels']} voxels{inside}")
        elif key == "levels":                                  # a line a level of detail
            click.echo(f"levels: {len(value)} besides the voxels' own (render --level N; by default the picture's)")
            for row in value:
                click.echo(f"  {row['level']}: voxels {row['voxel_edge']} times larger, "
                           f"{'x'.join(map(str, row['dimensions_xyz']))}, {row['object_voxels']} in the object, "
                           f"{row['segments']} segments")
        elif isinstance(value, list) and value and all(isinstance(v, str) for v in value):
            click.echo(f"{key.replace('_', ' ')}:")
            for line in value:
                click.echo(f"  {line}")
        else:
            click.echo(f"{key.replace('_', ' ')}: {value}")


@main.command("presets")
def presets_command():
    """List the CT tissue presets of --preset: HU window, colour, and where the values come from."""
    for name, tissue in colours.PRESETS.items():
        click.echo(f"{name:17} {str(tissue.window) + ' HU':16} rgb {','.join(map(str, tissue.colour)):12} "
                   f"{tissue.source}")
