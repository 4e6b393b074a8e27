"""The ``voxrender`` command line: it parses, calls the library and reports.

Bad input ends with one line on stderr and exit status 2; a bug in voxrender
ends with one line and exit status 1 (``VOXRENDER_DEBUG=1`` shows the traceback).
"""

from __future__ import annotations

import json
import os
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

import click
import numpy as np

from .. import __version__, io, samples
from .._render import DEFAULT_METHOD, METHODS, Clip
from .._render.raycast import CONNECTIVITIES
from .._shared.files import check_writable
from ..batch import parse
from ..batch import run as batch
from ..errors import InputError
from ..object import prep, segments
from ..object.pipeline import (
    AUTO,
    Encoded,
    PrepOptions,
    ReadOptions,
    is_segments_file,
    level_for_picture,
    load_segments,
    machine_memory,
)
from ..outputs import output
from ..outputs.output_kinds import LABEL_ROWS, LABELS, OUTPUTS
from ..pictures import colours, compare
from ..pictures._picture import PROJECTIONS, Outputs, RenderOptions, about, label_table, picture, write_outputs
from ..pictures.shade import HEADLIGHT, SHADINGS
from ..qc.sheet import render_sheet, sheet
from ..qc.slices import OVERLAYS
from ..space import lines, orient
from ..space.grids import patient_affine
from ..space.view import PRESETS, angles_from_vpn


def progress(iterable, length=None, label=None):
    """A click progress bar on stderr when it is a terminal; the bare iterable otherwise.  Items that are byte
    counts (a streamed encode's slabs) show as MB read, MB/s and the time left.
    """
    if not sys.stderr.isatty():
        return iterable
    stream = sys.modules.get("voxrender.object.stream")          # imported by the commands that stream, and only then
    if stream and isinstance(iterable, stream.ByteCounts):
        return _byte_bar(iterable, length, label)
    return _bar(iterable, length, label)


def _byte_bar(counts, length, label):
    started, done = time.perf_counter(), 0

    def rate(_):
        seconds = max(time.perf_counter() - started, 1e-6)
        return f"{done / 1e6:,.0f} of {length / 1e6:,.0f} MB, {done / 1e6 / seconds:,.0f} MB/s"

    with click.progressbar(length=length, label=label, file=sys.stderr, item_show_func=rate, show_eta=True,
                           show_percent=True) as bar:
        for count in counts:
            yield count
            done += count
            bar.update(count, count)


def _bar(iterable, length, label):
    with click.progressbar(iterable, length=length, label=label, file=sys.stderr) as bar:
        yield from bar


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    """A warning as one line, each once a command: a file read twice (``info`` reads it, then opens it as a stream)
    says what it says once.
    """
    if str(message) not in _WARNED:
        _WARNED.add(str(message))
        click.echo(f"warning: {message}", err=True)


_WARNED = set()


# ---------------------------------------------------------------- flags and their parsers

# Library parameters whose flag is not "--" + the name with dashes; the outputs' flags are in their records.
FLAGS = {"picture": "--pattern", "inputs": "INPUT", "compare": "--compare-rays", "views": "the manifest's views",
         "planes": "--slices",
         **{name: f"--{kind.flag}" for name, kind in OUTPUTS.items() if kind.flag}}


def _placed(error, args):
    """The error's line: led by the flag at fault when the user gave that flag; when not, the flag that is the
    fix follows the message (a 4-D file asks for ``--frame``), so that no line blames a flag nobody gave.

    >>> _placed(InputError("choose a frame", parameter="frame"), ["in.nii"])
    'choose a frame (--frame)'
    >>> _placed(InputError("must be positive", parameter="scale"), ["in.nii", "--scale=-1"])
    '--scale: must be positive'
    """
    if not error.parameter:
        return error.message
    name = flag(error.parameter)
    if not name.startswith("-") or any(arg == name or arg.startswith(name + "=") for arg in args):
        return f"{name}: {error.message}"
    return f"{error.message} ({name})"


def flag(parameter):
    """The command-line flag of a library parameter.

    >>> flag("cut_depth"), flag("depth")
    ('--cut-depth', '--depth-out')
    """
    return FLAGS.get(parameter, "--" + parameter.replace("_", "-"))


def _view_from(options):
    angles_given = any(options[k] is not None for k in ("alpha", "beta", "gamma"))
    chosen = [name for name, given in (("--view", options["view"]), ("--vpn", options["vpn"]),
                                       ("--alpha/--beta/--gamma", angles_given)) if given]
    if len(chosen) > 1:
        raise InputError(f"give one of {' and '.join(chosen)}, not both")
    if options["view"]:
        return PRESETS[options["view"]]
    if options["vpn"]:
        return angles_from_vpn(parse.vector(options["vpn"], "vpn"))
    return tuple(options[k] or 0.0 for k in ("alpha", "beta", "gamma"))


def _read_options(options):
    spacing = io.check_spacing(parse.vector(options["spacing"], "spacing")) if options["spacing"] else None
    raw = parse.raw_layout(options["raw"]) if options["raw"] else None
    if options["orientation"] is not None:
        orient.direction_of(options["orientation"])          # a bad code is an error before anything is read
    return ReadOptions(options["format"], raw, spacing, options["series"], options["frame"], options["orientation"],
                       options["reorient"], options["level"], options["run"])


