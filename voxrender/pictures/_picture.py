"""The picture step: render, shade and time, the same for every command.

:class:`RenderOptions` holds everything that turns an encoded object and a view into a
picture (method and its options, clip and cut, framing, shading); :func:`picture` makes it
(:func:`voxrender.outputs.picture_outputs.write_outputs` writes it).  ``voxrender render``, ``voxrender batch`` and
the demo all go through it, so the same options give the same picture from every command.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from .._render import DEFAULT_METHOD, Clip, DepthImage, framing_box, method_record, render
from ..errors import InputError
from ..space.view import PRESETS, View
from . import shade
from .kinds import PROJECTIONS, SURFACE
from .shade import HEADLIGHT, SHADINGS, light_direction

# The most runs whose box a picture's level of detail is chosen by (the finest level with no more).
_FRAMING_RUNS = 1 << 20
# The views that see a slab thin along an axis face-on.
FACE_ON = {"x": ("left", "right"), "y": ("anterior", "posterior"), "z": ("inferior", "superior")}


@dataclass(frozen=True)
class RenderOptions:
    """How a picture is made from an encoded object and view angles.

    Parameters
    ----------
    method : str
        A name in :data:`voxrender.METHODS`.
    method_options : dict
        The method's own options (e.g. ``{"connectivity": "6"}`` for ``raycast``).
    clip : Clip, optional
        Clip limits and the cut plane.
    fit : {"object", "volume"}
        How an unset ``scale`` frames the picture: the object as the view sees it, or the volume at any rotation.
    size : (H, W)
        Picture size in pixels.
    scale : float, optional
        Pixels per voxel (default: fitted).
    supersample : int
        Pre-image supersampling, for methods that turn a pre-image by gamma.
    shading : {"gradient", "depth-gradient", "depth"}
        Lighting of grey-level gradient normals (the default), the paper's depth-gradient shading, or depth.
    light : 3 floats
        Direction toward the light in image space (default: a headlight a little above and left).
    colour : 3 floats in [0, 1]
        Colour of a fully lit surface (a single object).
    colours : dict, optional
        ``{label: (name, (r, g, b))}`` for a multi-label object, ahead of the names and colours kept with it
        (see :func:`voxrender.pictures.colours.label_colours`).
    legend : bool
        Draw the names and colours of the labels the picture shows.
    background : 3 ints in [0, 255]
    ao : bool
        Darken creases and pits by screen-space ambient occlusion.
    orientation_marks : bool
        Write the patient directions (L/R, A/P, S/I) at the picture's edges.
    projection : {"mip", "minip", "mean"}, optional
        Draw the grey values' maximum (minimum, mean) along each ray instead of the surface
        (:func:`voxrender.pictures._project.project`); the picture then needs the grey values (a
        :class:`~voxrender.qc.study.Study`).
    window : DisplayWindow, optional
        The grey values' window of a projection (default: :meth:`~voxrender.qc.study.Study.window`, the same for every
        view; with a slab or clip limits, the 1st to 99th percentile of the picture's own values).
    slab : float, optional
        Project only a slab this many mm thick around the volume centre, or around the cut plane when there is one.
    """

    method: str = DEFAULT_METHOD
    method_options: dict = field(default_factory=dict)
    clip: Clip | None = None
    fit: str = "object"
    size: tuple = (512, 512)
    scale: float | None = None
    supersample: int = 2
    shading: str = "gradient"
    light: tuple = HEADLIGHT
    colour: tuple = (1.0, 1.0, 1.0)
    colours: dict | None = None
    legend: bool = False
    background: tuple = (0, 0, 0)
    ao: bool = False
    orientation_marks: bool = False
    projection: str | None = None
    window: object = None
    slab: float | None = None

    @property
    def drawn(self):
        """What the picture draws (:mod:`voxrender.pictures.kinds`): the surface, or the projection's record."""
        return PROJECTIONS.get(self.projection, SURFACE)

    def __post_init__(self):
        method_record(self.method, self.method_options)
        if self.projection is not None and self.projection not in PROJECTIONS:
            raise InputError(f"unknown projection {self.projection!r}; choose {', '.join(PROJECTIONS)}",
                             parameter="projection")
        if self.slab is not None and not (self.slab > 0 and np.isfinite(self.slab)):
            raise InputError(f"{self.slab:g} must be a thickness above 0 mm", parameter="slab")
        if self.slab is not None and self.projection is None:
            raise InputError("a slab is the thickness of a projection; choose a projection (mip, minip or mean) "
                             "too", parameter="slab")
        if self.shading not in SHADINGS:
            raise InputError(f"unknown shading {self.shading!r}; choose {' or '.join(SHADINGS)}", parameter="shading")
        if self.fit not in ("object", "volume"):
            raise InputError(f"{self.fit!r}: choose 'object' or 'volume'", parameter="fit")
        light_direction(self.light)
        View(size=self.size, scale=self.scale)   # checks size and scale

    def view(self, alpha=0.0, beta=0.0, gamma=0.0):
        """The :class:`View` of these options at the given angles (degrees)."""
        return View(alpha, beta, gamma, tuple(self.size), self.scale)


