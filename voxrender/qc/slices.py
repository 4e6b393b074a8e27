"""Slices: the axial, coronal and sagittal planes through a volume, with its labels drawn over them.

A reader who checks a segmentation looks at slices with the labels over them. Each plane is drawn as a view
preset of :data:`voxrender.space.view.PRESETS` sees it (:data:`PLANES`): axial from the feet (radiological: the
patient's left on the picture's right, the front up), coronal from the front and sagittal from the patient's left
(the head up). :func:`plane_image` takes a plane out of the canonical ``values[z, y, x]`` (LPS) and turns it so;
:func:`slice_picture` puts it on a screen in its true aspect, through a display window, with the labels filled or
outlined, the orientation letters, a scale bar and a legend.

Examples
--------
>>> import numpy as np
>>> from voxrender.pictures.display import DisplayWindow
>>> values = np.zeros((4, 6, 8), np.float32)                   # z, y, x
>>> image, pixel_mm = plane_image(values, (1.0, 1.0, 2.0), "coronal", 3)
>>> image.shape, pixel_mm                                      # rows run down from the head, columns along x
((4, 8), (2.0, 1.0))
>>> slice_picture(image, pixel_mm, DisplayWindow(0, 100), overlay=None, scale_bar=False).shape
(8, 8, 3)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

# Each plane is drawn as that view preset sees it.
PLANES = {"axial": "inferior", "coronal": "anterior", "sagittal": "left"}
OVERLAYS = ("fill", "outline", "both")
_AXIS_NAMES = "xyz"


@dataclass(frozen=True)
class SlicePoint:
    """Where the slices cross: a point in patient mm (LPS, ``unit="mm"``) or in voxel indices ``(x, y, z)`` of the
    canonical grid (``unit="voxel"``).

    >>> SlicePoint(10, -20.5, 30)
    SlicePoint(x=10, y=-20.5, z=30, unit='mm')
    """

    x: float
    y: float
    z: float
    unit: str = "mm"

    def __post_init__(self):
        if self.unit not in ("mm", "voxel"):
            raise InputError(f"the unit {self.unit!r} is neither 'mm' nor 'voxel'", parameter="at")
        if not all(math.isfinite(v) for v in (self.x, self.y, self.z)):
            raise InputError(f"{self.x}, {self.y}, {self.z} must be three finite numbers", parameter="at")


def plane_axes(plane):
    """``(normal, (row, row_sign), (column, column_sign))``: the object axes (0 x, 1 y, 2 z) of ``plane``, taken
    from its view preset's rotation (image axis ``X'`` is the picture's columns, ``Y'`` its rows, ``Z'`` the
    viewing direction), so the slices read exactly as the renderers' pictures of that preset.
    """
    from ..space.view import View

    if plane not in PLANES:
        raise InputError(f"unknown plane {plane!r}; choose one of {', '.join(PLANES)}", parameter="slices")
    r = View.preset(PLANES[plane]).matrix                   # row i: image axis i in object coordinates
    column, row, normal = (int(np.argmax(np.abs(r[i]))) for i in range(3))
    return normal, (row, int(np.sign(r[1, row]))), (column, int(np.sign(r[0, column])))


def slice_index(volume, plane, at=None):
    """The index of ``plane``'s slice along its normal axis (x, y or z) of ``volume``'s grid.

    Parameters
    ----------
    volume : voxrender.io.Volume
        The volume, in the canonical frame (as :func:`voxrender.io.read_volume` gives it).
    plane : {"axial", "coronal", "sagittal"}
        The plane (see :data:`PLANES`).
    at : SlicePoint, optional
        The point the slice goes through: in mm, through the inverse of :func:`voxrender.space.grids.patient_affine`; in
        voxels of the input, as it is (a cropped volume's ``meta["crop_corner"]`` is where its first voxel lay).
        ``None``: the middle slice (``n // 2`` of ``n``).

    Returns
    -------
    int
        The slice whose voxel holds the point.

    Raises
    ------
    InputError
        (``parameter="at"``) when the point lies outside the volume along the plane's normal; the message gives
        the volume's extent there, in the point's unit.

    Examples
    --------
    >>> from voxrender.io import Volume
    >>> volume = Volume(np.zeros((10, 4, 4)), (1.0, 1.0, 2.5), {"origin": [0.0, 0.0, -10.0]})
    >>> slice_index(volume, "axial"), slice_index(volume, "axial", SlicePoint(0, 0, 3, unit="voxel"))
    (5, 3)
    >>> slice_index(volume, "axial", SlicePoint(0, 0, 1.0))          # z = -10 + 2.5 * 4.4 mm
    4
    """
    normal, _, _ = plane_axes(plane)
    count = volume.shape[2 - normal]
    if at is None:
        return count // 2
    point = np.array([at.x, at.y, at.z], dtype=float)
    if at.unit == "mm":
        from ..space.grids import patient_affine

        affine = patient_affine(volume)
        voxel = np.linalg.solve(affine[:3, :3], point - affine[:3, 3])
    else:                   # voxels of the input: of a cropped volume, from the crop's corner (study.cropped)
        corner = np.asarray(volume.meta.get("crop_corner", (0, 0, 0)), float)
        voxel = point - corner
    position = float(voxel[normal])
    if not -0.5 <= position <= count - 0.5:           # a voxel is the closed unit cube about its grid point
        if at.unit == "mm":
            ends = [affine[:3, :3] @ np.where(np.arange(3) == normal, end, voxel) + affine[:3, 3]
                    for end in (0, count - 1)]
            low, high = sorted(float(end[normal]) for end in ends)
            extent = f"{_AXIS_NAMES[normal]} from {low:g} to {high:g} mm"
        else:
            extent = f"{_AXIS_NAMES[normal]} from {corner[normal]:g} to {corner[normal] + count - 1:g}"
        raise InputError(f"{at.x:g}, {at.y:g}, {at.z:g} ({at.unit}) lies outside the volume for the {plane} slice: "
                         f"its slices run along {extent}; give a point within them", parameter="at")
    return min(int(math.floor(position + 0.5)), count - 1)


def label_slices(labels, plane, how="centroid"):
    """For each label present, the ``plane`` slice that shows it best.

    Parameters
    ----------
    labels : (nz, ny, nx) array of int
        The label map in the canonical frame, 0 the background.
    plane : {"axial", "coronal", "sagittal"}
        The plane (see :data:`PLANES`).
    how : {"centroid", "largest"}
        The slice through the label's centroid, or the one where its cross-section is largest (the first of
        equals).

    Returns
    -------
    dict
        ``{label: index}`` along the plane's normal axis, in the order of the labels.

    Examples
    --------
    >>> labels = np.zeros((5, 3, 3), np.uint8)
    >>> labels[1:4, 1, 1] = 2
    >>> labels[4, 0] = 2                                     # three voxels in the last slice
    >>> label_slices(labels, "axial"), label_slices(labels, "axial", how="largest")
    ({2: 3}, {2: 4})
    """
    if how not in ("centroid", "largest"):
        raise InputError(f"unknown choice {how!r}; choose 'centroid' or 'largest'", parameter="at")
    normal, _, _ = plane_axes(plane)
    labels = np.asarray(labels)
    if labels.ndim != 3 or labels.dtype.kind not in "iub":
        raise InputError(f"the labels must be a 3-D array of whole numbers, not {labels.dtype} of shape "
                         f"{labels.shape}", parameter="labels")
    if labels.size == 0 or not labels.any():
        return {}
    if labels.dtype.kind == "i" and labels.min() < 0:
        raise InputError("the labels hold negative numbers; labels are 0 (background) or above", parameter="labels")
    # the voxels of each label in each slice: one bincount a slice (a loop over slices, not voxels), of which only
    # the labels the slice holds are kept, so large label numbers cost no (labels x slices) table
    found = []
    for sheet in np.moveaxis(labels, 2 - normal, 0):
        count = np.bincount(sheet.ravel())
        held = np.flatnonzero(count[1:]) + 1
        found.append((held, count[held]))
    present = np.unique(np.concatenate([held for held, _ in found]))
    counts = np.zeros((present.size, len(found)), np.int64)
    for index, (held, count) in enumerate(found):
        counts[np.searchsorted(present, held), index] = count
    if how == "largest":
        chosen = counts.argmax(axis=1)
    else:
        chosen = np.floor(counts @ np.arange(counts.shape[1]) / counts.sum(axis=1) + 0.5).astype(int)
    return dict(zip(present.tolist(), chosen.tolist(), strict=True))


def plane_image(values, spacing, plane, index):
    """Slice ``index`` of ``plane`` through ``values[z, y, x]``, turned to read as that plane's view preset sees it.

    Parameters
    ----------
    values : (nz, ny, nx) array
        The volume in the canonical frame (LPS: x toward the patient's left, y toward the back, z toward the head).
    spacing : (sx, sy, sz)
        Voxel size in mm.
    plane : {"axial", "coronal", "sagittal"}
        Axial as seen from the feet (the patient's left on the right, the front up), coronal from the front and
        sagittal from the patient's left (the head up); see :data:`PLANES`.
    index : int
        The slice along the plane's normal (:func:`slice_index`).

    Returns
    -------
    image : 2-D array
        A view of ``values`` (not a copy), row 0 at the picture's top.
    pixel_mm : (row_mm, column_mm)
        The size of its pixels.

    Examples
    --------
    >>> values = np.arange(8).reshape(2, 2, 2)                  # values[z, y, x]
    >>> plane_image(values, (1, 1, 1), "sagittal", 1)[0]        # the head up, the front (y = 0) on the left
    array([[5, 7],
           [1, 3]])
    """
    normal, (row, row_sign), (column, column_sign) = plane_axes(plane)
    values = np.asarray(values)
    count = values.shape[2 - normal]
    if not 0 <= index < count or int(index) != index:
        raise InputError(f"slice {index} is not one of the {count} {plane} slices (0 to {count - 1})",
                         parameter="at")
    image = np.take(values, int(index), axis=2 - normal)              # the two remaining axes, in [z, y, x] order
    kept = [axis for axis in (2, 1, 0) if axis != normal]              # their object axes, likewise
    if kept.index(row) != 0:
        image = image.T
    image = image[::row_sign, ::column_sign]
    return image, (float(spacing[row]), float(spacing[column]))


def slice_picture(grey, pixel_mm, window, labels=None, table=None, overlay="fill", opacity=0.4, size=None,
                  letters=None, scale_bar=True, legend=False, background=(0, 0, 0), shared=None, envelopes=()):
    """A slice on a screen: its grey values through ``window``, in true aspect, with its labels over it.

    Parameters
    ----------
    grey : (h, w) array
        A slice from :func:`plane_image`, of any dtype.
    pixel_mm : (row_mm, column_mm)
        The size of its pixels in mm.
    window : voxrender.pictures.display.DisplayWindow
        The grey-to-8-bit mapping (:data:`voxrender.pictures.display.CT_WINDOWS`,
        :func:`voxrender.pictures.display.auto_window`).
    labels : (h, w) array of int, optional
        The label slice on the same grid, 0 the background.
    table : dict, optional
        ``{label: (name, (r, g, b))}``, as :func:`voxrender.pictures._picture.label_table` gives; labels missing from it
        take :func:`voxrender.pictures.colours.label_colours`.
    overlay : {"fill", "outline", "both"} or None
        Labels filled at ``opacity``, outlined one screen pixel wide in their full colour, or both; ``None``: the
        grey slice alone (an overlay without ``labels`` is refused).
    opacity : float
        The fill's weight in [0, 1]: a filled pixel is ``(1 - opacity) * grey + opacity * colour``.
    size : (H, W), optional
        The picture's size: the slice fitted into it, centred, with ``background`` around it. ``None``: the slice
        at its finer pixel spacing.
    letters : dict, optional
        ``{"left", "right", "top", "bottom"} -> text`` written at the middle of each edge, e.g.
        ``voxrender.pictures.marks.edge_letters(View.preset(PLANES[plane]))``.
    scale_bar : bool
        A bar of a round length (1, 2, 5, 10, 20, 50 ... mm), about a fifth of the picture's width, with its length
        written, at the bottom right.
    legend : bool
        A legend (:func:`voxrender.pictures.marks.draw_legend`) of the labels this slice shows.
    background : (r, g, b)
        The colour around a fitted slice.
    shared : (codes, sets), optional
        Where structures share voxels, the label codes of the slice on the same grid and their sets
        (:mod:`voxrender._shared.label_sets`): each structure that shares voxels is then outlined by its own
        boundary (BODY by the skin, not around every organ inside it), not by the edge of what ``labels`` shows.
    envelopes : sequence of int
        Labels of the patient's outline (BODY, External): outlined, never filled, whatever the overlay, so they
        do not tint everything inside them.

    Returns
    -------
    (H, W, 3) uint8 array
        The picture. Its pixels are square in mm: the grey values are resampled linearly, the labels to the
        nearest, and the outlines are found after resampling, so they stay one pixel wide at any size.

    Examples
    --------
    >>> from voxrender.pictures.display import DisplayWindow
    >>> grey = np.zeros((2, 4))
    >>> labels = np.array([[0, 1, 1, 0], [0, 1, 1, 0]])
    >>> picture = slice_picture(grey, (2.0, 1.0), DisplayWindow(0, 2), labels, {1: ("ball", (200, 0, 0))},
    ...                         opacity=0.5, scale_bar=False)
    >>> picture.shape, picture[0, 1].tolist(), picture[0, 0].tolist()
    ((4, 4, 3), [164, 64, 64], [128, 128, 128])
    """
    grey, (row_mm, column_mm), labels = _checked(grey, pixel_mm, labels, overlay, opacity)
    canvas, shown, mm = _fitted(grey.shape, row_mm, column_mm, size)
    top, left = (canvas[0] - shown[0]) // 2, (canvas[1] - shown[1]) // 2

    picture = np.empty((*canvas, 3), np.uint8)
    picture[...] = np.asarray(background, np.uint8)
    inside = picture[top:top + shown[0], left:left + shown[1]]
    inside[...] = window.to_uint8(_resample_linear(grey, shown))[..., None]

    if labels is not None:
        members = [k for m in (shared[1].values() if shared is not None else ()) for k in m]
        lookup, table = _colour_lookup(labels, table, max([*members, *envelopes], default=0))
        if overlay is not None:
            if shared is not None:
                shared = (_resample_nearest(np.asarray(shared[0]), shown), shared[1])
            _draw_overlay(inside, _resample_nearest(labels, shown), lookup, overlay, opacity, shared, envelopes)
    if letters:
        from ..pictures.marks import draw_letters

        picture = draw_letters(picture, letters)
    if scale_bar:
        picture = _draw_scale_bar(picture, mm)
    if legend and labels is not None:
        from ..pictures.marks import draw_legend

        entries = [table[int(v)] for v in np.flatnonzero(np.bincount(labels.ravel())) if v]
        if entries:
            picture = draw_legend(picture, entries)
    return picture


def _checked(grey, pixel_mm, labels, overlay, opacity):
    """:func:`slice_picture`'s inputs checked: the grey slice and labels as arrays (a mask as label 1) and the pixel
    sizes in mm as floats.
    """
    grey = np.asarray(grey)
    if grey.ndim != 2 or grey.size == 0:
        raise InputError(f"the slice must be a 2-D image, not of shape {grey.shape}", parameter="grey")
    if overlay is not None and overlay not in OVERLAYS:
        raise InputError(f"unknown overlay {overlay!r}; choose one of {', '.join(OVERLAYS)}", parameter="overlay")
    if not 0 <= opacity <= 1:
        raise InputError(f"{opacity} is not within 0 to 1 (0 clear, 1 solid colour)", parameter="opacity")
    row_mm, column_mm = (float(v) for v in pixel_mm)
    if not (row_mm > 0 and column_mm > 0 and math.isfinite(row_mm) and math.isfinite(column_mm)):
        raise InputError(f"{pixel_mm} must be two positive pixel sizes in mm", parameter="pixel_mm")
    if labels is not None:
        labels = np.asarray(labels)
        labels = labels.view(np.uint8) if labels.dtype == bool else labels         # a mask: label 1
        if labels.shape != grey.shape or labels.dtype.kind not in "iu":
            raise InputError(f"the labels ({labels.dtype}, {labels.shape}) must be whole numbers on the slice's grid "
                             f"{grey.shape}", parameter="labels")
        if labels.dtype.kind == "i" and labels.size and labels.min() < 0:
            raise InputError("the labels hold negative numbers; labels are 0 (background) or above",
                             parameter="labels")
    elif overlay is not None:
        raise InputError(f"the {overlay!r} overlay needs labels; give the label slice, or overlay None for the grey "
                         "slice alone", parameter="overlay")

    return grey, (row_mm, column_mm), labels


def _fitted(shape, row_mm, column_mm, size):
    """The canvas, the size the slice is shown at within it (true aspect) and the mm a shown pixel spans: the slice
    at its finer spacing without a ``size``, else fitted into it.
    """
    height, width = shape
    if size is None:
        mm = min(row_mm, column_mm)                                    # the finer spacing: no detail is lost
        shown = (max(round(height * row_mm / mm), 1), max(round(width * column_mm / mm), 1))
        canvas = shown
    else:
        canvas = (int(size[0]), int(size[1]))
        if canvas[0] < 1 or canvas[1] < 1:
            raise InputError(f"{size} must be at least 1 x 1 pixels", parameter="size")
        mm = max(height * row_mm / canvas[0], width * column_mm / canvas[1])
        shown = (min(max(round(height * row_mm / mm), 1), canvas[0]), min(max(round(width * column_mm / mm), 1),
                                                                          canvas[1]))
    return canvas, shown, mm


def _resample_linear(grey, shape):
    """``grey`` as float32 resampled to ``shape`` (bilinear, pixel centres to pixel centres; averaged when it
    shrinks).
    """
    values = np.ascontiguousarray(grey, np.float32)
    if values.shape == tuple(shape):
        return values
    from PIL import Image

    return np.asarray(Image.fromarray(values, mode="F").resize(shape[::-1], Image.Resampling.BILINEAR))


def _resample_nearest(labels, shape):
    """``labels`` resampled to ``shape``: each screen pixel takes the label of the slice pixel its centre lies in."""
    rows = ((np.arange(shape[0]) + 0.5) * labels.shape[0] / shape[0]).astype(np.intp)
    columns = ((np.arange(shape[1]) + 0.5) * labels.shape[1] / shape[1]).astype(np.intp)
    return labels[np.minimum(rows, labels.shape[0] - 1)[:, None], np.minimum(columns, labels.shape[1] - 1)]


def _colour_lookup(labels, table, top=0):
    """A colour for every label value up to the largest present or ``top`` (``(top + 1, 3)`` uint8, a lookup
    table), and the table completed with :func:`voxrender.pictures.colours.label_colours` for the labels it lacks.
    """
    from ..pictures.colours import label_colours

    counts = np.bincount(labels.ravel(), minlength=top + 1)
    present = np.flatnonzero(counts)
    table = dict(table or {})
    missing = [int(v) for v in present if v and int(v) not in table]
    if missing:
        table.update(label_colours(missing))
    lookup = np.zeros((counts.size, 3), np.uint8)
    for label, (_, colour) in table.items():            # cheap per-label work: one row of the lookup table
        if 0 < label < counts.size:
            lookup[label] = colour
    return lookup, table


def _draw_overlay(rgb, labels, lookup, overlay, opacity, shared=None, envelopes=()):
    """Draw ``labels`` into ``rgb`` (in place): filled at ``opacity``, outlined, or both; the ``envelopes`` only
    outlined; a structure that shares voxels (``shared``) outlined by its own boundary.
    """
    # one gather of packed 32-bit colours is ten times faster than gathering rows of three bytes
    packed = np.zeros((len(lookup), 4), np.uint8)
    packed[:, :3] = lookup
    colours = packed.view(np.uint32).ravel()[labels].view(np.uint8).reshape(*labels.shape, 4)[..., :3]
    envelopes = [int(k) for k in envelopes if 0 < int(k) < len(lookup)]
    if overlay in ("fill", "both") and opacity > 0:
        weight = np.full(len(lookup), opacity, np.float32)
        weight[0] = 0                                               # the background keeps its grey
        weight[envelopes] = 0                                       # the outline of the patient: not a tint
        under = rgb.astype(np.float32)
        under += weight[labels][..., None] * (colours - under)
        rgb[...] = np.rint(under, out=under).astype(np.uint8)
    outlined = range(1, len(lookup)) if overlay in ("outline", "both") else envelopes
    if not len(outlined):
        return
    from skimage.segmentation import find_boundaries

    codes, sets = shared if shared is not None else (None, {})
    apart = sorted({k for members in sets.values() for k in members} & set(outlined))   # their own boundaries
    alone = np.zeros(len(lookup), bool)
    alone[list(outlined)] = True
    alone[apart] = False
    # "inner": the label's own pixels next to another label or the background, so one pixel wide
    edge = find_boundaries(labels, mode="inner") & alone[labels]
    rgb[edge] = colours[edge]
    if apart:
        from .._shared.label_sets import member_mask

        own = {label: member_mask(codes, sets, label) for label in apart}     # the few structures that share
        for label in sorted(apart, key=lambda k: -int(own[k].sum())):          # the largest first, under the rest
            rgb[find_boundaries(own[label], mode="inner")] = lookup[label]


def round_length(mm):
    """The round length (1, 2 or 5 times a power of ten) nearest ``mm`` on a log scale: a scale bar's length.

    >>> round_length(0.3), round_length(42.0), round_length(140.0), round_length(380.0)
    (0.2, 50.0, 100.0, 500.0)
    """
    power = 10.0 ** math.floor(math.log10(mm))
    steps = np.array([1.0, 2.0, 5.0, 10.0])
    best = steps[np.argmin(np.abs(np.log(steps * power / mm)))]
    return float(f"{best * power:.6g}")


def _draw_scale_bar(rgb, mm_per_pixel, colour=(255, 255, 255)):
    """``rgb`` with a scale bar in its lower right corner: a round length about a fifth of its width, written."""
    from PIL import Image, ImageDraw

    height, width = rgb.shape[:2]
    length = round_length(width * mm_per_pixel / 5)
    pixels = int(round(length / mm_per_pixel))
    if pixels < 2 or height < 24 or pixels > width - 8:
        return rgb                                                  # no room for a bar that can be read
    image = Image.fromarray(np.ascontiguousarray(rgb))
    draw = ImageDraw.Draw(image)
    right, bottom = width - 6, height - 6
    draw.rectangle((right - pixels, bottom - 4, right + 1, bottom + 1), fill=(0, 0, 0))          # a dark rim
    draw.rectangle((right - pixels + 1, bottom - 3, right, bottom), fill=tuple(colour))        # `pixels` wide
    text = f"{length:g} mm"
    draw.text((right - draw.textlength(text), bottom - 16), text, fill=tuple(colour), stroke_width=1,
              stroke_fill=(0, 0, 0))
    return np.asarray(image)