def _prep_options(options):
    labels = None
    if options["labels"] or options["label"] or options["labels_from"]:
        chosen = parse.labels(options["label"]) if options["label"] else None
        labels = prep.LabelSelection(chosen, bool(options["labels"] or options["labels_from"] and not chosen),
                                     options["labels_from"], envelopes=options["with_body"])
    tissues = parse.presets(options["preset"]) if options["preset"] else []
    if tissues and options["threshold"] is not None:
        raise InputError("give --preset or --threshold, not both (a preset is a window and a colour)",
                         parameter="preset")
    if len(tissues) > 1 and labels:
        raise InputError("give several presets or labels, not both: the presets are the labels", parameter="preset")
    if len(tissues) == 1:
        threshold = tissues[0][1].window
    elif options["threshold"] is not None:
        threshold = parse.threshold(options["threshold"])
    else:
        threshold = AUTO                                   # PrepOptions decides: Otsu's, or none with labels
    several = tuple((name, tissue.window, tissue.colour) for name, tissue in tissues) if len(tissues) > 1 else ()
    crop = parse.crop(options["crop"]) if options["crop"] else None
    return PrepOptions(threshold, crop, options["voxel"], options["resample"], options["min_object"], labels, several,
                       options["bin"])


def _render_options(options):
    """The :class:`RenderOptions` of the flags that both ``render`` and ``batch`` declare."""
    clip = Clip(*(parse.clip_range(options[f"clip_{axis}"], f"clip_{axis}") if options[f"clip_{axis}"] else None
                  for axis in "xyz"), options["cut_depth"])
    method_options = {"connectivity": options["connectivity"]} if options["connectivity"] else {}
    if options["compare_rays"]:
        method_options["compare"] = True
    tissues = parse.presets(options["preset"]) if options.get("preset") else []
    colour = parse.colour(options["colour"], "colour") if options["colour"] else \
        tissues[0][1].colour if len(tissues) == 1 else (255, 255, 255)
    table = colours.read_colour_table(options["colours"]) if options["colours"] else None
    return RenderOptions(options["method"], method_options, clip if clip.active else None, options["fit"],
                         parse.size(options["size"]), options["scale"], options["supersample"], options["shading"],
                         parse.vector(options["light"], "light"), tuple(c / 255 for c in colour), table,
                         options["legend"], background=parse.colour(options["background"]), ao=options["ao"],
                         orientation_marks=options["orientation_marks"], projection=options["projection"],
                         window=parse.window(options["window"]) if options["window"] else None, slab=options["slab"])


def _output_paths(options):
    """``{name: path}`` of the outputs whose flags are given (the picture's own flag aside), by ``OUTPUTS``."""
    return {name: options[name] for name in OUTPUTS if options.get(name) is not None}


def _max_memory_option(command):
    what = ("a stack larger is read a slab at a time (streamed), and an octree build that would need more is "
            "refused" if command.__name__ == "encode_command" else "an octree build that would need more is refused")
    return click.option("--max-memory", metavar="SIZE",
                        help=f"Memory to stay within, e.g. 8G (default: half the machine's): {what}.")(command)


def _check_vxs_options(path, options):
    """A .vxs file is already thresholded: refuse options that would silently do nothing."""
    if not is_segments_file(path):
        return
    given = [flag(name) for name in ("threshold", "preset", "label", "labels", "labels_from", "crop", "voxel", "raw",
                                     "spacing", "series", "frame", "level", "orientation")
             if options.get(name) not in (None, False)] + ["--bin"] * (options.get("bin", 1) != 1)
    if given:
        raise InputError(f"{path} is already encoded, so {', '.join(given)} cannot apply; "
                         "give the slice stack instead")


def _check_label_options(s, options):
    """Options for labels (``{name: value}``) given with a single object would silently do nothing: refuse them."""
    if s.labels is None:
        given = [flag(name) for name, value in options.items() if value]
        if given:
            raise InputError(f"{', '.join(given)} apply to labels, but the object is a single one; show a label map's "
                             "labels by --labels, or a CT's by --labels-from")


# ---------------------------------------------------------------- shared options

def _decorate(command, decorators):
    for decorator in reversed(decorators):
        command = decorator(command)
    return command


def _input_options(command):
    return _decorate(command, [click.argument("input_path", metavar="INPUT", type=click.Path(path_type=Path)),
                               _read_options_decorator])


def _read_options_decorator(command):
    return _decorate(command, [
        click.option("--format", "format", default="auto", show_default=True,
                     type=click.Choice(io.FORMATS), help="Input format (auto-detected)."),
        click.option("--raw", metavar="WxH:DTYPE:ENDIAN", help="Headerless slices, e.g. 64x64:uint16:little."),
        click.option("--spacing", metavar="X,Y,Z", help="Voxel spacing in mm; overrides the files."),
        click.option("--series", metavar="UID", help="DICOM SeriesInstanceUID, when a folder holds several."),
        click.option("--run", type=click.IntRange(1), metavar="N",
                     help="Of a DICOM series with uneven slice steps, the regular run to read, from 1 in slice "
                          "order (default: the longest)."),
        click.option("--frame", type=int, metavar="N", help="The volume to read from a 4-D NIfTI or NRRD (from 0)."),
        click.option("--level", type=click.IntRange(0), metavar="N",
                     help="The level of a multiscale OME-Zarr, 0 the finest (default: for render, the finest that "
                          "suits the picture; else the finest)."),
        click.option("--orientation", metavar="CODE",
                     help="Orientation of an input whose header has none, e.g. RAS or LPI: the sides voxel x, y and "
                          "z grow toward."),
        click.option("--reorient/--no-reorient", default=True, show_default=True,
                     help="Bring the volume to the patient frame the view presets assume (flips and permutations "
                          "only), or keep the stored order."),
    ])


