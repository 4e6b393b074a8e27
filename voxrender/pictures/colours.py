"""Colours of labels and objects: named colours, colour tables, the built-in palette, and CT tissue presets.

A colour table maps labels to ``(name, (r, g, b))`` with 8-bit components.  One comes from a file
(:func:`read_colour_table`: CSV, JSON, 3D Slicer's ``.ctbl``, ITK-SNAP's label descriptions), from a ``.seg.nrrd``
(its segments' names and colours, read with the volume), from the anatomy table by a structure's name
(:func:`anatomy_colour`), or from :func:`palette`; :func:`label_colours` settles which one each label takes.
"""

from __future__ import annotations

import csv
import functools
import json
import re
import shlex
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..object.prep import Interval

# A few colour names a user may type (and the tissue colours of the presets).
NAMED = {
    "white": (255, 255, 255), "black": (0, 0, 0), "grey": (128, 128, 128), "gray": (128, 128, 128),
    "red": (220, 50, 47), "green": (60, 170, 80), "blue": (40, 110, 220), "yellow": (240, 210, 60),
    "orange": (245, 140, 40), "purple": (150, 80, 180), "cyan": (60, 190, 210), "magenta": (210, 70, 160),
    "pink": (240, 150, 170), "brown": (150, 95, 55), "ivory": (255, 250, 235),
    "bone": (241, 214, 145), "skin": (177, 122, 101), "muscle": (192, 104, 88), "artery": (216, 101, 79),
    "lung": (197, 165, 145),
}

# Twenty colours in an order that keeps neighbouring labels far apart (after Kelly's colours of maximum contrast).
_PALETTE = np.array([
    (230, 159, 0), (86, 180, 233), (0, 158, 115), (240, 228, 66), (0, 114, 178), (213, 94, 0), (204, 121, 167),
    (190, 60, 60), (120, 200, 80), (150, 110, 210), (255, 190, 140), (40, 160, 160), (220, 220, 220),
    (170, 110, 40), (250, 130, 180), (100, 130, 60), (130, 200, 255), (200, 160, 230), (245, 90, 60),
    (160, 200, 170)], np.uint8)


def named_colour(text, parameter="colour"):
    """An 8-bit colour from a name (:data:`NAMED`), ``#rrggbb``, a grey level ``"40"`` or ``"r,g,b"``.

    >>> named_colour("#ff8000"), named_colour("bone"), named_colour("20,30,40")
    ((255, 128, 0), (241, 214, 145), (20, 30, 40))
    """
    text = str(text).strip().lower()
    if text in NAMED:
        return NAMED[text]
    if re.fullmatch(r"#[0-9a-f]{6}", text):
        return tuple(int(text[k:k + 2], 16) for k in (1, 3, 5))
    try:
        values = tuple(int(p) for p in text.split(","))
    except ValueError:
        values = ()
    if len(values) == 1:
        values = values * 3
    if len(values) != 3 or not all(0 <= v <= 255 for v in values):
        raise InputError(f"{text!r} is not a colour: give a name ({', '.join(list(NAMED)[:8])} ...), #rrggbb, "
                         "a grey level 0..255 or r,g,b", parameter=parameter)
    return values


def palette(labels):
    """The built-in colours of ``labels``: ``{label: (r, g, b)}``; labels next to each other differ clearly.

    >>> palette([1, 2])
    {1: (230, 159, 0), 2: (86, 180, 233)}
    """
    return {int(v): tuple(int(c) for c in _PALETTE[(int(v) - 1) % len(_PALETTE)]) for v in labels}


