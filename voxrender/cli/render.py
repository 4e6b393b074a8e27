"""``voxrender render``: one picture of an input."""

from __future__ import annotations

from pathlib import Path

import click

from .._render import octree_for
from ..batch import parse
from ..object.pipeline import is_segments_file, level_for_picture, load_segments
from ..outputs import Outputs, about, write_outputs
from ..outputs.output_kinds import LABEL_ROWS, LABELS, OUTPUTS
from ..pictures import level_for, picture
from ..space.view import PRESETS
from ._main import main, progress
from ._options import (
    check_label_options,
    check_output_paths,
    check_vxs_options,
    check_window,
    dicom_study_of,
    input_flags,
    max_memory_flag,
    output_paths_of,
    prep_flags,
    prep_options_of,
    read_options_of,
    render_flags,
    render_options_of,
    view_of,
)


@main.command("render")
@input_flags
@prep_flags
@click.option("-o", "--output", "output_path", required=True, type=click.Path(path_type=Path), help="PNG to write.")
@click.option("--view", type=click.Choice(list(PRESETS)), help="A named view (DICOM axial stacks).")
@click.option("--alpha", type=float, help="Rotation about X1 in degrees.")
@click.option("--beta", type=float, help="Rotation about Y1 in degrees.")
@click.option("--gamma", type=float, help="Rotation about Z1 (the view axis) in degrees.")
@click.option("--vpn", metavar="I,J,K", help="View plane normal (object x,y,z toward the viewer).")
@render_flags
@max_memory_flag
def render_command(input_path, output_path, **options):
    """Render INPUT (a slice folder, volume file, label map or .vxs) to a shaded PNG."""
    check_vxs_options(input_path, options)
    angles = view_of(options)
    render_options = render_options_of(options)
    check_window(render_options)
    outputs = Outputs(output_path, **output_paths_of(options))
    outputs.check(render_options)
    check_output_paths(outputs.wanted())
    joins = dicom_study_of(input_path, options, outputs.dicom)         # a non-DICOM input is refused before reading
    read, note = level_for_picture(input_path, read_options_of(options), max(render_options.size))
    if note:
        click.echo(f"note: {note}", err=True)
    study = None
    if render_options.drawn.grey_values:
        from ..qc.study import load_study

        # a projection is framed by the object, and draws no surface: no normals
        study = load_study(input_path, read, prep_options_of(options), progress, normals=False)
        loaded = study.encoded
    else:
        loaded = load_segments(input_path, read, prep_options_of(options), progress)
    view, drawn_from = render_options.view(*angles), None
    if loaded.segments.levels:         # a .vxs with levels of detail: --level, or the one that suits the picture
        level, view = level_for(loaded.segments, view, render_options, read.level)
        if level:
            drawn = loaded.segments.at_level(level)
            drawn_from = (f"note: drawn from level {level} of {input_path}: voxels {drawn.meta['level_factor']} "
                          f"times larger, {'x'.join(map(str, drawn.shape[::-1]))}" +
                          ("" if read.level is not None else ", the coarsest no larger than a pixel"))
        loaded = loaded.at_level(level)
    elif read.level and is_segments_file(input_path):
        loaded.segments.at_level(read.level)               # refused: the file keeps no levels
    check_label_options(loaded.segments, {"colours": options["colours"], "legend": options["legend"],
                                           **{name: path for name, path in outputs.wanted().items()
                                              if OUTPUTS[name].needs in (LABELS, LABEL_ROWS)}})
    max_memory = parse.memory(options["max_memory"]) if options["max_memory"] else None
    result = picture(loaded.segments, view, render_options, progress,
                     octree_for(render_options.method, loaded, max_memory), study=study)
    result.seconds = {**loaded.seconds, **result.seconds}
    write_outputs(result, outputs, {**about(loaded.segments), **joins})   # an empty picture was warned of
    if drawn_from:                                          # once drawn: bad input stays one line
        click.echo(drawn_from, err=True)