def _prep_options_decorator(command):
    return _decorate(command, [
        click.option("--threshold", metavar="VALUE|LO:HI|otsu",
                     help="Object is value >= VALUE, or LO <= value <= HI (stored units, HU for CT; a side may be "
                          "left out); default: otsu."),
        click.option("--preset", metavar="NAME[,NAME...]",
                     help="A CT tissue: its HU window and colour (bone, skin, soft-tissue, contrast-vessels, lung; "
                          "'voxrender presets' lists them); several make one object, each tissue a label "
                          "(skin,bone: bone wins where both hold)."),
        click.option("--labels", is_flag=True,
                     help="INPUT is a label map: every non-zero label (or those of --label) an object in its own "
                          "colour."),
        click.option("--label", metavar="N[,M...]",
                     help="Render these labels of a label map as one object (with --labels: each in its colour)."),
        click.option("--labels-from", type=click.Path(path_type=Path), metavar="FILE",
                     help="A label map of INPUT (same grid): show its labels; --threshold/--preset then also select "
                          "INPUT's values."),
        click.option("--with-body", is_flag=True,
                     help="Draw the surface of the patient's outline too (an RTSTRUCT ROI of type EXTERNAL, or a "
                          "structure named BODY or External), which is left out by default: it hides the rest."),
        click.option("--crop", metavar="X0:X1,Y0:Y1,Z0:Z1", help="Subregion in input voxel indices."),
        click.option("--resample/--no-resample", default=True, show_default=True,
                     help="Resample to cubic voxels from the spacing."),
        click.option("--voxel", type=float, metavar="MM", help="Cubic voxel size (default: smallest spacing)."),
        click.option("--min-object", type=int, default=0, metavar="N", help="Drop connected specks under N voxels."),
        click.option("--bin", type=click.IntRange(1, 64), default=1, show_default=True, metavar="N",
                     help="Mean of every N x N x N voxels (after --crop), for a preview of a huge stack: 2048^3 "
                          "becomes 1024^3 with --bin 2; the spacing grows N times."),
    ])


def _render_options_decorator(command):
    """The options of the picture step, declared once for ``render`` and ``batch``."""
    return _decorate(command, [
        click.option("--method", default=DEFAULT_METHOD, show_default=True, type=click.Choice(sorted(METHODS)),
                     help="Rendering algorithm."),
        click.option("--connectivity", type=click.Choice(CONNECTIVITIES),
                     help="Discrete rays of --method raycast: 6, 26, or 26 switching to 6 near the object "
                          "(default adaptive)."),
        click.option("--compare-rays", is_flag=True,
                     help="With --method raycast: also cast 6-rays and count the late hits, leaks and misses "
                          "(--stats-json); costs a second pass."),
        click.option("--size", default="512", show_default=True, metavar="N|WxH", help="Image size in pixels."),
        click.option("--scale", type=float, help="Pixels per voxel (default: see --fit)."),
        click.option("--fit", type=click.Choice(["object", "volume"]), default="object", show_default=True,
                     help="Without --scale: frame the object as this view sees it, or the whole volume at any "
                          "rotation (a batch of several views: one scale for all)."),
        click.option("--clip-x", metavar="A:B", help="Keep voxels with A <= x < B (object space, after resampling)."),
        click.option("--clip-y", metavar="A:B", help="Keep voxels with A <= y < B."),
        click.option("--clip-z", metavar="A:B", help="Keep voxels with A <= z < B."),
        click.option("--cut-depth", type=float, metavar="D",
                     help="Cutaway: ignore voxels nearer than Z' = D (voxels; 0 is the volume centre)."),
        click.option("--supersample", default=2, show_default=True, type=click.IntRange(1, 8),
                     help="Pre-image supersampling for methods that apply gamma by rotating the picture."),
        click.option("--shading", default="gradient", show_default=True, type=click.Choice(list(SHADINGS)),
                     help="gradient: lit grey-level gradient normals; depth-gradient: the paper's shading; depth."),
        click.option("--light", default=",".join(f"{v:g}" for v in HEADLIGHT), show_default=True, metavar="X,Y,Z",
                     help="Direction toward the light in image space (X right, Y down, Z away)."),
        click.option("--colour", "--color", "colour", metavar="NAME|#RRGGBB",
                     help="Colour of a single object (default white, or the preset's)."),
        click.option("--colours", "--colors", "colours", type=click.Path(path_type=Path), metavar="FILE",
                     help="Names and colours of labels: CSV or JSON (label, name, r, g, b), Slicer .ctbl, or an "
                          "ITK-SNAP label description (.txt)."),
        click.option("--legend", is_flag=True, help="Draw the names and colours of the labels the picture shows "
                     "(beside it when they would cover much of it)."),
        click.option("--background", default="black", show_default=True, metavar="NAME|GREY|R,G,B|#RRGGBB"),
        click.option("--ao", is_flag=True, help="Darken creases and pits (screen-space ambient occlusion)."),
        click.option("--orientation-marks", is_flag=True,
                     help="Write the patient directions (L/R, A/P, S/I) at the picture's edges."),
        click.option("--projection", type=click.Choice(PROJECTIONS),
                     help="Draw the maximum (mip), minimum (minip) or mean of the grey values along each ray, "
                          "framed as the surface would be, instead of the surface."),
        click.option("--slab", type=float, metavar="MM",
                     help="With --projection: only a slab this thick, around the volume centre or the cut plane."),
        _window_option,
        click.option("--dicom-study-from", type=click.Path(path_type=Path), metavar="DICOM_DIR",
                     help="With --dicom-out: the DICOM series whose study the picture joins (default: INPUT's)."),
        _output_options_decorator,
    ])


