"""``voxrender lines``: the discrete 3-D lines of Cohen-Or and Kaufman, their tables reproduced by experiment."""

from __future__ import annotations

import click

from ..errors import InputError
from ..space import lines
from ._main import main


@main.command("lines")
@click.option("--table", is_flag=True, help="Reproduce the paper's Tables 1 and 2 by experiment.")
@click.option("--trials", default=100_000, show_default=True, type=click.IntRange(100, 10_000_000),
              help="Random pairs of end points.")
@click.option("--seed", default=0, show_default=True, type=int)
@click.option("--side", default=100, show_default=True, type=click.IntRange(2, 100_000),
              help="Side of the voxel space.")
def lines_command(table, trials, seed, side):
    """Discrete 3-D lines: average d6, d18, d26 of random lines and their ratios (Cohen-Or and Kaufman)."""
    if not table:
        raise InputError("say what to compute: voxrender lines --table")
    result = lines.metrics_table(trials, seed, side)
    analytical = result["analytical_length"]
    click.echo(f"{result['trials']} random lines in a {side}^3 voxel space (seed {seed})")
    click.echo("")
    click.echo("Table 2: average length   experimental   analytical")
    for name in ("d6", "d18", "d26"):
        expected = analytical.get(name)
        click.echo(f"  {name:<24}{result['mean_length'][name]:>12.2f}   " +
                   (f"{expected:>10.2f}" if expected is not None else f"{'':>10}"))
    click.echo("")
    click.echo("Table 1: ratio            mean ratio   ratio of means   analytical   difference")
    for (a, b), expected in result["analytical_ratio"].items():
        mean_ratio = result["mean_ratio"][(a, b)]
        mark = "*" if (a, b) in lines.TABLE1_PRINTED else " "
        click.echo(f"  {a + '/' + b:<22}{mean_ratio:>12.3f}   {result['ratio_of_means'][(a, b)]:>14.3f}   "
                   f"{expected:>10.3f}{mark}  {mean_ratio - expected:>+10.3f}")
    click.echo("")
    click.echo("Table 1's analytical row is the mean of each ratio; the ratio of the means is its experimental row.")
    for (a, b), printed in lines.TABLE1_PRINTED.items():
        click.echo(f"* the paper prints {printed} for {a}/{b}; read as a swap of the digits of "
                   f"{lines.TABLE1_ANALYTICAL[(a, b)]}, the mean of {a}/{b}")
