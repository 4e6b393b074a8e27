"""Text to typed values: the small languages of the command line and of batch manifests.

The library takes numbers, tuples and slices; only the command line and the manifests hold text.
Each parser raises :class:`~voxrender.errors.InputError` naming its ``parameter``, which the CLI
turns into its flag and a manifest error into its column.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..errors import InputError
from ..io import RawLayout
from ..object.prep import Interval, otsu_threshold


def size(text):
    """``"N"`` or ``"WxH"`` pixels to ``(H, W)``.

    >>> size("640x480"), size("256")
    ((480, 640), (256, 256))
    """
    try:
        parts = [int(p) for p in str(text).lower().split("x")]
    except ValueError:
        parts = []
    if len(parts) == 1:
        parts = parts * 2
    if len(parts) != 2 or min(parts) < 1 or max(parts) > 32768:
        raise InputError(f"{text!r} must be N or WxH in pixels, e.g. 512 or 640x480", parameter="size")
    width, height = parts
    return height, width


def memory(text):
    """A size in bytes: ``"8G"``, ``"512M"``, ``"2.5GB"`` or a number of bytes (binary units, as memory is counted).

    >>> memory("8G"), memory("512m"), memory("1000")
    (8589934592, 536870912, 1000)
    """
    units = {"": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}
    found = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*([kmgt]?)(i?b)?\s*", str(text).lower())
    if not found or float(found[1]) * units[found[2]] < 1:
        raise InputError(f"{text!r} must be a size such as 8G, 512M or a number of bytes", parameter="max_memory")
    return int(float(found[1]) * units[found[2]])


def vector(text, parameter, count=3):
    """``"1,2,3"`` to a tuple of ``count`` finite floats.

    >>> vector("1, -2,0.5", "light")
    (1.0, -2.0, 0.5)
    """
    try:
        values = tuple(float(v) for v in str(text).split(","))
    except ValueError:
        values = ()
    if len(values) != count or not all(np.isfinite(values)):
        raise InputError(f"{text!r} must be {count} numbers separated by commas", parameter=parameter)
    return values


def colour(text, parameter="background"):
    """A colour: a name (white, black, grey, red, bone ...), ``#rrggbb``, a grey level ``"40"`` or ``"r,g,b"``
    in 0..255 (see :func:`voxrender.pictures.colours.named_colour`).

    >>> colour("white"), colour("20,30,40"), colour("7"), colour("#0000ff")
    ((255, 255, 255), (20, 30, 40), (7, 7, 7), (0, 0, 255))
    """
    from ..pictures.colours import named_colour

    return named_colour(text, parameter)


def clip_range(text, parameter):
    """``"a:b"`` (either side may be empty) to ``(a, b)`` with ``None`` for an open side.

    >>> clip_range("10:", "clip_x")
    (10, None)
    """
    lo, sep, hi = str(text).partition(":")
    try:
        bounds = (int(lo) if lo.strip() else None, int(hi) if hi.strip() else None)
    except ValueError:
        bounds = None
    if not sep or bounds is None or (None not in bounds and bounds[0] >= bounds[1]):
        raise InputError(f"{text!r} must be a:b with whole numbers a < b (either may be left out)",
                         parameter=parameter)
    return bounds


def crop(text):
    """``"x0:x1,y0:y1,z0:z1"`` (voxel indices, end excluded, parts may be empty) to ``(z, y, x)`` slices.

    >>> crop("10:20,:,5:")
    (slice(5, None, None), slice(None, None, None), slice(10, 20, None))
    """
    parts = str(text).split(",")
    if len(parts) != 3:
        raise InputError(f"{text!r} must be x0:x1,y0:y1,z0:z1 (parts may be empty, e.g. ':,:,10:50')",
                         parameter="crop")
    result = []
    for axis, part in zip("xyz", parts, strict=True):
        lo, sep, hi = part.partition(":")
        if not sep and part.strip():
            raise InputError(f"{text!r}: {axis} range {part!r} needs a colon, as in {part}:", parameter="crop")
        try:
            result.append(slice(int(lo) if lo.strip() else None, int(hi) if hi.strip() else None))
        except ValueError:
            raise InputError(f"{text!r}: {axis} range {part!r} is not a:b with whole numbers",
                             parameter="crop") from None
    return tuple(result[::-1])


def threshold(text):
    """A threshold: a number, a window ``"lo:hi"`` (either side may be left open), or ``"otsu"`` for
    :func:`voxrender.object.prep.otsu_threshold`.

    >>> threshold("-300"), threshold("otsu").__name__, threshold("300:")
    (-300.0, 'otsu_threshold', Interval(lo=300.0, hi=None))
    """
    if str(text).strip().lower() == "otsu":
        return otsu_threshold
    if ":" in str(text):
        lo, _, hi = str(text).partition(":")
        try:
            bounds = tuple(float(v) if v.strip() else None for v in (lo, hi))
        except ValueError:
            raise InputError(f"{text!r} must be a window lo:hi of numbers (in stored units, HU for CT), "
                             "either side may be left out", parameter="threshold") from None
        return Interval(*bounds)
    try:
        value = float(text)
    except (TypeError, ValueError):
        value = math.nan
    if not math.isfinite(value):
        raise InputError(f"{text!r} must be a finite number (in stored units, HU for CT) or 'otsu'",
                         parameter="threshold")
    return value


def presets(text):
    """Preset names ``"skin,bone"`` as ``[(name, Preset)]``, in the order given (see
    :data:`voxrender.pictures.colours.PRESETS`).

    >>> [(name, str(tissue.window)) for name, tissue in presets("skin, bone")]
    [('skin', '-300:'), ('bone', '300:')]
    """
    from ..pictures.colours import preset

    names = [name.strip() for name in str(text).split(",") if name.strip()]
    if not names:
        raise InputError(f"{text!r} names no preset; 'voxrender presets' lists them", parameter="preset")
    return [(name, preset(name)) for name in names]


def labels(text):
    """Labels ``"3,5,7"`` as a tuple of whole numbers.

    >>> labels("3, 5")
    (3, 5)
    """
    try:
        values = tuple(int(part) for part in str(text).split(","))
    except ValueError:
        raise InputError(f"{text!r} must be labels separated by commas, e.g. 1,4,7", parameter="label") from None
    return values


def raw_layout(text):
    """``"WxH:dtype:endian"`` to a :class:`~voxrender.io.RawLayout`.

    >>> layout = raw_layout("64x64:uint16:little")
    >>> layout.width, layout.height, layout.dtype.str
    (64, 64, '<u2')
    """
    match = re.fullmatch(r"\s*(\d+)[xX](\d+):(\w+)(?::(\w+))?\s*", text or "")
    if not match:
        raise InputError(f"{text!r} is not WxH:dtype:endian, e.g. 64x64:uint16:little", parameter="raw")
    width, height, name, endian = match.groups()
    try:
        dtype = np.dtype(name)
    except TypeError:
        raise InputError(f"unknown dtype {name!r}; use uint8, int16, uint16, int32, float32, ...",
                         parameter="raw") from None
    orders = {None: "<", "little": "<", "le": "<", "big": ">", "be": ">"}
    if (endian and endian.lower()) not in orders:
        raise InputError(f"byte order {endian!r} must be little or big", parameter="raw")
    if dtype.kind not in "uif":
        raise InputError(f"dtype {name!r} is not numeric", parameter="raw")
    return RawLayout(int(width), int(height), dtype.newbyteorder(orders[endian and endian.lower()]))


def window(text):
    """A display window: ``"LEVEL/WIDTH"`` or a CT window's name (brain, soft-tissue, bone, lung; see
    :data:`voxrender.pictures.display.CT_WINDOWS`).

    >>> window("40/400"), window("bone")
    (DisplayWindow(level=40.0, width=400.0), DisplayWindow(level=400, width=1800))
    """
    from ..pictures.display import CT_WINDOWS, DisplayWindow

    name = str(text).strip().lower().replace("_", "-").replace(" ", "-")
    if name in CT_WINDOWS or name == "soft":
        return CT_WINDOWS.get(name, CT_WINDOWS["soft-tissue"])
    level, slash, width = str(text).partition("/")
    try:
        numbers = (float(level), float(width)) if slash else ()
    except ValueError:
        numbers = ()
    if not numbers:
        raise InputError(f"{text!r} must be LEVEL/WIDTH, e.g. 40/400, or one of {', '.join(CT_WINDOWS)}",
                         parameter="window")
    return DisplayWindow(*numbers)


def planes(text):
    """Slice planes ``"axial,coronal"`` as a tuple (checked by :class:`voxrender.qc.qc.SliceOptions`).

    >>> planes("axial, sagittal")
    ('axial', 'sagittal')
    """
    return tuple(p.strip().lower() for p in str(text).split(",") if p.strip())


def slice_point(text):
    """Where slices cross: ``"centre"`` (``None``), ``"labels"`` or ``"labels:largest"`` (through each label's
    centroid or largest cross-section), or a point ``"x,y,z"`` in patient mm (LPS), or in voxels with ``vox`` after
    it (``"256,256,117vox"``).

    >>> slice_point("centre"), slice_point("labels:largest"), slice_point("10,-20,35")
    (None, 'largest', SlicePoint(x=10.0, y=-20.0, z=35.0, unit='mm'))
    >>> slice_point("256,256,117vox").unit
    'voxel'
    """
    from ..qc.slices import SlicePoint

    words = str(text).strip().lower()
    if words in ("centre", "center"):
        return None
    if words in ("labels", "labels:centroid", "labels:largest"):
        return "largest" if words.endswith("largest") else "centroid"
    unit = "mm"
    for ending, name in (("vox", "voxel"), ("mm", "mm")):
        if words.endswith(ending):
            words, unit = words[:-len(ending)], name
            break
    try:
        x, y, z = vector(words, "at")
    except InputError:
        raise InputError(f"{text!r} must be x,y,z in mm (patient LPS), x,y,zvox in voxels, centre, labels or "
                         "labels:largest", parameter="at") from None
    return SlicePoint(x, y, z, unit)