_window_option = click.option(
    "--window", metavar="LEVEL/WIDTH|NAME",
    help="Grey values' window of slices and projections: e.g. 40/400, or brain, soft-tissue, bone, lung (default: "
         "slices of a CT soft-tissue; else the 1st to 99th percentile of the values, of a projection along y for "
         "projections).")


def _slice_options_decorator(command):
    """The options of the slices, declared once for ``slices``, ``sheet`` and ``batch``."""
    return _decorate(command, [
        click.option("--slices", "planes", metavar="PLANE[,PLANE...]",
                     help="Slices to draw: axial, coronal, sagittal (radiological: the patient's left on the "
                          "right), at their true aspect."),
        click.option("--at", metavar="centre|X,Y,Z|X,Y,Zvox|labels|labels:largest",
                     help="Where the slices cross: the volume centre, a point in patient mm (LPS) or in voxels, or "
                          "through each label's centroid (labels) or largest cross-section."),
        click.option("--overlay", type=click.Choice([*OVERLAYS, "none"]),
                     help="Labels over the slices: filled, outlined (one pixel wide) or both [default: fill, when "
                          "there are labels]."),
        click.option("--opacity", type=float, default=0.4, show_default=True, help="Of the filled labels, 0 to 1."),
    ])


def _slice_options(options, planes=None, legend=False):
    """The :class:`~voxrender.qc.qc.SliceOptions` of the slice flags, or ``None`` when no planes are asked for."""
    from ..qc.qc import SliceOptions

    planes = parse.planes(options["planes"]) if options.get("planes") else planes
    if planes is None:
        given = [flag(name) for name in ("at", "overlay") if options.get(name)]
        if given:
            raise InputError(f"{', '.join(given)} apply to slices; give --slices axial,coronal,sagittal too")
        return None
    overlay = options.get("overlay") or "auto"
    return SliceOptions(planes, parse.slice_point(options["at"]) if options.get("at") else None,
                        parse.window(options["window"]) if options.get("window") else None,
                        None if overlay == "none" else overlay, options["opacity"], legend=legend)


def _output_options_decorator(command):
    """A flag per output of ``OUTPUTS`` besides the picture (which each command names itself), its parameter the
    output's name: a file in ``render``, a pattern in ``batch``, refused by ``sheet``.
    """
    return _decorate(command, [
        click.option(f"--{kind.flag}", name, type=click.Path(path_type=Path), metavar=f"FILE{kind.suffix}",
                     help=kind.help)
        for name, kind in OUTPUTS.items() if kind.flag])


# ---------------------------------------------------------------- commands

class _Group(click.Group):
    def main(self, args=None, prog_name=None, **extra):
        warnings.showwarning = _one_line_warning
        _WARNED.clear()
        try:
            return super().main(args, prog_name, standalone_mode=False, **extra)
        except click.exceptions.Exit as done:
            sys.exit(done.exit_code)
        except click.exceptions.Abort:
            click.echo("aborted", err=True)
            sys.exit(130)
        except click.ClickException as exc:
            hint = f" (see '{exc.ctx.command_path} --help')" if getattr(exc, "ctx", None) else ""
            click.echo(f"error: {exc.format_message()}{hint}", err=True)
            sys.exit(2)
        except InputError as exc:
            click.echo(f"error: {_placed(exc, sys.argv[1:] if args is None else args)}", err=True)
            sys.exit(2)
        except KeyboardInterrupt:
            click.echo("interrupted", err=True)
            sys.exit(130)
        except MemoryError:  # sizes are checked before allocating, so running out is not the input's fault
            click.echo("internal error: out of memory; --crop a subregion or choose a larger --voxel", err=True)
            sys.exit(1)
        except Exception as exc:  # a bug: one line unless debugging
            if os.environ.get("VOXRENDER_DEBUG"):
                raise
            click.echo(f"internal error: {type(exc).__name__}: {exc} (VOXRENDER_DEBUG=1 shows the traceback)",
                       err=True)
            sys.exit(1)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="voxrender")
def main():
    """Shaded pictures of the object inside a stack of CT-like slices."""


@main.command("render")
@_input_options
@_prep_options_decorator
@click.option("-o", "--output", "output_path", required=True, type=click.Path(path_type=Path), help="PNG to write.")
@click.option("--view", type=click.Choice(list(PRESETS)), help="A named view (DICOM axial stacks).")
@click.option("--alpha", type=float, help="Rotation about X1 in degrees.")
@click.option("--beta", type=float, help="Rotation about Y1 in degrees.")
@click.option("--gamma", type=float, help="Rotation about Z1 (the view axis) in degrees.")
@click.option("--vpn", metavar="I,J,K", help="View plane normal (object x,y,z toward the viewer).")
@_render_options_decorator
@_max_memory_option
def render_command(input_path, output_path, **options):
    """Render INPUT (a slice folder, volume file, label map or .vxs) to a shaded PNG."""
    _check_vxs_options(input_path, options)
    angles = _view_from(options)
    render_options = _render_options(options)
    _check_window(render_options)
    outputs = Outputs(output_path, **_output_paths(options))
    outputs.check(render_options)
    _check_output_paths(outputs.wanted())
    joins = _dicom_study(input_path, options, outputs.dicom)         # a non-DICOM input is refused before reading
    read, note = level_for_picture(input_path, _read_options(options), max(render_options.size))
    if note:
        click.echo(f"note: {note}", err=True)
    study = None
    if render_options.projection:
        from ..qc.study import load_study

        study = load_study(input_path, read, _prep_options(options), progress)
        loaded = study.encoded
    else:
        loaded = load_segments(input_path, read, _prep_options(options), progress)
    _check_label_options(loaded.segments, {"colours": options["colours"], "legend": options["legend"],
                                           **{name: path for name, path in outputs.wanted().items()
                                              if OUTPUTS[name].needs in (LABELS, LABEL_ROWS)}})
    max_memory = parse.memory(options["max_memory"]) if options["max_memory"] else None
    result = picture(loaded.segments, render_options.view(*angles), render_options, progress,
                     loaded.tree_for(render_options.method, max_memory), study=study)
    result.seconds = {**loaded.seconds, **result.seconds}
    write_outputs(result, outputs, {**about(loaded.segments), **joins})   # an empty picture was warned of