def read_colour_table(path):
    r"""A colour table file as ``{label: (name, (r, g, b))}``.

    Formats, told by the suffix: ``.csv`` (columns label, name, r, g, b; a header row is allowed), ``.json``
    (a list of objects with ``label``, ``name`` and ``r, g, b`` or ``colour``/``color``), 3D Slicer's ``.ctbl``
    and ``.txt`` colour tables (``label name r g b a``), and ITK-SNAP's label description files
    (``label r g b a visible mesh "name"``).  ``#`` starts a comment line.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "t.csv"
    >>> _ = path.write_text("label,name,r,g,b\n1,liver,200,100,50\n")
    >>> read_colour_table(path)
    {1: ('liver', (200, 100, 50))}
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise InputError(f"cannot read the colour table {path}: {exc.strerror or exc}", parameter="colours") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"the colour table {path} is not UTF-8 text (byte {exc.object[exc.start]:#04x} at "
                         f"{exc.start}); save it as UTF-8", parameter="colours") from None
    suffix = path.suffix.lower()
    if suffix == ".json":
        rows = _json_rows(path, text)
    elif suffix == ".csv":
        try:
            rows = [(n, row) for n, row in enumerate(csv.reader(text.splitlines()), 1) if row and "".join(row).strip()]
        except csv.Error as exc:                    # a field beyond csv's limit, a NUL byte
            raise InputError(f"{path} is not a CSV table: {exc}", parameter="colours") from None
        if rows and not rows[0][1][0].strip().lstrip("-").isdigit():
            rows = rows[1:]                                           # the header
        rows = [(n, row) for n, row in rows if not row[0].lstrip().startswith("#")]
    else:
        rows = [(n, _split(path, n, line)) for n, line in enumerate(text.splitlines(), 1)
                if line.strip() and not line.lstrip().startswith("#")]
    table = {}
    for number, row in rows:
        label, name, rgb = _entry(path, number, row)
        if label:                                 # 0 is the background: nothing is drawn in its colour
            table[label] = (name, rgb)
    if not table:
        raise InputError(f"the colour table {path} lists no label above 0", parameter="colours")
    return table


def _split(path, number, line):
    """A whitespace-separated line; ITK-SNAP quotes its names.  Slicer's ``label name r g b a`` and ITK-SNAP's
    ``label r g b a visible mesh "name"`` become ``[label, name, r, g, b]``.
    """
    try:
        words = shlex.split(line)
    except ValueError:
        raise InputError(f"{path}, line {number}: an unclosed quote", parameter="colours") from None
    if len(words) == 8 and all(w.lstrip("-").replace(".", "", 1).isdigit() for w in words[:7]):
        return [words[0], words[7], *words[1:4]]                      # ITK-SNAP
    return words[:5]


def _json_rows(path, text):
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{path} is not JSON: {exc.msg} at line {exc.lineno}", parameter="colours") from None
    except RecursionError:
        raise InputError(f"{path} nests its JSON too deep for a colour table", parameter="colours") from None
    if isinstance(data, dict):                    # {"3": {"name": ..., "colour": [...]}}
        data = [{"label": key, **(value if isinstance(value, dict) else {"colour": value})}
                for key, value in data.items()]
    if not isinstance(data, list):
        raise InputError(f"{path} must hold a list of labels with name and colour", parameter="colours")
    rows = []
    for number, item in enumerate(data, 1):
        item = item if isinstance(item, dict) else {}
        colour = item.get("colour", item.get("color", [item.get(k) for k in "rgb"]))
        colour = list(colour) if isinstance(colour, (list, tuple)) else []
        rows.append((number, [item.get("label"), item.get("name", ""), *colour[:3]]))
    return rows


def _entry(path, number, row):
    where = f"{path}, {'row' if path.suffix.lower() in ('.csv', '.json') else 'line'} {number}"
    try:
        label = int(str(row[0]).strip())
        rgb = tuple(int(round(float(str(v).strip()))) for v in row[2:5])
    except (ValueError, IndexError, TypeError, OverflowError):       # OverflowError: a colour of inf
        label, rgb = None, ()
    if label is None or len(rgb) != 3 or not 0 <= label <= 65535 or not all(0 <= v <= 255 for v in rgb):
        raise InputError(f"{where}: {row!r} is not 'label, name, r, g, b' with a label 0..65535 and colours "
                         "0..255", parameter="colours")
    name = str(row[1]).strip() or f"label {label}"
    return label, name, rgb


@functools.cache
def _anatomy():
    """The anatomy table, ``{key: (r, g, b)}``, keyed by structure name and by SNOMED CT meaning (see
    :func:`anatomy_colour`).
    """
    table = {}
    text = resources.files("voxrender").joinpath("data/anatomy_colours.csv").read_text()
    for row in csv.DictReader(line for line in text.splitlines() if not line.startswith("#")):
        colour = (int(row["r"]), int(row["g"]), int(row["b"]))
        meaning = f"{row['modifier']} {row['meaning']}" if row["modifier"] else row["meaning"]
        for key in (row["structure"], meaning):
            table.setdefault(_anatomy_key(key), colour)
    return table


def _anatomy_key(name):
    """A name as the anatomy table is searched: :func:`voxrender._shared.label_sets.label_key`, the one rule that
    also matches labels across a batch (``Left kidney`` and ``kidney_left`` are one key).
    """
    from .._shared.label_sets import label_key

    return label_key(name)


def anatomy_colour(name):
    """The colour of an anatomical structure by its name, or ``None`` when the table does not know it.

    The table holds the 170 structures of TotalSegmentator, with the colours TotalSegmentator itself gives them in
    DICOM SEG and RTSTRUCT output, keyed by its names (``liver``, ``kidney_left``, ``vertebrae_L1``,
    ``rib_left_1``) and by their SNOMED CT meanings (``Liver``, ``Left kidney``, ``L1 vertebra``).  Names match
    without regard to case, spaces or hyphens, and with a side given first or last (``left_kidney``).

    >>> anatomy_colour("liver"), anatomy_colour("Left kidney") == anatomy_colour("kidney_left")
    ((40, 140, 40), True)
    >>> anatomy_colour("label 3") is None
    True

    References
    ----------
    TotalSegmentator, ``totalsegmentator/resources/totalsegmentator_snomed_mapping.csv`` (Apache License 2.0),
    https://github.com/wasserth/TotalSegmentator; kept as ``voxrender/data/anatomy_colours.csv``.
    """
    return _anatomy().get(_anatomy_key(name))


def label_colours(labels, stored=None, given=None):
    """Name and colour of each of ``labels``: ``{label: (name, (r, g, b))}``.

    A label takes its entry in ``given`` (a table the user gave), else in ``stored`` (kept with the object: a
    ``.seg.nrrd``'s segments, a SEG's, the names of a mask folder's files), else ``"label N"``.  When the object
    names its labels and ``given`` names some of them too, ``given`` applies by name (a table of structures over a
    mask folder, whose numbers follow its file names), else by number.  A stored name without a colour takes the
    anatomy table's (:func:`anatomy_colour`); what is left takes the :func:`palette`.  ``stored`` may be the JSON
    form kept in a ``.vxs`` (``{"3": {"name": ..., "colour": [...] or None}}``).

    >>> label_colours([1, 2], given={2: ("liver", (200, 100, 50))})
    {1: ('label 1', (230, 159, 0)), 2: ('liver', (200, 100, 50))}
    >>> label_colours([1, 2], stored={"1": {"name": "liver", "colour": None}, "2": {"name": "tumour", "colour": None}})
    {1: ('liver', (40, 140, 40)), 2: ('tumour', (86, 180, 233))}
    >>> label_colours([1], stored={"1": {"name": "liver", "colour": None}}, given={7: ("liver", (1, 2, 3))})
    {1: ('liver', (1, 2, 3))}
    """
    built_in = palette(labels)
    kept = {int(k): (v["name"], v.get("colour")) if isinstance(v, dict) else tuple(v)
            for k, v in (stored or {}).items()}
    by_name = {name: (name, colour) for name, colour in (given or {}).values()}
    by_name = by_name if any(name in by_name for name, _ in kept.values()) else None
    table = {}
    for v in labels:
        name, colour = kept.get(int(v), (None, None))
        entry = by_name.get(name) if by_name is not None else (given or {}).get(int(v))
        if entry is None:
            name = name or f"label {v}"
            entry = (name, tuple(int(c) for c in colour or anatomy_colour(name) or built_in[int(v)]))
        table[int(v)] = entry
    return table


@dataclass(frozen=True)
class Preset:
    """A CT tissue: a HU window, a colour, and where the values come from."""

    window: Interval
    colour: tuple
    source: str


PRESETS = {
    "bone": Preset(Interval(300, None), NAMED["bone"],
                   "cancellous bone from +300 HU, cortical +500 to +1900 (Hounsfield scale tables); the project's "
                   "head data: bone at about 300 HU"),
    "skin": Preset(Interval(-300, None), NAMED["skin"],
                   "the air/tissue boundary: air is -1000 HU, fat -120 to -90, so -300 is safely between them "
                   "(the project's head data: skin at about -300 HU)"),
    "soft-tissue": Preset(Interval(20, 80), NAMED["muscle"],
                          "muscle +35 to +55, organs, brain and blood +20 to +60 HU; leaves out fat (-120 to -90), "
                          "water (0) and bone (from +300)"),
    "contrast-vessels": Preset(Interval(150, 500), NAMED["artery"],
                               "iodine-enhanced vessel lumen in CT angiography, about +200 to +500 HU, above "
                               "unenhanced blood (+13 to +50); overlaps cancellous bone, so crop or clip bone away"),
    "lung": Preset(Interval(-950, -500), NAMED["lung"],
                   "aerated lung parenchyma, about -900 to -500 HU (-700 to -600 typical); -950 is the usual "
                   "emphysema threshold and keeps out the air around the body (-1000)"),
}


def preset(name):
    """The :class:`Preset` called ``name``; an :class:`InputError` listing the presets otherwise."""
    if name not in PRESETS:
        raise InputError(f"unknown preset {name!r}; choose one of {', '.join(PRESETS)} "
                         "('voxrender presets' lists their values)", parameter="preset")
    return PRESETS[name]
