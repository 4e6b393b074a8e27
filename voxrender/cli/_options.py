"""The flags the commands share, declared once (``input_flags``, ``prep_flags``, ``render_flags``, ...), the
library values they parse into (``read_options_of``, ``prep_options_of``, ``render_options_of``, ...), and the checks
of what a command is asked to write (``check_output_paths``, ``dicom_study_of``, ...).
"""

from __future__ import annotations

from pathlib import Path

import click

from .. import io
from .._render import DEFAULT_METHOD, METHODS, Clip
from .._render.raycast import CONNECTIVITIES
from .._shared.files import check_writable
from ..batch import parse
from ..errors import InputError
from ..object import prep
from ..object.pipeline import AUTO, PrepOptions, ReadOptions, is_segments_file
from ..outputs.output_kinds import OUTPUTS
from ..pictures import PROJECTIONS, RenderOptions, colours
from ..pictures.shade import HEADLIGHT, SHADINGS
from ..qc.slices import OVERLAYS
from ..space import orient
from ..space.view import PRESETS, angles_from_vpn
from ._main import flag


def view_of(options):
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


def read_options_of(options):
    spacing = io.check_spacing(parse.vector(options["spacing"], "spacing")) if options["spacing"] else None
    raw = parse.raw_layout(options["raw"]) if options["raw"] else None
    if options["orientation"] is not None:
        orient.direction_of(options["orientation"])          # a bad code is an error before anything is read
    return ReadOptions(options["format"], raw, spacing, options["series"], options["frame"], options["orientation"],
                       options["reorient"], options["level"], options["run"])


def prep_options_of(options):
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


def render_options_of(options):
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


def output_paths_of(options):
    """``{name: path}`` of the outputs whose flags are given (the picture's own flag aside), by ``OUTPUTS``."""
    return {name: options[name] for name in OUTPUTS if options.get(name) is not None}


def max_memory_flag(command):
    what = ("a stack larger is read a slab at a time (streamed), and an octree build that would need more is "
            "refused" if command.__name__ == "encode_command" else "an octree build that would need more is refused")
    return click.option("--max-memory", metavar="SIZE",
                        help=f"Memory to stay within, e.g. 8G (default: half the machine's): {what}.")(command)


def check_vxs_options(path, options):
    """A .vxs file is already thresholded: refuse options that would silently do nothing."""
    if not is_segments_file(path):
        return
    given = [flag(name) for name in ("threshold", "preset", "label", "labels", "labels_from", "crop", "voxel", "raw",
                                     "spacing", "series", "frame", "orientation")
             if options.get(name) not in (None, False)] + ["--bin"] * (options.get("bin", 1) != 1)
    if given:
        raise InputError(f"{path} is already encoded, so {', '.join(given)} cannot apply; "
                         "give the slice stack instead")


def check_label_options(s, options):
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


def input_flags(command):
    return _decorate(command, [click.argument("input_path", metavar="INPUT", type=click.Path(path_type=Path)),
                               read_flags])


def read_flags(command):
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
                     help="The level of a multiscale OME-Zarr, or of a .vxs encoded with --levels, 0 the finest "
                          "(default: for render, the one that suits the picture; else the finest)."),
        click.option("--orientation", metavar="CODE",
                     help="Orientation of an input whose header has none, e.g. RAS or LPI: the sides voxel x, y and "
                          "z grow toward."),
        click.option("--reorient/--no-reorient", default=True, show_default=True,
                     help="Bring the volume to the patient frame the view presets assume (flips and permutations "
                          "only), or keep the stored order."),
    ])


def prep_flags(command):
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


def render_flags(command):
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
        window_flag,
        click.option("--dicom-study-from", type=click.Path(path_type=Path), metavar="DICOM_DIR",
                     help="With --dicom-out: the DICOM series whose study the picture joins (default: INPUT's)."),
        output_flags,
    ])


window_flag = click.option(
    "--window", metavar="LEVEL/WIDTH|NAME",
    help="Grey values' window of slices and projections: e.g. 40/400, or brain, soft-tissue, bone, lung (default: "
         "slices of a CT soft-tissue; else the 1st to 99th percentile of the values, of a projection along y for "
         "projections).")


def slice_flags(command):
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


def slice_options_of(options, planes=None, legend=False):
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


def output_flags(command):
    """A flag per output of ``OUTPUTS`` besides the picture (which each command names itself), its parameter the
    output's name: a file in ``render``, a pattern in ``batch``, refused by ``sheet``.
    """
    return _decorate(command, [
        click.option(f"--{kind.flag}", name, type=click.Path(path_type=Path), metavar=f"FILE{kind.suffix}",
                     help=kind.help)
        for name, kind in OUTPUTS.items() if kind.flag])


def check_window(render_options, slice_options=None):
    """A window shows grey values: refused when nothing drawn has any (surfaces alone)."""
    if render_options.window is not None and not render_options.drawn.grey_values and slice_options is None:
        raise InputError("a window shows grey values, and a surface picture draws none; give a projection (mip, "
                         "minip or mean) or slices too, or drop it", parameter="window")


def check_output_paths(paths):
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


def check_study_from(options, wanted):
    """``--dicom-study-from`` names the study of a DICOM output: refused when none is ``wanted``."""
    if options.get("dicom_study_from") and not wanted:
        raise InputError("names the study a DICOM output joins; give --dicom-out too", parameter="dicom_study_from")


def dicom_study_of(input_path, options, wanted):
    """``{"dicom_study": DicomStudy}`` of the series a DICOM output joins (``--dicom-study-from``, else the input),
    read before anything is rendered, so that a non-DICOM input is refused first; ``{}`` when none is wanted.
    """
    check_study_from(options, wanted)
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