def _check_window(render_options, slice_options=None):
    """A window shows grey values: refused when nothing drawn has any (surfaces alone)."""
    if render_options.window is not None and not render_options.projection and slice_options is None:
        raise InputError("a window shows grey values, and a surface picture draws none; give a projection (mip, "
                         "minip or mean) or slices too, or drop it", parameter="window")


def _check_output_paths(paths):
    """The files a command writes (``{output name: path or None}``): each writable, none given twice, and a DICOM
    picture's named ``.dcm`` (a PACS takes it by what it holds, a person by its name).
    """
    seen = {}
    for name, path in paths.items():
        if path is None:
            continue
        if name == "dicom" and Path(path).suffix.lower() != ".dcm":
            raise InputError(f"{path} must end in .dcm", parameter="dicom")
        if Path(path).resolve() in seen:
            first = seen[Path(path).resolve()]
            raise InputError(f"{path} is given for two outputs ({'-o' if first == 'picture' else flag(first)} and "
                             f"{flag(name)}); give each its own file", parameter=name)   # the picture comes first
        seen[Path(path).resolve()] = name
        check_writable(path)


def _write_with_dicom(path, rgb, dicom, joins, what):
    """Write ``rgb`` to the PNG ``path`` and, when ``dicom`` is given, as a Secondary Capture of the study in
    ``joins``: both or neither.
    """
    if dicom is not None:
        from ..outputs.secondary_capture import write_secondary_capture

        write_secondary_capture(dicom, rgb, joins["dicom_study"], f"voxrender {__version__}: {what}")
    try:
        output.write_png(path, rgb)
    except BaseException:
        if dicom is not None:
            Path(dicom).unlink(missing_ok=True)
        raise


def _check_study_from(options, wanted):
    """``--dicom-study-from`` names the study of a DICOM output: refused when none is ``wanted``."""
    if options.get("dicom_study_from") and not wanted:
        raise InputError("names the study a DICOM output joins; give --dicom-out too", parameter="dicom_study_from")


def _dicom_study(input_path, options, wanted):
    """``{"dicom_study": DicomStudy}`` of the series a DICOM output joins (``--dicom-study-from``, else the input),
    read before anything is rendered, so that a non-DICOM input is refused first; ``{}`` when none is wanted.
    """
    _check_study_from(options, wanted)
    if not wanted:
        return {}
    from ..outputs.secondary_capture import dicom_study

    source = options.get("dicom_study_from")
    if source is None:
        return {"dicom_study": dicom_study(input_path, options.get("series"))}
    try:
        return {"dicom_study": dicom_study(source)}
    except InputError as exc:       # --series chooses the input's series; a study folder's is chosen by a file of it
        if exc.parameter != "series":
            raise
        raise InputError(f"{exc.message.split('; choose')[0]}; name one file of the series the picture joins",
                         parameter="dicom_study_from") from None


@main.command("slices")
@_input_options
@click.option("--labels", is_flag=True, help="INPUT is a label map: its labels drawn alone, each in its colour.")
@click.option("--label", metavar="N[,M...]", help="Only these labels of the label map.")
@click.option("--labels-from", type=click.Path(path_type=Path), metavar="MAP",
              help="The labels of INPUT: a label map, a folder of masks, a DICOM SEG or RTSTRUCT, placed by position.")
@click.option("--crop", metavar="X0:X1,Y0:Y1,Z0:Z1", help="Subregion in input voxel indices.")
@click.option("-o", "--output", "output_path", required=True, type=click.Path(path_type=Path), help="PNG to write.")
@_slice_options_decorator
@_window_option
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

    _check_vxs_options(input_path, options)
    _check_output_paths({"picture": output_path, "dicom": dicom})
    joins = _dicom_study(input_path, options, dicom)
    chosen = parse.labels(options["label"]) if options["label"] else None
    labelled = options["labels"] or options["label"] or options["labels_from"]
    selection = prep.LabelSelection(chosen, True, options["labels_from"]) if labelled else None
    crop = parse.crop(options["crop"]) if options["crop"] else None
    slice_options = replace(_slice_options(options, planes=("axial", "coronal", "sagittal"), legend=legend),
                            size=parse.size(size))
    table = colours.read_colour_table(colour_table) if colour_table else None
    metrics = None
    if reference is not None:
        study, metrics = _agreement_study(input_path, options, reference, crop, tolerance_mm)
    else:
        study = load_study(input_path, _read_options(options), PrepOptions(None, crop, labels=selection), progress,
                           encode=False)
    rows = slice_pictures(study, slice_options, table)
    picture_rgb = sheet([[rgb for _, rgb in row] for row in rows], [[caption for caption, _ in row] for row in rows])
    if metrics is not None:
        picture_rgb = _with_metrics(picture_rgb, metrics)
    _write_with_dicom(output_path, picture_rgb, dicom, joins,
                      f"slices {', '.join(slice_options.planes)}"
                      + (f" with the labels of {options['labels_from'].name}" if options["labels_from"] else ""))
    click.echo(f"{output_path}: {len(rows)} row{'s' * (len(rows) > 1)} of {', '.join(slice_options.planes)}")


