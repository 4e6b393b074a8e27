"""``voxrender slices``, ``sheet`` and ``agreement``: the pictures a reviewer checks a study by."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import click
import numpy as np

from ..batch import parse, spec
from ..errors import InputError
from ..object import prep
from ..object.pipeline import Encoded, PrepOptions, load_segments
from ..outputs import Composite, Outputs, output, write_outputs
from ..pictures import colours, label_table
from ..qc.sheet import render_sheet, sheet
from ..space.view import PRESETS
from ._main import flag, main, progress
from ._options import (
    check_output_paths,
    check_vxs_options,
    check_window,
    dicom_study_of,
    input_flags,
    output_paths_of,
    prep_flags,
    prep_options_of,
    read_flags,
    read_options_of,
    render_flags,
    render_options_of,
    slice_flags,
    slice_options_of,
    window_flag,
)


@main.command("slices")
@input_flags
@click.option("--labels", is_flag=True, help="INPUT is a label map: its labels drawn alone, each in its colour.")
@click.option("--label", metavar="N[,M...]", help="Only these labels of the label map.")
@click.option("--labels-from", type=click.Path(path_type=Path), metavar="MAP",
              help="The labels of INPUT: a label map, a folder of masks, a DICOM SEG or RTSTRUCT, placed by position.")
@click.option("--crop", metavar="X0:X1,Y0:Y1,Z0:Z1", help="Subregion in input voxel indices.")
@click.option("-o", "--output", "output_path", required=True, type=click.Path(path_type=Path), help="PNG to write.")
@slice_flags
@window_flag
@click.option("--size", default="512", show_default=True, metavar="N|WxH", help="Each slice's picture, in pixels.")
@click.option("--colours", "--colors", "colour_table", type=click.Path(path_type=Path), metavar="FILE",
              help="Names and colours of labels (as for render).")
@click.option("--legend", is_flag=True, help="Name the labels each slice shows.")
@click.option("--dicom-out", "dicom", type=click.Path(path_type=Path), metavar="FILE.dcm",
              help="Also save the picture as an RGB DICOM Secondary Capture in a new series of the source study.")
@click.option("--dicom-study-from", type=click.Path(path_type=Path), metavar="DICOM_DIR",
              help="With --dicom-out: the DICOM series whose study the picture joins (default: INPUT's).")
@click.option("--reference", type=click.Path(path_type=Path), metavar="REF",
              help="A reference segmentation the labels are held to: the slices show both / labels only / "
                   "reference only, and the agreement's table follows.")
@click.option("--tolerance-mm", default=2.0, show_default=True, type=click.FloatRange(0),
              help="With --reference: the normalised surface Dice's tolerance.")
def slices_command(input_path, output_path, size, colour_table, legend, dicom, reference, tolerance_mm, **options):
    """Draw axial, coronal and sagittal slices of INPUT with its labels over them, side by side, to a PNG.

    The slices cross at the volume centre, a point, or each label (a row per label); each is shown at its true
    aspect, radiologically (the patient's left on the right), with orientation letters and a scale bar in mm.
    """
    from ..qc.qc import slice_pictures
    from ..qc.study import load_study

    check_vxs_options(input_path, options)
    check_output_paths({"picture": output_path, "dicom": dicom})
    joins = dicom_study_of(input_path, options, dicom)
    chosen = parse.labels(options["label"]) if options["label"] else None
    labelled = options["labels"] or options["label"] or options["labels_from"]
    selection = prep.LabelSelection(chosen, True, options["labels_from"]) if labelled else None
    crop = parse.crop(options["crop"]) if options["crop"] else None
    slice_options = replace(slice_options_of(options, planes=("axial", "coronal", "sagittal"), legend=legend),
                            size=parse.size(size))
    table = colours.read_colour_table(colour_table) if colour_table else None
    metrics = None
    if reference is not None:
        study, metrics = _agreement_study(input_path, options, reference, crop, tolerance_mm)
    else:
        study = load_study(input_path, read_options_of(options), PrepOptions(None, crop, labels=selection), progress,
                           encode=False)
    rows = slice_pictures(study, slice_options, table)
    picture_rgb = sheet([[rgb for _, rgb in row] for row in rows], [[caption for caption, _ in row] for row in rows])
    if metrics is not None:
        picture_rgb = _with_metrics(picture_rgb, metrics)
    shows = f"slices {', '.join(slice_options.planes)}" + (
        f" with the labels of {options['labels_from'].name}" if options["labels_from"] else "")
    write_outputs(Composite(picture_rgb, shows), Outputs(output_path, dicom=dicom), joins)
    click.echo(f"{output_path}: {len(rows)} row{'s' * (len(rows) > 1)} of {', '.join(slice_options.planes)}")


@main.command("agreement")
@input_flags
@click.option("--labels-from", required=True, type=click.Path(path_type=Path), metavar="TEST",
              help="The segmentation to judge: a label map, a folder of masks, a DICOM SEG or RTSTRUCT of INPUT.")
@click.option("--reference", required=True, type=click.Path(path_type=Path), metavar="REF",
              help="The segmentation it is held to, of any of those kinds; each is placed on INPUT by position.")
@click.option("-o", "--output", "output_path", required=True, type=click.Path(path_type=Path),
              help="PNG to write: the worst structures' slices, both / test only / reference only, and the table.")
@click.option("--metrics-out", type=click.Path(path_type=Path), metavar="FILE.csv",
              help="Also the metrics, a structure a row: Dice, NSD, HD95, ASSD, volumes, pieces.")
@click.option("--tolerance-mm", default=2.0, show_default=True, type=click.FloatRange(0),
              help="The normalised surface Dice's tolerance.")
@click.option("--size", default="256", show_default=True, metavar="N|WxH", help="Each slice's picture, in pixels.")
@click.option("--worst", default=4, show_default=True, type=click.IntRange(1), metavar="N",
              help="How many structures, the worst first, the picture shows slices of.")
def agreement_command(input_path, labels_from, reference, output_path, metrics_out, tolerance_mm, size, worst,
                      **options):
    """Measure how the segmentation --labels-from agrees with --reference on INPUT, a structure at a time.

    Structures are matched by name (case, spaces, hyphens and underscores aside; 'hip right' is 'hip_right'),
    unnamed ones by number. Per structure: Dice, the normalised surface Dice at --tolerance-mm, HD95 and ASSD in mm
    (surface elements weighted by area, as DeepMind's surface-distance), both volumes and their difference, and
    the pieces of each. A structure on one side only is listed with Dice 0.
    """
    from ..review.agreement import Comparison, write_metrics

    check_output_paths({"picture": output_path, "metrics_out": metrics_out})
    comparison = Comparison(input_path, labels_from, reference, read_options_of(options))
    rows = comparison.metrics(tolerance_mm)
    picture_rgb = comparison.picture(rows, parse.size(size), worst)
    if metrics_out is not None:
        write_metrics(metrics_out, rows)
    output.write_png(output_path, picture_rgb)
    one_sided = [row["name"] for row in rows if row["present"] != "both"]
    if one_sided:
        sides = [", ".join(sorted(s[1] for s in side.values())) or "none" for side in comparison.structures]
        click.echo(f"warning: {len(one_sided)} structure{'s' * (len(one_sided) > 1)} on one side only "
                   f"({', '.join(one_sided[:6])}{' ...' if len(one_sided) > 6 else ''}); the test holds "
                   f"{sides[0]}; the reference holds {sides[1]}", err=True)
    worst_row = rows[0]
    click.echo(f"{output_path}: {len(rows)} structures; the worst, {worst_row['name']}, has Dice "
               f"{worst_row['dice']:.3f}" + (f"; metrics in {metrics_out}" if metrics_out else ""))


def _agreement_study(input_path, options, reference, crop, tolerance_mm):
    """The study whose labels are the agreement of --labels-from with ``reference`` (both / labels only /
    reference only), and the agreement's records.
    """
    from ..qc.study import Study
    from ..review.agreement import CLASSES, Comparison

    if not options.get("labels_from"):
        raise InputError("a reference is held against labels: give them with --labels-from", parameter="reference")
    if crop is not None:
        raise InputError("the agreement is measured on the whole image: drop --crop", parameter="crop")
    comparison = Comparison(input_path, options["labels_from"], reference, read_options_of(options))
    table = {str(k): {"name": name, "colour": list(colour)} for k, (name, colour) in CLASSES.items()}
    return Study(comparison.volume, comparison.classes(), table), comparison.metrics(tolerance_mm)


def _with_metrics(rgb, rows):
    """``rgb`` with the agreement's table under it, both as wide as the wider."""
    from ..review.agreement import metrics_picture

    table = metrics_picture(rows, rgb.shape[1])
    width = max(rgb.shape[1], table.shape[1])
    return np.concatenate([np.pad(part, ((0, 0), (0, width - part.shape[1]), (0, 0))) for part in (rgb, table)])


@main.command("sheet")
@click.argument("inputs", nargs=-1, required=True, type=click.Path(path_type=Path), metavar="INPUT...")
@read_flags
@prep_flags
@click.option("-o", "--output", "output_path", required=True, type=click.Path(path_type=Path), help="PNG to write.")
@click.option("--view", "views", multiple=True, type=click.Choice(list(PRESETS)), help="A named view (repeatable).")
@click.option("--views", "view_list", metavar="NAME[,NAME...]", help="Named views, separated by commas.")
@click.option("--angles", multiple=True, metavar="A,B,G", help="alpha,beta,gamma in degrees (repeatable).")
@click.option("--methods", metavar="M1,M2,...", help="Rows of methods (one input): compare the algorithms.")
@click.option("--per-label", is_flag=True, help="Rows of labels (one input with labels): all, then each alone.")
@slice_flags
@render_flags
@click.option("--reference", type=click.Path(path_type=Path), metavar="REF",
              help="With a QC sheet: a reference segmentation the labels are held to; its table follows.")
@click.option("--tolerance-mm", default=2.0, show_default=True, type=click.FloatRange(0),
              help="With --reference: the normalised surface Dice's tolerance.")
def sheet_command(inputs, output_path, views, view_list, angles, methods, per_label, reference, tolerance_mm,
                  **options):
    """Lay out pictures in a grid: one input's views x methods (--methods) or x labels (--per-label), or several
    inputs' views; with --slices or --projection, one study's QC sheet: its surfaces, projections and slices with
    the labels over them, captioned, and a table of its labels (name, colour, voxels, mL).
    """
    given = [flag(name) for name in output_paths_of(options) if name != "dicom"]   # a sheet writes the picture alone
    if given:
        raise InputError(f"a sheet is one picture: {', '.join(given)} cannot apply; use render or batch")
    dicom = options.get("dicom")
    check_output_paths({"picture": output_path, "dicom": dicom})
    names = [*views, *(parse.planes(view_list) if view_list else ())]
    chosen = spec.parse_views(names, [parse.vector(a, "angles") for a in angles])
    columns = [(v.label, (v.alpha, v.beta, v.gamma)) for v in chosen]
    render_options = render_options_of(options)
    read, prepare = read_options_of(options), prep_options_of(options)
    slice_options = slice_options_of(options)
    check_window(render_options, slice_options)
    if methods and per_label:
        raise InputError("give --methods or --per-label, not both: a sheet has one kind of row")
    if (methods or per_label) and len(inputs) > 1:
        raise InputError(f"give one input for {'--methods' if methods else '--per-label'}, or several without it")
    if reference is not None and slice_options is None and not render_options.drawn.grey_values:
        raise InputError("a reference's table goes on a QC sheet: give --slices or --projection too",
                         parameter="reference")
    if slice_options is not None or render_options.drawn.grey_values:
        if methods or per_label or len(inputs) > 1:
            raise InputError("a QC sheet (--slices, --projection) is of one study: give one input, without "
                             "--methods or --per-label; 'voxrender batch --sheet' makes one per study")
        from ..qc.qc import qc_sheet
        from ..qc.study import load_study

        joins = dicom_study_of(inputs[0], options, dicom)
        study = load_study(inputs[0], read, prepare, progress)
        rgb = qc_sheet(study, render_options, columns, slice_options, title=str(inputs[0]), progress=progress)
        if reference is not None:
            from ..review.agreement import Comparison

            rgb = _with_metrics(rgb, Comparison.of_study(study, reference, read).metrics(tolerance_mm))
        from ..outputs.secondary_capture import selection_words

        shows = [f"QC sheet of {', '.join(v.label for v in chosen)}"]
        if render_options.drawn.grey_values:
            shows.append(render_options.drawn.name)
        if slice_options:
            shows.append(f"slices {', '.join(slice_options.planes)}")
        shows += selection_words(study.encoded.segments.meta)
        write_outputs(Composite(rgb, ", ".join(shows)), Outputs(output_path, dicom=dicom), joins)
        click.echo(f"{output_path}: the QC sheet of {inputs[0]}")
        return
    if dicom is not None:
        raise InputError("a DICOM picture is made of one study: give --slices or --projection for its QC sheet, or "
                         "use render", parameter="dicom")
    if methods:
        loaded = load_segments(inputs[0], read, prepare, progress)
        rows = [(name, loaded, replace(render_options, method=name, method_options={}))
                for name in (m.strip() for m in methods.split(",")) if name]
    elif per_label:
        loaded = load_segments(inputs[0], read, prepare, progress)
        if loaded.segments.labels is None:
            raise InputError("needs an object with labels: a label map with --labels, or a CT with --labels-from",
                             parameter="per_label")
        table = label_table(loaded.segments, render_options.colours)
        alone = replace(render_options, legend=False)
        rows = [("all labels", loaded, render_options)] + [
            (name, Encoded(loaded.segments.only(label)), replace(alone, colour=tuple(c / 255 for c in rgb)))
            for label, (name, rgb) in table.items()]
    else:
        rows = [(path.stem or path.name, load_segments(path, read, prepare, progress), render_options)
                for path in inputs]
    output.write_png(output_path, render_sheet(rows, columns, progress))
    click.echo(f"{output_path}: {len(rows)} rows x {len(columns)} views")
