"""The QC sheet of a study: its surfaces, its slices with the labels over them, its projections and its labels.

A reader who checks a segmentation or a study looks at three things: the 3-D surfaces, the 2-D slices with the
labels over them and, for angiography and PET, a maximum-intensity projection.  :func:`slice_pictures` draws the
slices (:mod:`voxrender.qc.slices`) as ``voxrender slices`` shows them; :func:`qc_sheet` lays out one sheet of all
three, captioned, with a table of the labels (name, colour, voxels, mL).  ``voxrender sheet``, ``voxrender batch
--sheet`` and the library all go through these functions, so the same options give the same pictures.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import InputError

PLACES = ("centroid", "largest")        # --at labels: through each label's centroid, or its largest cross-section


@dataclass(frozen=True)
class SliceOptions:
    """Which slices of a study to draw, and how.

    Parameters
    ----------
    planes : tuple of str
        Of ``"axial"``, ``"coronal"``, ``"sagittal"``, in the order drawn.
    at : SlicePoint, str or None
        Where the slices cross: the volume centre (``None``), a :class:`~voxrender.qc.slices.SlicePoint` (mm or
        voxels), or through each label: ``"centroid"`` or ``"largest"`` (its largest cross-section), a row per
        label.
    window : DisplayWindow, optional
        The grey values' window (default: soft tissue for CT in HU, else the 1st to 99th percentile).
    overlay : {"auto", "fill", "outline", "both"} or None
        How the labels are drawn over the grey values; ``None`` draws none, ``"auto"`` fills them when the study has
        labels.
    opacity : float
        Of the filled labels, in [0, 1].
    size : (H, W)
        Each slice's picture, in pixels (the slice fitted at its true aspect).
    legend : bool
        Name the labels each slice shows.
    """

    planes: tuple = ("axial", "coronal", "sagittal")
    at: object = None
    window: object = None
    overlay: str | None = "auto"
    opacity: float = 0.4
    size: tuple = (512, 512)
    legend: bool = False

    def __post_init__(self):
        from .slices import OVERLAYS, PLANES

        unknown = [p for p in self.planes if p not in PLANES]
        if unknown or not self.planes:
            raise InputError(f"{', '.join(unknown) or 'no plane'}: choose planes of {', '.join(PLANES)}",
                             parameter="slices")
        if isinstance(self.at, str) and self.at not in PLACES:
            raise InputError(f"{self.at!r}: slices through the labels go through each one's {' or '.join(PLACES)}",
                             parameter="at")
        if self.overlay not in ("auto", None, *OVERLAYS):
            raise InputError(f"{self.overlay!r}: draw the labels as one of {', '.join(OVERLAYS)}", parameter="overlay")
        if not 0 <= self.opacity <= 1:
            raise InputError(f"{self.opacity:g} must lie between 0 and 1", parameter="opacity")


def default_window(volume):
    """The window slices of ``volume`` are shown through when none is given: soft tissue for CT in HU (as DICOM says,
    or as the values show: air at about -1000), else the 1st to 99th percentile of its values.
    """
    from ..pictures.display import CT_WINDOWS, auto_window

    if volume.meta.get("units") == "HU":
        return CT_WINDOWS["soft-tissue"]
    values = np.asarray(volume.values[::max(1, volume.shape[0] // 16)])      # a few slices tell
    finite = values[np.isfinite(values)] if values.dtype.kind == "f" else values.ravel()
    air = np.count_nonzero((finite >= -1100) & (finite <= -900))       # a NIfTI CT, which names no unit (its air)
    if finite.size and air >= 0.01 * finite.size and finite.max() >= 200:
        return CT_WINDOWS["soft-tissue"]
    return auto_window(volume.values)


def slice_pictures(study, options=None, colours=None):
    """The slices of a study, as ``voxrender slices`` draws them.

    Parameters
    ----------
    study : Study
        From :func:`voxrender.qc.study.load_study`.
    options : SliceOptions, optional
    colours : dict, optional
        ``{label: (name, (r, g, b))}``, ahead of the label map's own names and colours.

    Returns
    -------
    list of rows, each a list of ``(caption, rgb)``
        One row of the planes, or one per label with ``at`` ``"centroid"`` or ``"largest"``.

    Examples
    --------
    >>> from voxrender.io import Volume
    >>> from voxrender.qc.study import Study
    >>> study = Study(Volume(np.arange(60.0).reshape(3, 4, 5), (1.0, 1.0, 2.0)))
    >>> rows = slice_pictures(study, SliceOptions(size=(32, 32)))
    >>> [caption for caption, _ in rows[0]], rows[0][0][1].shape
    (['axial 2 of 3', 'coronal 3 of 4', 'sagittal 3 of 5'], (32, 32, 3))
    """
    from ..pictures.marks import edge_letters
    from ..space.orient import in_patient_frame
    from ..space.view import View
    from .slices import PLANES, label_slices, plane_image, slice_index, slice_picture

    options = options or SliceOptions()
    volume, labels = study.volume, study.labels
    overlay = options.overlay
    if overlay == "auto":
        overlay = None if labels is None else "fill"
    if overlay is not None and labels is None:
        raise InputError("an overlay draws labels, and this input has none; give its label map, or draw no overlay",
                         parameter="overlay")
    if isinstance(options.at, str) and labels is None:
        raise InputError("slices through the labels need labels; give a label map, or a point", parameter="at")
    table = study.label_table(colours) if labels is not None else None
    window = options.window or default_window(volume)
    grey = volume.values if study.has_grey else np.broadcast_to(np.uint8(0), volume.shape)   # a label map alone
    opacity = options.opacity if study.has_grey else 1.0         # nothing to see through the labels: full colours
    framed = in_patient_frame(volume.meta)           # else (kept in its stored order) its edges have no directions

    def draw(plane, index, caption):
        image, pixel_mm = plane_image(grey, volume.spacing, plane, index)
        label_slice = None if labels is None else plane_image(labels, volume.spacing, plane, index)[0]
        shared = None if study.codes is None else (plane_image(study.codes, volume.spacing, plane, index)[0],
                                                   study.sets)
        letters = edge_letters(View.preset(PLANES[plane])) if framed else None
        rgb = slice_picture(image, pixel_mm, window, label_slice, table, overlay, opacity, options.size, letters,
                            True, options.legend, shared=shared, envelopes=study.envelopes)
        return caption, rgb

    if not isinstance(options.at, str):
        indices = {plane: slice_index(volume, plane, options.at) for plane in PLANES}   # the point lies inside
        return [[draw(plane, indices[plane], f"{plane} {_numbered(volume, plane, indices[plane])}")
                 for plane in options.planes]]
    places = {plane: label_slices(labels, plane, options.at) for plane in options.planes}
    rows = []
    for label, (name, _) in table.items():
        if label not in places[options.planes[0]]:
            continue
        rows.append([draw(plane, places[plane][label],
                          f"{name}, {plane} {_numbered(volume, plane, places[plane][label])}")
                     for plane in options.planes])
    return rows


def _numbered(volume, plane, index):
    """A slice's number for its caption: counted from 1 in the input, as a point in voxels names it (a cropped
    volume's slices from the crop's corner), "of N" when the volume is not cropped.
    """
    from .slices import plane_axes

    normal = plane_axes(plane)[0]                       # the object axis (x, y, z) the plane is across
    corner = volume.meta.get("crop_corner")
    if corner is None:
        return f"{index + 1} of {volume.shape[2 - normal]}"
    return f"{index + corner[normal] + 1}"


def label_rows(study, colours=None):
    """Each label of the study with its name, colour, voxels and mL, counted on the image's grid, where the slices
    show them (:func:`voxrender.pictures.labels.label_list`).
    """
    from ..pictures.labels import label_list

    if study.labels is None:
        return []
    return label_list(study.label_table(colours), study.label_voxels(), study.volume.spacing)


def table_picture(rows, width, overlaps=(), line=14):
    """The labels as a picture ``width`` pixels wide: a swatch, the number, the name, voxels and mL of each row of
    :func:`label_rows`, in as many columns as fit; then the overlapping pairs, flagged.

    >>> table_picture([{"label": 1, "name": "liver", "colour": [40, 140, 40], "voxels": 10, "ml": 0.01}], 300).shape
    (38, 300, 3)
    """
    from PIL import Image, ImageDraw

    entries = [(f"{row['label']:>3} {row['name'][:28]:<28} {row['voxels']:>10} vx {row['ml']:>10.2f} mL",
                row["colour"], row["voxels"] == 0) for row in rows]
    entries += [(f"overlap: {' and '.join(pair['names'])}: {pair['voxels']} voxels", None, True) for pair in overlaps]
    column = 6 * 62 + 24
    columns = max(1, width // column)
    per_column = -(-len(entries) // columns) if entries else 0
    height = 10 + line * (per_column + 1)
    image = Image.new("RGB", (width, height), (0, 0, 0))
    draw = ImageDraw.Draw(image)
    draw.text((4, 4), f"{len(rows)} labels" + (f", {len(overlaps)} overlapping pairs" if overlaps else ""),
              fill=(230, 230, 230))
    for k, (text, colour, flagged) in enumerate(entries):
        left, top = 4 + (k // per_column) * column, 4 + line * (1 + k % per_column)
        if colour is not None:
            draw.rectangle((left, top + 2, left + 9, top + 11), fill=tuple(int(c) for c in colour))
        draw.text((left + 14, top), text, fill=(255, 120, 90) if flagged else (230, 230, 230))
    return np.asarray(image)


def qc_sheet(study, options, views, slices=None, title=None, progress=None):
    """One sheet of a study: its surfaces from ``views``, its slices, its projections and a table of its labels.

    Parameters
    ----------
    study : Study
        With its encoded object (:func:`voxrender.qc.study.load_study` with ``encode=True``).
    options : RenderOptions
        Of the surfaces; with ``projection``, a row of that projection from each view follows them, framed as
        they are.
    views : list of (label, (alpha, beta, gamma))
    slices : SliceOptions, optional
        The slices' row (none when ``None``).
    title : str, optional
        A line at the top.
    progress : callable, optional

    Returns
    -------
    ndarray of uint8, (H, W, 3)
    """
    from .._render import octree_for
    from ..pictures import picture
    from .sheet import framed_views, sheet

    encoded = study.encoded
    surface = replace(options, projection=None, slab=None, window=None)
    chosen = framed_views(encoded.segments, surface, views)
    tree = octree_for(surface.method, encoded)
    rows = [[(label, picture(encoded.segments, view, surface, progress, tree).rgb)
             for (label, _), view in zip(views, chosen, strict=True)]]
    if options.drawn.grey_values:
        rows.append([(f"{options.drawn.name}, {label}", picture(encoded.segments, view, options, progress,
                                                                 study=study).rgb)
                     for (label, _), view in zip(views, chosen, strict=True)])
    if slices is not None:
        rows += slice_pictures(study, replace(slices, size=tuple(options.size)), options.colours)
    grid = sheet([[rgb for _, rgb in row] for row in rows], [[caption for caption, _ in row] for row in rows])
    parts = [_title(title, grid.shape[1])] if title else []
    parts.append(grid)
    if study.labels is not None:
        parts.append(table_picture(label_rows(study, options.colours), grid.shape[1], study.overlaps))
    return np.concatenate(parts)


def _title(text, width, height=20):
    """A band ``width`` pixels wide with ``text`` on it."""
    from PIL import Image, ImageDraw

    image = Image.new("RGB", (width, height), (0, 0, 0))
    ImageDraw.Draw(image).text((4, 4), text, fill=(255, 255, 255))
    return np.asarray(image)