@main.command("agreement")
@_input_options
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

    _check_output_paths({"picture": output_path, "metrics_out": metrics_out})
    comparison = Comparison(input_path, labels_from, reference, _read_options(options))
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
    comparison = Comparison(input_path, options["labels_from"], reference, _read_options(options))
    table = {str(k): {"name": name, "colour": list(colour)} for k, (name, colour) in CLASSES.items()}
    return Study(comparison.volume, comparison.classes(), table), comparison.metrics(tolerance_mm)


def _with_metrics(rgb, rows):
    """``rgb`` with the agreement's table under it, both as wide as the wider."""
    from ..review.agreement import metrics_picture

    table = metrics_picture(rows, rgb.shape[1])
    width = max(rgb.shape[1], table.shape[1])
    return np.concatenate([np.pad(part, ((0, 0), (0, width - part.shape[1]), (0, 0))) for part in (rgb, table)])


@main.command("encode")
@_input_options
@_prep_options_decorator
@click.option("-o", "--output", "output_path", required=True, type=click.Path(path_type=Path),
              help=".vxs file to write (.vxo with --octree).")
@click.option("--octree", "as_octree", is_flag=True,
              help="Also keep the region octree, linear octree and face adjacency (.vxo), so that octree methods "
                   "rendering from it pay only their traversal.")
@click.option("--jobs", type=click.IntRange(1, 1024), default=1, show_default=True,
              help="Worker processes encoding slabs of the stack at once.")
@click.option("--scheduler", metavar="ADDRESS|local",
              help="Encode the slabs on a Dask cluster ('local' starts one here); its workers read INPUT's path.")
@_max_memory_option
def encode_command(input_path, output_path, as_octree, jobs, scheduler, max_memory, **options):
    """Select the object of INPUT and save its run-length segments (.vxs), with its octrees (.vxo).

    A stack larger than --max-memory is read a slab at a time (streamed), in bounded memory.
    """
    suffix = ".vxo" if as_octree else ".vxs"
    if output_path.suffix.lower() != suffix:
        raise InputError(f"the output {output_path} must end in {suffix}")
    if is_segments_file(input_path) and not as_octree:
        raise InputError(f"{input_path} is already encoded")
    _check_vxs_options(input_path, options)
    check_writable(output_path)
    from ..object import stream

    loaded, how = stream.encode_file(input_path, output_path, _read_options(options), _prep_options(options),
                              octree=as_octree, jobs=jobs, scheduler=scheduler,
                              max_memory=parse.memory(max_memory) if max_memory else None, progress=progress)
    s = loaded.segments
    nz, ny, nx = s.shape
    chosen = [f"threshold {s.meta['threshold']}"] if "threshold" in s.meta else []
    if "labels" in s.meta:
        chosen.append(f"{len(s.meta['labels'])} labels" + (" as one object" if s.labels is None else ""))
    if s.meta.get("binned"):
        chosen.append(f"binned by {s.meta['binned']}")
    if how:
        chosen.append(f"streamed ({how})")
    click.echo(f"{output_path}: {nx}x{ny}x{nz} voxels, {s.voxel_count} in the object, {s.segment_count} segments"
               + "".join(f", {c}" for c in chosen) + f", {loaded.seconds['encode']:.1f} s")
    if as_octree:
        tree = loaded.octree()
        counts = tree.counts()
        click.echo(f"  a {1 << tree.n}^3 octree: {counts['black']} black, {counts['white']} white, {counts['grey']} "
                   f"grey nodes; {len(tree.linear)} linear-octree codes")


@main.command("info")
@_input_options
@_prep_options_decorator
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
def info_command(input_path, as_json, **options):
    """Describe INPUT: size, spacing, values, a suggested threshold, the object at a threshold."""
    if is_segments_file(input_path):
        _check_vxs_options(input_path, options)
        loaded = load_segments(input_path)
        s = loaded.segments
        summary = {"input": str(input_path), "format": input_path.suffix.lower()[1:],
                   "dimensions_xyz": list(s.shape[::-1]), "spacing_mm": list(s.spacing),
                   "object_voxels": s.voxel_count, "segments": s.segment_count,
                   **{k: v for k, v in s.meta.items() if k != "source"}}
        if loaded.has_octree:
            counts = loaded.octree().counts()
            summary["octree"] = {"side": 1 << loaded.octree().n, **{k: counts[k] for k in ("black", "white", "grey")},
                                 "face_adjacency": "kept"}
    else:
        read = _read_options(options)
        from ..object import stream

        stack = stream.stack_of(input_path, read)
        if stack is not None and stack.nbytes > machine_memory() // 2:       # described by its header
            summary = {"input": str(input_path), "format": stack.meta.get("format"),
                       "dimensions_xyz": list(stack.shape[::-1]), "spacing_mm": list(stack.spacing),
                       "dtype": str(stack.dtype), "size_mb": round(stack.nbytes / 1e6),
                       "values": "not read: the stack is larger than half this machine's memory; encode streams it"}
        else:
            summary = _describe(input_path, read.read(input_path, progress), _prep_options(options))
        if stack is not None:
            summary["if_streamed"] = stream.HOW[stack.how]
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
        elif isinstance(value, list) and value and all(isinstance(v, str) for v in value):
            click.echo(f"{key.replace('_', ' ')}:")
            for line in value:
                click.echo(f"  {line}")
        else:
            click.echo(f"{key.replace('_', ' ')}: {value}")


