"""How a segmentation agrees with a reference segmentation of the same image, label by label.

Both are any label source voxrender reads (a label map, a folder of masks, a DICOM SEG, an RTSTRUCT), each paired
with the image by patient position and placed on its grid.  Their labels are matched by name
(:func:`voxrender._shared.label_sets.label_key`: ``hip right`` is ``hip_right``), unnamed ones by number; each
structure is its own mask (a structure inside another keeps its voxels).  Per structure, in its bounding box: Dice,
both volumes and their difference, HD95, ASSD and the normalised surface Dice (:mod:`voxrender.review.surfaces`),
and the pieces of each.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .. import io
from .._shared import label_sets
from ..errors import InputError
from . import surfaces

# The columns of a metrics table, in order (agreement.csv, --metrics-out).
COLUMNS = ("name", "label", "reference_label", "present", "dice", "nsd", "hd95_mm", "assd_mm", "volume_ml",
           "reference_ml", "volume_diff_ml", "volume_diff_percent", "components", "reference_components")


# The classes of an agreement picture: a voxel both hold, the test alone, the reference alone.
CLASSES = {1: ("both", (90, 200, 90)), 2: ("test only", (240, 70, 60)), 3: ("reference only", (70, 130, 240))}


def agreement(image, test, reference, *, tolerance_mm=2.0, read=None):
    """The agreement of ``test`` with ``reference`` on ``image``, a record a structure.

    Parameters
    ----------
    image : path or Volume
        The image both segment (its grid is the one they are compared on).
    test, reference : path or Volume
        Label sources of the image: a label map, a folder of masks, a DICOM SEG, an RTSTRUCT; or a Volume of labels
        on the image's grid.
    tolerance_mm : float
        The tolerance of the normalised surface Dice, in mm.
    read : voxrender.ReadOptions, optional
        How to read the image.

    Returns
    -------
    list of dict
        One record a structure (the columns of ``COLUMNS``), the worst first (by Dice, then by name): a structure on
        one side only has Dice 0 and no surface distances (``nan``), and says so in ``present``.

    Examples
    --------
    >>> from voxrender.io import Volume
    >>> image = Volume(np.zeros((8, 8, 8), np.int16), (1.0, 1.0, 2.0))
    >>> labels = np.zeros((8, 8, 8), np.uint8); labels[2:6, 2:6, 2:6] = 1
    >>> row = agreement(image, Volume(labels, image.spacing), Volume(labels, image.spacing))[0]
    >>> row["dice"], row["nsd"], row["hd95_mm"], row["volume_diff_ml"]
    (1.0, 1.0, 0.0, 0.0)
    """
    return Comparison(image, test, reference, read).metrics(tolerance_mm)


class Comparison:
    """Two segmentations of one image on its grid, their structures matched by name: what :func:`agreement`
    measures and :meth:`picture` draws (the parameters are :func:`agreement`'s).
    """

    def __init__(self, image, test, reference, read=None):
        from ..object.pipeline import ReadOptions

        self.volume = image if isinstance(image, io.Volume) else (read or ReadOptions()).read(image)
        self.sides = [_on_grid(source, self.volume, read, parameter)
                      for source, parameter in ((test, "labels_from"), (reference, "reference"))]
        self.boxes = [label_sets.structure_boxes(values, meta.get("label_sets") or {})
                      for values, meta in self.sides]
        self.structures = [_structures(boxes, meta) for boxes, (_, meta) in zip(self.boxes, self.sides, strict=True)]
        self.keys = list(dict.fromkeys([*self.structures[1], *self.structures[0]]))   # the reference's order first

    @classmethod
    def of_study(cls, study, reference, read=None):
        """The comparison of a :class:`~voxrender.qc.study.Study`'s labels with ``reference``: its image and the label
        source it already paired with it (:attr:`~voxrender.qc.study.Study.paired`, all its labels, before any crop),
        so that neither is read or placed again; only the reference is.
        """
        if study.paired is None:
            raise InputError("a reference is held against labels: give the labels too (labels_from)",
                             parameter="reference")
        return cls(study.image, study.paired, reference, read)

    def masks(self, key):
        """The structure ``key``'s box (slices of the image's grid) and its test and reference masks in it."""
        found = [s.get(key) for s in self.structures]
        box = label_sets.union_box([self.boxes[k].get(found[k][0]) if found[k] else None for k in range(2)])
        masks = [label_sets.member_mask(values[box], meta.get("label_sets") or {}, found[k][0]) if found[k]
                 else np.zeros(tuple(b.stop - b.start for b in box), bool)
                 for k, (values, meta) in enumerate(self.sides)]
        return found, box, masks

    def metrics(self, tolerance_mm=2.0):
        """:func:`agreement`'s records."""
        if not (isinstance(tolerance_mm, (int, float)) and math.isfinite(tolerance_mm) and tolerance_mm >= 0):
            raise InputError(f"{tolerance_mm!r} is not a distance in mm (0 or more)", parameter="tolerance_mm")
        voxel_ml = float(np.prod(self.volume.spacing)) / 1000
        rows = []
        for key in self.keys:
            found, _, masks = self.masks(key)
            rows.append({**_row(found, masks, self.volume.spacing, voxel_ml, tolerance_mm), "key": key})
        return sorted(rows, key=lambda r: (r["dice"], r["name"]))

    def classes(self):
        """The image's grid with :data:`CLASSES` of every structure: where they agree, and where one side alone
        holds one (a disagreement shows over an agreement of another structure).
        """
        classes = np.zeros(self.volume.shape, np.uint8)
        for key in self.keys:
            _, box, masks = self.masks(key)
            classes[box] = np.maximum(classes[box], _classes(*masks))
        return classes

    def picture(self, rows, size=(256, 256), worst=4):
        """A sheet: for each of the ``worst`` structures of ``rows`` (:meth:`metrics`), its axial, coronal and
        sagittal slices through the middle of both and its surface from the front, it alone in :data:`CLASSES` with
        a legend; then the metrics table.
        """
        from ..qc.qc import default_window
        from ..qc.sheet import sheet
        from ..qc.slices import PLANES, plane_axes, plane_image, slice_picture

        window = default_window(self.volume)
        pictures, captions = [], []
        for row in rows[:worst]:
            _, box, masks = self.masks(row["key"])
            classes = np.zeros(self.volume.shape, np.uint8)      # this structure alone
            classes[box] = _classes(*masks)
            middle = [(b.start + b.stop - 1) // 2 for b in box][::-1]               # x, y, z
            line, words = [], []
            for plane in PLANES:
                index = middle[plane_axes(plane)[0]]
                grey, pixel_mm = plane_image(self.volume.values, self.volume.spacing, plane, index)
                labels = plane_image(classes, self.volume.spacing, plane, index)[0]
                line.append(slice_picture(grey, pixel_mm, window, labels, CLASSES, "both", 0.45, size,
                                          legend=True))
                words.append(f"{row['name'][:24]}, {plane}")
            line.append(_surface_of(self.volume, classes, box, size))
            words.append(f"{row['name'][:24]}, surface")
            pictures.append(line)
            captions.append(words)
        parts = [sheet(pictures, captions)]
        parts.append(metrics_picture(rows, parts[0].shape[1]))
        width = max(part.shape[1] for part in parts)
        return np.concatenate([np.pad(part, ((0, 0), (0, width - part.shape[1]), (0, 0))) for part in parts])


def _classes(test, reference):
    """:data:`CLASSES` of two masks of one box: 1 both, 2 the test alone, 3 the reference alone, 0 neither."""
    return np.select([test & reference, test, reference], [1, 2, 3], 0).astype(np.uint8)


def _surface_of(volume, classes, box, size):
    """The surface of a structure's :data:`CLASSES` in its box (and a voxel around it), from the front, each voxel in
    its class's colour: where the surfaces differ shows as test only or reference only.
    """
    from ..object.pipeline import PrepOptions, encode_volume
    from ..object.prep import LabelSelection
    from ..pictures import RenderOptions, picture
    from ..space.view import PRESETS

    around = tuple(slice(max(b.start - 1, 0), b.stop + 1) for b in box)
    table = {str(k): {"name": name, "colour": list(colour)} for k, (name, colour) in CLASSES.items()}
    part = io.Volume(np.ascontiguousarray(classes[around]), volume.spacing, {"label_table": table})
    if not part.values.any():
        return np.zeros((*size, 3), np.uint8)
    segments = encode_volume(part, PrepOptions(threshold=None, labels=LabelSelection()))
    options = RenderOptions(size=tuple(size), legend=True)
    return picture(segments, options.view(*PRESETS["anterior"]), options).rgb


def metrics_picture(rows, width, line=14):
    """The metrics as a picture ``width`` pixels wide, a structure a line, the worst first; a structure on one side
    only in red.
    """
    from PIL import Image, ImageDraw

    def number(value, form):
        return "-" if value is None or (isinstance(value, float) and math.isnan(value)) else format(value, form)

    # (heading, the cell of a row, its right edge in pixels; None: left-aligned at the column's start)
    columns = [("structure", lambda r: r["name"][:32], None, 4), ("Dice", lambda r: number(r["dice"], ".3f"), 250, 0),
               ("NSD", lambda r: number(r["nsd"], ".3f"), 300, 0), ("HD95 mm", lambda r: number(r["hd95_mm"], ".2f"),
                                                                     365, 0),
               ("ASSD mm", lambda r: number(r["assd_mm"], ".2f"), 430, 0),
               ("test mL", lambda r: number(r["volume_ml"], ".2f"), 505, 0),
               ("reference mL", lambda r: number(r["reference_ml"], ".2f"), 590, 0),
               ("", lambda r: "" if r["present"] == "both" else r["present"], None, 600)]
    image = Image.new("RGB", (max(width, 700), 8 + line * (len(rows) + 1)), (0, 0, 0))      # 700: the columns
    draw = ImageDraw.Draw(image)
    for k, row in enumerate([None, *rows]):
        colour = (230, 230, 230) if row is None or row["present"] == "both" else (255, 120, 90)
        for heading, cell, right, left in columns:
            text = heading if row is None else cell(row)
            x = left if right is None else right - draw.textlength(text)
            draw.text((x, 4 + line * k), text, fill=colour)
    return np.asarray(image)


def _on_grid(source, volume, read, parameter):
    """A label source's values on the image's grid and its meta; its errors name ``parameter``."""
    from ..object.pipeline import on_image_grid, read_labels

    try:
        if isinstance(source, io.Volume):
            found, name = source, source.meta.get("source", "the label array")
        else:
            found, name = read_labels(source, volume, read), str(source)
        values = on_image_grid(found, volume, name)[0]
    except InputError as exc:
        if parameter == "labels_from":
            raise
        raise InputError(exc.message.replace("the label map", "the reference", 1), parameter=parameter) from None
    return np.asarray(values), found.meta


def _structures(boxes, meta):
    """``{key: (label, name)}`` of the structures a label map holds: those with a box, in order."""
    table = meta.get("label_table") or {}
    found = {}
    for label in sorted(boxes):
        name = (table.get(str(label)) or {}).get("name") or f"label {label}"
        found.setdefault(label_sets.label_key(name, label), (label, name))
    return found


def _row(found, masks, spacing, voxel_ml, tolerance_mm):
    """The record of one structure: ``found`` its (label, name) in the test and the reference, or ``None``."""
    test, reference = masks
    volumes = [int(m.sum()) * voxel_ml for m in masks]
    distances = surfaces.surface_distances(test, reference, spacing)
    both = found[0] is not None and found[1] is not None
    difference = volumes[0] - volumes[1]
    return {"name": (found[1] or found[0])[1], "label": found[0][0] if found[0] else None,
            "reference_label": found[1][0] if found[1] else None,
            "present": "both" if both else "test only" if found[0] else "reference only",
            "dice": surfaces.dice(test, reference), "nsd": distances.surface_dice(tolerance_mm) if both else 0.0,
            "hd95_mm": distances.hausdorff() if both else float("nan"),
            "assd_mm": distances.assd() if both else float("nan"),
            "volume_ml": _round(volumes[0]), "reference_ml": _round(volumes[1]),
            "volume_diff_ml": _round(difference),
            "volume_diff_percent": _round(100 * difference / volumes[1]) if volumes[1] else float("nan"),
            "components": surfaces.components(test), "reference_components": surfaces.components(reference)}


def _round(value):
    """A volume to 5 significant digits, as every table gives them."""
    return float(f"{value:.5g}")


def write_metrics(path, rows, study=None):
    """Write ``rows`` (:func:`agreement`'s) as CSV under ``COLUMNS``, atomically; with ``study``, a first column
    naming it.
    """
    from ..outputs import output

    columns = (("study",) if study is not None else ()) + COLUMNS
    output.write_csv(Path(path), columns, [{**row, "study": study} for row in rows])