@dataclass
class Picture:
    """A finished picture: ``rgb`` (H, W, 3) uint8, the :class:`DepthImage`, ``seconds`` by stage, the
    image-space ``normals`` (H, W, 3) it was lit with (NaN in the background), and for a multi-label object the
    label image (uint16 (H, W), see :mod:`voxrender.pictures.labels`), ``label_table``, ``{label: (name, (r, g, b))}``
    of the object's labels, and ``label_rows``, each label with its voxels, mL and the pixels it shows
    (:func:`voxrender.pictures.labels.label_list`).
    """

    rgb: np.ndarray
    image: DepthImage
    seconds: dict
    normals: np.ndarray | None = None
    labels: np.ndarray | None = None
    label_table: dict | None = None
    label_rows: list | None = None
    values: np.ndarray | None = None
    projection: str | None = None

    @property
    def depth(self):
        """The depth image; ``None`` for a projection, which has none."""
        return self.image.depth if PROJECTIONS.get(self.projection, SURFACE).depth else None

    def _repr_png_(self):
        """The picture as PNG bytes: a notebook shows it."""
        import io

        from PIL import Image

        buffer = io.BytesIO()
        Image.fromarray(self.rgb).save(buffer, format="png")
        return buffer.getvalue()

    def visible_labels(self):
        """The :attr:`label_rows` of the labels the picture shows."""
        return [row for row in self.label_rows or () if row["pixels"]]


