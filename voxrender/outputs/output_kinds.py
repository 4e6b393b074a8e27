"""The kinds of output a picture is written to: the registry ``OUTPUTS`` of :class:`OutputKind` records.

As :data:`voxrender.METHODS` is for renderers, ``OUTPUTS`` is the one place an output is spelt out: the
ending of its file, its help, how it is written and what the picture must have for it.  The rest is derived from
it: :class:`voxrender.outputs.picture_outputs.Outputs` (a path per output) and
:func:`voxrender.outputs.picture_outputs.write_outputs`, :class:`voxrender.batch.run.Patterns` (a pattern per output)
and its check of the endings, and the command line's options.  Adding an output is one record.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import MISSING, dataclass

from ..pictures import shade
from . import output
from .secondary_capture import write_dicom_output  # light: it imports pydicom when it writes


@dataclass(frozen=True)
class Need:
    """Something only some pictures have, which an output needs.

    Parameters
    ----------
    field : str
        The :class:`~voxrender.pictures._picture.Picture` field the output writes, ``None`` on the pictures without it.
    lacking : str
        Why a picture is without it and what to do, in words (the message of the error that refuses the output).
    parameter : str, optional
        The parameter at fault (default: the output's own).
    given : callable, optional
        ``given(options)``: whether the pictures of these :class:`~voxrender.pictures._picture.RenderOptions` have it,
        when the options alone tell; checked before anything is rendered.
    """

    field: str
    lacking: str
    parameter: str | None = None
    given: Callable | None = None


GRADIENT_NORMALS = Need("normals", "normals are kept with gradient shading only; drop the normals outputs or shade "
                        "by gradient", "shading",
                        lambda options: options.shading == "gradient" and options.drawn.depth)
DEPTH = Need("depth", "a projection has no depth, its pixels hold grey values; drop the depth outputs, or write the "
             "values", "projection", lambda options: options.drawn.depth)
VALUES = Need("values", "only a projection has grey values to write; choose a projection (mip, minip or mean)",
              "projection", lambda options: options.drawn.grey_values)
LABELS = Need("labels", "the picture has no label image to write: it is of a surface of labels, and a projection "
              "has none; render the labels of a label map, without a projection")
LABEL_ROWS = Need("label_rows", "the object has no labels to write; render the labels of a label map")


@dataclass(frozen=True)
class OutputKind:
    """One kind of output of a picture: a file beside the picture, or the picture itself.

    Parameters
    ----------
    suffix : str
        The ending its file must have (checked for the patterns of a batch).
    help : str
        What it holds, as the command line's help of its flag says it.
    write : callable
        ``write(path, result, about)`` writes it from the :class:`~voxrender.pictures._picture.Picture` ``result``;
        ``about`` holds the fields the JSON report adds (see :func:`~voxrender.outputs.picture_outputs.write_outputs`).
    flag : str, optional
        Its flag on the command line, without the dashes (``"depth-out"``); ``None`` for the picture, which each
        command names in its own way.
    needs : Need, optional
        What the picture must have for it: normals need gradient shading, labels a multi-label object.
    report : bool
        It reports the picture's stages, so it is written last, once ``write`` and ``total`` are counted.
    """

    suffix: str
    help: str
    write: Callable
    flag: str | None = None
    needs: Need | None = None
    report: bool = False


def _write_report(path, result, about):
    """The JSON report of a picture: its method, stages, the renderer's statistics and the view."""
    image = result.image
    output.write_json(path, {
        "method": image.method, "seconds": result.seconds, "stats": image.stats,
        "view": {"alpha": image.view.alpha, "beta": image.view.beta, "gamma": image.view.gamma,
                 "scale": image.view.scale, "size": list(image.view.size)},
        "covered_pixels": int(image.coverage.sum()),
        **{k: v for k, v in (about or {}).items() if k != "dicom_study"}})      # the source's header: not JSON


# In the order of the commands' help and of Outputs' fields; the picture first.
OUTPUTS = {
    "picture": OutputKind(
        ".png", "The shaded picture (8-bit RGB, or grey when it has no colour).",
        lambda path, result, about: output.write_png(path, result.rgb)),
    "depth": OutputKind(
        ".npy", "Save the depth image (float32, +inf background); in a batch, a pattern like --pattern.",
        lambda path, result, about: output.write_npy(path, result.image.depth), "depth-out", DEPTH),
    "depth_png": OutputKind(
        ".png", "Save depth as a 16-bit PNG (near bright, background 0); in a batch, a pattern.",
        lambda path, result, about: output.write_png(path, shade.depth_to_uint16(result.image.depth)), "depth-png",
        DEPTH),
    "stats_json": OutputKind(
        ".json", "Save timings and the renderer's statistics as JSON; in a batch, a pattern.",
        _write_report, "stats-json", report=True),
    "normals": OutputKind(
        ".npy", "Save the image-space unit normals (H x W x 3, NaN background); in a batch, a pattern.",
        lambda path, result, about: output.write_npy(path, result.normals), "normals-out", GRADIENT_NORMALS),
    "normals_png": OutputKind(
        ".png", "Save an RGB normal map; in a batch, a pattern.",
        lambda path, result, about: output.write_png(path, shade.normals_to_rgb(result.normals)), "normals-png",
        GRADIENT_NORMALS),
    "labels_json": OutputKind(
        ".json", "Save the object's labels: names, colours, voxels, volumes in mL and the pixels each shows; in a "
        "batch, a pattern.",
        lambda path, result, about: output.write_json(path, {"labels": result.label_rows}), "labels-out",
        LABEL_ROWS),
    "label_png": OutputKind(
        ".png", "Save the label image (16-bit, one label per pixel, 0 background); in a batch, a pattern.",
        lambda path, result, about: output.write_png(path, result.labels), "label-png", LABELS),
    "values": OutputKind(
        ".npy", "Save a projection's values (float32 in the input's units, NaN where the ray meets no voxel); in a "
        "batch, a pattern.", lambda path, result, about: output.write_npy(path, result.values), "values-out", VALUES),
    "dicom": OutputKind(
        ".dcm", "Save the picture as an RGB DICOM Secondary Capture in a new series of the source study; in a batch, "
        "a pattern.", write_dicom_output, "dicom-out"),
}


def fields_per_output(value_type, picture=MISSING):
    """A class decorator: the class becomes a frozen dataclass with a field per output in :data:`OUTPUTS`, in its
    order: ``picture`` first (``picture`` its default, when given), each other one ``None`` (not wanted) by default.

    >>> @fields_per_output(str, picture="p.png")
    ... class Names:
    ...     pass
    >>> Names(depth="d.npy").depth, Names().picture, Names().stats_json
    ('d.npy', 'p.png', None)
    """
    def decorate(cls):
        cls.__annotations__ = {name: value_type if name == "picture" else value_type | None for name in OUTPUTS}
        for name in OUTPUTS:
            if name != "picture":
                setattr(cls, name, None)
            elif picture is not MISSING:
                cls.picture = picture
        return dataclass(frozen=True)(cls)

    return decorate