def _describe(path, volume, prepare):
    values = prep.crop(volume.values, prepare.crop)
    low, high = prep.value_range(values)                 # NaN and inf voxels left out, and counted
    if low is None:
        raise InputError(f"{path}: every voxel is NaN or infinite, so there is nothing to describe")
    padding = prep.padding_value(volume)
    lowest, highest = prep.value_range(values, padding)
    suggested = prep.otsu_threshold(values, padding) if lowest is not None and lowest < highest else low
    sample = np.asarray(values[::max(1, values.shape[0] // 64)])
    if sample.dtype.kind in "fc":                 # its finite values (or all slices', when the sample has none)
        finite = np.isfinite(sample)
        sample = sample[finite] if finite.any() else np.asarray(values)[np.isfinite(values)]
    percentiles = np.percentile(sample, [1, 5, 25, 50, 75, 95, 99])
    summary = {"input": str(path), "format": volume.meta.get("format"),
               "dimensions_xyz": list(volume.shape[::-1]), "spacing_mm": list(volume.spacing),
               "spacing_from": volume.meta.get("spacing_from"), "dtype": str(volume.values.dtype),
               "units": volume.meta.get("units", "stored values"), "value_range": [low, high],
               **{f"{kind}_voxels": count for kind, count in prep.non_finite_counts(values).items()},
               "percentiles_1_5_25_50_75_95_99": [round(float(p), 2) for p in percentiles],
               **({"padding_value": padding, "padding_voxels": int(np.count_nonzero(np.asarray(values) == padding))}
                  if padding is not None else {}),
               "suggested_threshold_otsu": round(suggested, 2)}
    if volume.meta.get("units") == "HU":                  # the tissue windows of a CT
        summary["suggested_presets"] = {name: str(colours.PRESETS[name].window) for name in ("skin", "bone")}
    for key in ("modality", "series", "description", "sorted_by", "orientation", "orientation_from", "affine",
                "reoriented", "masks_reoriented"):
        if volume.meta.get(key):
            summary[key] = volume.meta[key]
    if prepare.labels is not None and prepare.labels.source is None:       # a label map: its labels
        summary.update(_describe_labels(volume, values, path))
        return summary
    if prepare.labels is not None:                                         # an image and its label map
        summary.update(_describe_pairing(volume, prepare.labels.source, prepare.crop))
        return summary
    threshold = suggested if callable(prepare.selecting) or prepare.selecting is None else prepare.selecting
    mask, info = prep.binarize(volume, threshold, crop=prepare.crop, voxel=prepare.voxel,
                               resample=prepare.resample, min_object=prepare.min_object)
    encoded = segments.encode(mask)
    summary.update({"threshold": str(threshold) if isinstance(threshold, prep.Window) else threshold,
                    "object_grid_xyz": list(mask.shape[::-1]),
                    "object_voxel_mm": info["voxel"], "object_voxels": encoded.voxel_count,
                    "object_fraction": round(encoded.voxel_count / mask.size, 6),
                    "segments": encoded.segment_count})
    return summary


def _describe_labels(volume, values, source):
    """The labels of a label map: each with its name (as a table or the palette would give it), voxels and mL,
    those its file names but that hold no voxel too, and the overlaps its reader resolved.
    """
    from ..pictures.labels import label_list

    prep.check_labels(values, source)
    counts = prep.label_counts(values, volume.meta.get("label_sets"))      # each structure's own voxels
    stored = volume.meta.get("label_table") or {}
    table = colours.label_colours(sorted(set(counts) | {int(k) for k in stored}), stored)
    rows = label_list(table, counts, volume.spacing)
    summary = {"labels": {row.pop("label"): row for row in rows}}
    if volume.meta.get("overlaps"):
        summary["overlaps"] = volume.meta["overlaps"]
    return summary


def _describe_pairing(volume, source, crop):
    """An image's label map: both grids and how they relate, and its labels as they fall on the image's grid."""
    from ..object.pipeline import on_image_grid, read_labels
    from ..space.grids import relate

    labels = read_labels(source, volume)
    relation = relate(labels.shape, patient_affine(labels), volume.shape, patient_affine(volume))
    lines = relation.lines("label map", "image", labels.meta.get("orientation"), volume.meta.get("orientation"))
    paired = replace(volume, values=on_image_grid(labels, volume, source)[0],
                     meta={**labels.meta, "source": str(source)})
    return {"label_map": str(source), "grids": lines,
            **_describe_labels(paired, prep.crop(paired.values, crop), source)}


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
@_read_options_decorator
@_prep_options_decorator
@click.option("--view", "views", multiple=True, type=click.Choice(list(PRESETS)), help="A named view (repeatable).")
@click.option("--angles", multiple=True, metavar="A,B,G", help="alpha,beta,gamma in degrees (repeatable).")
@click.option("--turntable", type=click.IntRange(1, 3600), metavar="N",
              help="N views turning the object about --axis, from the first view given (default anterior).")
@click.option("--axis", default="z", show_default=True, type=click.Choice(["x", "y", "z"]))
@click.option("--pattern", default="{name}/{view}.png", show_default=True,
              help="Output names under --out: {name}, {view}, {method}, {index}.")
@_render_options_decorator
@click.option("--per-label", is_flag=True,
              help="Also write each label the picture shows alone, beside it ({view}-label{N}.png).")
@click.option("--sheet", "make_sheet", is_flag=True,
              help="Also each input's QC sheet in OUT/sheets/NAME.png (its views, --projection, --slices and labels) "
                   "and all pictures laid out in OUT/sheet.png.")
@_slice_options_decorator
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
    patterns = batch.Patterns(pattern, **{name: str(path) for name, path in _output_paths(options).items()})
    slice_options = _slice_options(options)
    render_options = _render_options(options)
    _check_window(render_options, slice_options)
    if per_label and options["projection"]:
        raise InputError("a projection draws grey values, not labels one by one; drop --per-label, or the projection",
                         parameter="per_label")
    if slice_options is not None and not make_sheet:
        raise InputError("slices are drawn on each input's QC sheet; give --sheet too", parameter="planes")
    _check_study_from(options, options.get("dicom"))
    items = batch.items_from(batch.expand_inputs(inputs), batch.read_manifest(manifest) if manifest else [],
                             _read_options(options), _prep_options(options), render_options,
                             batch.parse_views(views, [parse.vector(a, "angles") for a in angles], turntable, axis),
                             patterns, per_label, make_sheet, slice_options, options["dicom_study_from"],
                             reference, tolerance_mm)
    animations = [kind for kind, wanted in (("gif", gif), ("mp4", mp4)) if wanted]
    started = time.perf_counter()
    from ..qc.index_page import read_verdicts

    earlier = read_verdicts(verdicts) if verdicts is not None else None
    summary = batch.run_batch(items, out_dir, jobs, scheduler, cache, animations, fps, _BatchBar, make_sheet,
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


@main.command("sheet")
@click.argument("inputs", nargs=-1, required=True, type=click.Path(path_type=Path), metavar="INPUT...")
@_read_options_decorator
@_prep_options_decorator
@click.option("-o", "--output", "output_path", required=True, type=click.Path(path_type=Path), help="PNG to write.")
@click.option("--view", "views", multiple=True, type=click.Choice(list(PRESETS)), help="A named view (repeatable).")
@click.option("--views", "view_list", metavar="NAME[,NAME...]", help="Named views, separated by commas.")
@click.option("--angles", multiple=True, metavar="A,B,G", help="alpha,beta,gamma in degrees (repeatable).")
@click.option("--methods", metavar="M1,M2,...", help="Rows of methods (one input): compare the algorithms.")
@click.option("--per-label", is_flag=True, help="Rows of labels (one input with labels): all, then each alone.")
@_slice_options_decorator
@_render_options_decorator
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
    given = [flag(name) for name in _output_paths(options) if name != "dicom"]   # a sheet writes the picture alone
    if given:
        raise InputError(f"a sheet is one picture: {', '.join(given)} cannot apply; use render or batch")
    dicom = options.get("dicom")
    _check_output_paths({"picture": output_path, "dicom": dicom})
    names = [*views, *(parse.planes(view_list) if view_list else ())]
    chosen = batch.parse_views(names, [parse.vector(a, "angles") for a in angles])
    columns = [(v.label, (v.alpha, v.beta, v.gamma)) for v in chosen]
    render_options = _render_options(options)
    read, prepare = _read_options(options), _prep_options(options)
    slice_options = _slice_options(options)
    _check_window(render_options, slice_options)
    if methods and per_label:
        raise InputError("give --methods or --per-label, not both: a sheet has one kind of row")
    if (methods or per_label) and len(inputs) > 1:
        raise InputError(f"give one input for {'--methods' if methods else '--per-label'}, or several without it")
    if reference is not None and slice_options is None and not render_options.projection:
        raise InputError("a reference's table goes on a QC sheet: give --slices or --projection too",
                         parameter="reference")
    if slice_options is not None or render_options.projection:
        if methods or per_label or len(inputs) > 1:
            raise InputError("a QC sheet (--slices, --projection) is of one study: give one input, without "
                             "--methods or --per-label; 'voxrender batch --sheet' makes one per study")
        from ..qc.qc import qc_sheet
        from ..qc.study import load_study

        joins = _dicom_study(inputs[0], options, dicom)
        study = load_study(inputs[0], read, prepare, progress)
        rgb = qc_sheet(study, render_options, columns, slice_options, title=str(inputs[0]), progress=progress)
        if reference is not None:
            from ..review.agreement import Comparison

            if not options.get("labels_from"):
                raise InputError("a reference is held against labels: give them with --labels-from",
                                 parameter="reference")
            rgb = _with_metrics(rgb, Comparison(inputs[0], options["labels_from"], reference, read)
                                .metrics(tolerance_mm))
        from ..outputs.secondary_capture import selection_words

        shows = [f"QC sheet of {', '.join(v.label for v in chosen)}"]
        if render_options.projection:
            shows.append(render_options.projection)
        if slice_options:
            shows.append(f"slices {', '.join(slice_options.planes)}")
        shows += selection_words(study.encoded.segments.meta)
        _write_with_dicom(output_path, rgb, dicom, joins, ", ".join(shows))
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


@main.command("presets")
def presets_command():
    """List the CT tissue presets of --preset: HU window, colour, and where the values come from."""
    for name, tissue in colours.PRESETS.items():
        click.echo(f"{name:17} {str(tissue.window) + ' HU':16} rgb {','.join(map(str, tissue.colour)):12} "
                   f"{tissue.source}")


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