def picture(segments, view, options=None, progress=None, tree=None, normals=None, study=None):
    """Render ``segments`` from ``view`` and shade it as ``options`` say.

    Parameters
    ----------
    segments : Segments or Encoded
        The object, or the encoded object :func:`voxrender.load_segments` gives (see :func:`render`).
    view : View
        Usually ``options.view(alpha, beta, gamma)``.
    options : RenderOptions, optional
    progress : callable, optional
    tree : RegionOctree, optional
        The object's region octree, kept by the caller for octree methods.
    normals : SurfaceNormals, optional
        The object's surface normals (default: those kept with the segments, else from the binary mask).
    study : Study, optional
        The grey values a projection draws (:func:`voxrender.qc.study.load_study`), on the grid the segments were
        made from.

    Returns
    -------
    Picture
        With ``seconds["render"]`` (the renderer alone) and ``seconds["shade"]``; a projection's picture also has
        its ``values`` (float32, NaN where the ray meets no voxel).

    Examples
    --------
    >>> from voxrender.object.segments import encode
    >>> result = picture(encode(np.ones((4, 4, 4), bool)), View(30, 20, size=(16, 16), scale=2.0))
    >>> result.rgb.shape, result.image.method
    ((16, 16, 3), 'ftb')
    """
    options = options or RenderOptions()
    if options.drawn.grey_values:
        return _projection(segments, view, options, study, progress)
    drawn = getattr(segments, "segments", segments)
    shown_normals = normals or drawn.normals
    drawn.prefetch()                     # a file's runs, and the normals the shading looks up, read meanwhile
    if options.shading == "gradient" and shown_normals is not None:
        shown_normals.prefetch()
    image = render(segments, view, options.method, progress, options.supersample, options.clip, options.fit,
                   tree, **options.method_options)
    segments = drawn
    seconds = {"render": image.seconds}
    if not image.coverage.any():
        warnings.warn(_why_empty(segments, image.view, options), stacklevel=2)
    colour, labels, table = options.colour, None, None
    if segments.labels is not None:
        started = time.perf_counter()
        labels, table, colour = _label_colours(segments, image, options)
        seconds["labels"] = time.perf_counter() - started
    started = time.perf_counter()
    normal_image = None
    if options.shading == "gradient":
        from ..object.normals import kept
        from ..object.normals import normal_image as at_hits

        normal_image = at_hits(image.depth, image.view, segments.shape, normals or kept(segments), segments,
                               options.clip)
    occlusion = shade.ambient_occlusion(image.depth, image.view.scale) if options.ao else None
    rgb = shade.shade(image.depth, options.shading, image.view.scale, options.light, colour,
                      options.background, normal_image, occlusion)
    if _marks_apply(options, segments.meta):
        from .marks import draw_marks

        rgb = draw_marks(rgb, image.view)
    rows = None if table is None else _label_rows(segments, table, image.stats["label_pixels"])
    result = Picture(rgb, image, {**seconds, "shade": time.perf_counter() - started}, normal_image, labels, table,
                     rows)
    if options.legend and table is not None:
        from .marks import draw_legend

        result.rgb = draw_legend(rgb, [(_caption(v), v["colour"]) for v in result.visible_labels()])
    return result


def level_for(segments, view, options=None, level=None):
    """The level of detail a picture of ``segments`` is drawn from, and its view in that level's voxels.

    ``level`` 0 is the object's own voxels, ``k`` its ``k``-th coarser level (:mod:`voxrender.object.levels`,
    kept by ``encode --levels``); ``None`` chooses the coarsest whose voxel is no larger than a pixel of the
    picture (the full resolution when the object keeps no levels, or with clip limits, which are given in its own
    voxels).  A scale the view sets (pixels per voxel of the full resolution) becomes that of the level's voxels.

    Parameters
    ----------
    segments : Segments
    view : View
    options : RenderOptions, optional
        Their ``fit`` frames the picture when the view sets no scale.
    level : int, optional

    Returns
    -------
    level : int
    view : View

    Examples
    --------
    >>> from voxrender.object.levels import build_levels
    >>> from voxrender.object.segments import encode
    >>> ball = encode(np.ones((64, 64, 64), bool)); ball.levels = build_levels(ball)
    >>> level_for(ball, View(size=(16, 16)))[0], level_for(ball, View(size=(256, 256)))[0]
    (2, 0)
    >>> level_for(ball, View(size=(64, 64), scale=0.5))
    (1, View(alpha=0.0, beta=0.0, gamma=0.0, size=(64, 64), scale=1.0, centre=(0.0, 0.0)))
    """
    options = options or RenderOptions()
    if level is None:
        if not segments.levels or options.clip is not None:
            return 0, view
        from ..object.levels import choose_level

        # the box of the finest level quick to scan (the object's own, when small): its coarse voxels' middles
        framer = next((one for one in (segments, *segments.levels) if one.segment_count <= _FRAMING_RUNS),
                      segments.levels[-1])
        factor = framer.meta.get("level_factor", 1) if framer is not segments else 1
        box = framing_box(framer)
        middle = (factor - 1) / 2
        fine_box = None if box is None else tuple((lo * factor + middle, hi * factor + middle) for lo, hi in box)
        scale = view.fitted(segments.shape, fine_box, options.fit).scale
        level = choose_level([one.meta["level_factor"] for one in segments.levels], 1 / scale)
    drawn = segments.at_level(level)
    if level and options.clip is not None:
        raise InputError("clip limits are given in the object's own voxels: draw them at level 0",
                         parameter="level")
    if not level or view.scale is None:
        return level, view
    # the same picture of the coarse grid: a coarse voxel q is fine p = f q + (f - 1) / 2, so image space scales by
    # 1 / f and moves by R delta / f, delta the way the coarse grid's centre lies from the fine one's
    factor = drawn.meta["level_factor"]
    delta = (np.array(drawn.shape[::-1]) * factor - np.array(segments.shape[::-1])) / 2
    shift = view.matrix @ delta
    centre = tuple(float(c - d) / factor for c, d in zip(view.centre, shift[:2], strict=True))
    return level, replace(view, scale=view.scale * factor, centre=centre)


def _label_rows(segments, table, pixels=None):
    """The rows of the labels the object holds (a threshold may empty some), with their voxels, mL and, of a surface
    picture, the ``pixels`` each shows (:func:`voxrender.pictures.labels.label_list`).
    """
    from .labels import label_list

    own = segments.meta.get("label_voxels")           # each structure's own voxels on the image's grid
    voxels = {int(k): v for k, v in own.items()} if own else segments.label_voxels()
    rows = label_list({k: v for k, v in table.items() if voxels.get(k)}, voxels, segments.spacing, pixels,
                      segments.meta.get("label_ml"), segments.meta.get("label_ml_outside"))
    shown = segments.meta.get("labels_shown")         # the volumes are the labels' own; the picture keeps less
    pieces, border = segments.meta.get("label_pieces"), segments.meta.get("label_border")
    if pieces is not None:                            # measured for a batch's flags
        rows = [{**row, "components": pieces.get(str(row["label"])), "border": border.get(str(row["label"]))}
                for row in rows]
    return [{**row, "shown": shown} for row in rows] if shown else rows


def _marks_apply(options, meta):
    """Whether the orientation marks asked for can be drawn: the object lies in the patient frame (a warning when
    not: kept in its stored order, its picture's edges have no patient directions).
    """
    from ..space.orient import in_patient_frame

    if options.orientation_marks and not in_patient_frame(meta):
        warnings.warn("the volume was kept in its stored order, not the patient frame, so the picture's edges have "
                      "no patient directions to mark; reorient it to have them", stacklevel=3)
        return False
    return options.orientation_marks


def _caption(entry):
    """A label's line in a legend: "3 liver"; an unnamed label is already "label 3"."""
    named = entry["name"] != f"label {entry['label']}"
    return f"{entry['label']} {entry['name']}" if named else entry["name"]


def _projection(segments, view, options, study, progress):
    """The picture of a projection of the study's grey values, framed as the surface picture of ``segments``."""
    from ._project import depth_range, project

    if study is None:
        raise InputError("a projection draws grey values, which an encoded object does not keep; give the slice "
                         "stack", parameter="projection")
    segments = getattr(segments, "segments", segments)
    if not segments.segment_count:
        raise InputError("the object is empty: no voxel reaches the threshold")
    view = view.fitted(segments.shape, framing_box(segments, options.clip), options.fit)
    slab = None
    if options.slab is not None:
        low, high = depth_range(view, segments.shape)
        mm = float(np.linalg.norm(view.matrix[2] * np.asarray(segments.spacing)))   # a unit of Z' along the view
        thickness = options.slab / mm
        if thickness > high - low:
            raise InputError(f"a slab of {options.slab:g} mm is thicker than the volume seen from this view "
                             f"({(high - low) * mm:.1f} mm); choose a thinner one, or drop it to project the whole "
                             "volume", parameter="slab")
        middle = options.clip.cut_depth if options.clip is not None and options.clip.cut_depth is not None else 0.0
        slab = (middle - thickness / 2, middle + thickness / 2)
    started = time.perf_counter()
    values = project(study.volume.values, view, options.projection, shape=segments.shape, step=study.step,
                     clip=options.clip, slab=slab, progress=progress)
    seconds = {"render": time.perf_counter() - started}
    started = time.perf_counter()
    seen = np.isfinite(values)
    if not seen.any():
        raise InputError("no ray of the projection meets a voxel within the clip limits and slab; widen them",
                         parameter="slab" if slab else "projection")
    if options.window is not None:
        window = options.window
    elif slab or options.clip is not None:          # a part of the study: its own values (a slab's MinIP is no air)
        from .display import auto_window

        window = auto_window(values[seen])
    else:                                           # the whole study: one window for every view of it
        window = study.window(options.projection)
    grey = window.to_uint8(values)
    rgb = np.where(seen[..., None], grey[..., None], np.asarray(options.background, np.uint8)).astype(np.uint8)
    if _marks_apply(options, segments.meta):
        from .marks import draw_marks

        rgb = draw_marks(rgb, view)
    stats = {"projection": options.projection, "window": str(window), "rays_meeting_voxels": int(seen.sum()),
             **({"slab": list(slab)} if slab else {})}
    image = DepthImage(np.where(seen, np.float32(0), np.float32(np.inf)), view, options.projection, stats,
                       seconds["render"])
    table, rows = None, None
    if segments.labels is not None:                     # the labels' list, as a surface picture of them has it
        table = label_table(segments, options.colours)
        rows = _label_rows(segments, table)
        if options.legend:
            from .marks import draw_legend

            rgb = draw_legend(rgb, [(_caption(row), row["colour"]) for row in rows])
    return Picture(rgb, image, {**seconds, "shade": time.perf_counter() - started}, label_table=table,
                   label_rows=rows, values=values, projection=options.projection)


def _why_empty(segments, view, options):
    """Why a picture shows none of the object, and the way out, in words."""
    named = next((f"the {name} view" for name, angles in PRESETS.items()
                  if angles == (view.alpha, view.beta, view.gamma)), None)
    named = named or f"the view at alpha {view.alpha:g}, beta {view.beta:g}, gamma {view.gamma:g}"
    box = framing_box(segments, options.clip)
    (x0, x1), (y0, y1) = view.extent(segments.shape, box)
    height, width = view.size
    (left, right), (top, bottom) = view.pixel_centres(np.array([0, width - 1]), np.array([0, height - 1]))
    if x1 < left or x0 > right or y1 < top or y0 > bottom:
        return f"the object falls outside the picture from {named} at {view.scale:g} pixels per voxel; " \
               "choose a smaller scale, or leave it to be fitted"
    if min(x1 - x0, y1 - y0) * view.scale < 1:
        sizes = [high - low + 1 for low, high in box]
        axis = "zyx"[int(np.argmin(sizes))]
        thin = min(sizes)
        return (f"the object is {thin} voxel{'s' * (thin > 1)} thick along {axis} and edge-on from {named}: "
                f"thinner than a pixel at {view.scale:g} pixels per voxel, so no ray meets it; see it face-on "
                f"from the {' or '.join(FACE_ON[axis])} view, or at a larger scale")
    return f"the picture shows none of the object from {named}"


def label_table(segments, given=None):
    """Name and colour of every label of a multi-label object, and of the patient's outline left out of it
    (``meta["set_aside"]``): ``{label: (name, (r, g, b))}``, from ``given`` (a colour table), else from those kept
    with the object, else the built-in palette (``colours.label_colours``).
    """
    from .colours import label_colours

    present = segments.meta.get("labels") or np.unique(np.asarray(segments.labels)).tolist()
    present = sorted({*present, *(segments.meta.get("set_aside") or [])})   # the outline left out: still listed
    return label_colours(present, segments.meta.get("label_table"), given)


def _label_colours(segments, image, options):
    """The label image of a multi-label picture, its names and colours, and the colour of each pixel (H, W, 3)
    in [0, 1]; the statistics gain the pixels of each label (``label_pixels``).
    """
    from .labels import label_image, label_pixels

    labels = label_image(segments, image, options.clip)
    image.stats["label_pixels"] = {str(k): v for k, v in label_pixels(labels).items()}
    table = label_table(segments, options.colours)
    lookup = np.zeros((max(table) + 1, 3), np.float32)
    for label, (_, rgb) in table.items():
        lookup[label] = np.asarray(rgb, np.float32) / 255
    return labels, table, lookup[labels]
