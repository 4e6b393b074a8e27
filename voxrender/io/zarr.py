"""Zarr arrays and OME-Zarr images (NGFF 0.4 and 0.5), read a slab of chunks at a time.

What a path may be:

* a Zarr array (format 2 or 3) of three axes ``[z, y, x]`` (axes of length 1 before them are dropped): no spacing
  (1 mm);
* an OME-Zarr image: a group whose ``multiscales`` metadata (NGFF 0.4 in its attributes, 0.5 under ``"ome"``)
  names its axes (``t``, ``c``, ``z``, ``y``, ``x``: one time point and one channel are taken, more is refused)
  and its levels (``datasets``, the finest first), each with its ``coordinateTransformations``: the scale is the
  spacing, converted from the axes' units to mm, the translation the origin;
* a group holding exactly one such array or image (a bioformats2raw layout of one image).

NGFF says nothing of the patient's orientation, so the direction is ``None`` (the stored order is kept), unless
every spatial axis carries an anatomical ``orientation`` (NGFF RFC-4: ``{"type": "anatomical", "value":
"left-to-right"}``, as BrainGlobe's atlases write it) naming one of the six sides of a patient (left, right,
anterior, posterior, inferior, superior).

Chunks that were never written read as the array's fill value, as Zarr defines them.  ``level`` picks the level of
a multiscale image (0 the finest); :func:`choose_level` picks the coarsest that still gives a picture its pixels.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numpy as np

from .._shared.text import first_line
from ..errors import InputError
from ..space import orient
from ._shared import Reader, Volume, check_fits, check_spacing, identity_progress, stack_type
from ._stack import Stack

# The files that make a folder a Zarr node: an array or a group of format 2, any node of format 3.
METADATA_FILES = (".zarray", ".zgroup", "zarr.json")

# Millimetres in a unit of length, for the units NGFF allows (UDUNITS-2 names) and the abbreviations found in files.
MM_PER_UNIT = {
    "angstrom": 1e-7, "attometer": 1e-15, "centimeter": 10.0, "decimeter": 100.0, "exameter": 1e21,
    "femtometer": 1e-12, "foot": 304.8, "gigameter": 1e12, "hectometer": 1e5, "inch": 25.4, "kilometer": 1e6,
    "megameter": 1e9, "meter": 1e3, "micrometer": 1e-3, "mile": 1609344.0, "millimeter": 1.0, "nanometer": 1e-6,
    "parsec": 3.0856775814913673e19, "petameter": 1e18, "picometer": 1e-9, "terameter": 1e15, "yard": 914.4,
    "yoctometer": 1e-21, "yottameter": 1e27, "zeptometer": 1e-18, "zettameter": 1e24,
    "um": 1e-3, "µm": 1e-3, "μm": 1e-3, "micron": 1e-3, "mm": 1.0, "nm": 1e-6, "cm": 10.0, "m": 1e3,
}

# The side of the patient an axis grows toward, for NGFF RFC-4's anatomical orientations of a human.
SIDES = {"left-to-right": "R", "right-to-left": "L", "anterior-to-posterior": "P", "posterior-to-anterior": "A",
         "inferior-to-superior": "S", "superior-to-inferior": "I"}

AXIS_TYPES = {"t": "time", "c": "channel", "z": "space", "y": "space", "x": "space"}

SLAB_BYTES = 64 << 20          # what read_zarr reads at a time: whole chunks along z, about this many bytes


def read_zarr(path, progress, level=None):
    """Read a Zarr array or an OME-Zarr image (its level ``level``, default 0: the finest) into a
    :class:`~voxrender.io.Volume`, a slab of chunks at a time.

    ``meta`` tells the level read (``"level"``), the shapes ``[z, y, x]`` of all levels (``"levels"``), and where
    the spacing and orientation came from.

    Examples
    --------
    >>> import tempfile, pathlib, zarr
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "v.zarr"
    >>> zarr.create_array(store=str(path), data=np.arange(24, dtype=np.int16).reshape(2, 3, 4)).shape
    (2, 3, 4)
    >>> read_zarr(path, None).values[1, 2].tolist()
    [20, 21, 22, 23]
    """
    progress = progress or identity_progress
    stack, step = _open(path, level)
    check_fits(stack.shape, stack.dtype, path)
    values = np.empty(stack.shape, stack.dtype)
    starts = range(0, stack.shape[0], step)
    for z0 in progress(starts, len(starts), "reading Zarr chunks"):
        z1 = min(z0 + step, stack.shape[0])
        values[z0:z1] = stack.read_slices(z0, z1)
    return Volume(values, stack.spacing, stack.meta, stack.direction)


def open_zarr(path, level=None):
    """A Zarr array or OME-Zarr image (its level ``level``) as a :class:`~voxrender.io._stack.Stack`: a slab of
    slices reads only the chunks that hold it.
    """
    return _open(path, level)[0]


def _open(path, level):
    """The :class:`~voxrender.io._stack.Stack` of :func:`open_zarr`, and the slices to read at a time: whole
    chunks along z, about ``SLAB_BYTES``.
    """
    image = _image(path)
    array = image.level_array(level)
    dtype = np.dtype(array.dtype)
    if dtype.kind not in "uifb":
        raise InputError(f"{image.where(level)} holds {dtype} values; voxrender needs a numeric array (integers, "
                         "floats or booleans)")
    stored = dtype
    source = image.where(level)
    dtype = stack_type(dtype, source)
    if any(int(n) < 1 for n in array.chunks):
        raise InputError(f"the Zarr metadata of {source} is damaged: its chunks are {array.chunks}")
    index = image.index(array.shape, level)
    shape = tuple(int(array.shape[axis]) for axis in image.space)
    chunk = max(1, int(array.chunks[image.space[0]]))
    check_fits(tuple(int(n) for n in array.chunks), stored, source)          # zarr decodes a chunk whole

    def read_slices(z0, z1):
        take = list(index)
        take[image.space[0]] = slice(z0, z1)
        try:
            part = array[tuple(take)]
        except _damaged_chunks() as exc:
            _settle()
            raise InputError(f"{source}: the chunks holding slices {z0} to {z1 - 1} are damaged: "
                             f"{first_line(exc)}") from None
        part = np.asarray(part).reshape((z1 - z0,) + shape[1:])
        return part.view(np.uint8) if stored.kind == "b" else part.astype(dtype, copy=False)

    spacing, origin, notes = image.spacing(level)
    meta = {"level": image.chosen(level), "levels": image.shapes(), **notes}
    if origin is not None:
        meta["origin"] = origin
    direction, meta["orientation_from"] = image.direction()
    slab = chunk * max(1, SLAB_BYTES // max(1, chunk * math.prod(shape[1:]) * dtype.itemsize))
    return Stack(shape, dtype, read_slices, spacing, direction, meta), slab


def levels(path):
    """The shapes ``[z, y, x]`` of the levels of the Zarr array or OME-Zarr image at ``path``, the finest first
    (one for a plain array).
    """
    return _image(path).shapes()


def choose_level(path, pixels):
    """The level of the image at ``path`` to read for a picture ``pixels`` across: the finest whose largest side is
    at most ``pixels`` (a finer one would add nothing the picture can show), or the coarsest if none is.

    Examples
    --------
    >>> import tempfile, pathlib, zarr
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "v.zarr"
    >>> _ = zarr.create_array(store=str(path), shape=(20, 30, 40), dtype=np.uint8)
    >>> choose_level(path, 512)
    0
    """
    shapes = levels(path)
    return next((k for k, shape in enumerate(shapes) if max(shape) <= pixels), len(shapes) - 1)


def holds_zarr(path):
    """A folder holding a Zarr array or group (its ``.zarray``, ``.zgroup`` or ``zarr.json``)."""
    return path.is_dir() and any((path / name).is_file() for name in METADATA_FILES)


@dataclass
class _Image:
    """What a path holds, found from its metadata: the arrays of its levels, which of their axes are spatial
    (``space``: z, y, x in order) and their scales and translations (for each level, in array order).
    """

    path: object
    arrays: list                     # the levels' zarr arrays, the finest first
    names: list                      # their dataset paths, for messages
    axes: list                       # per array axis: {"name", "type", "unit", "orientation"}
    space: tuple
    scales: list
    translations: list
    kind: str
    channels: tuple = ()

    def where(self, level=None):
        """The array a message names: the path, and the level's dataset in a multiscale image."""
        name = self.names[self.chosen(level)]
        return f"{self.path}/{name}" if name else str(self.path)

    def chosen(self, level):
        return 0 if level is None else level

    def shapes(self):
        return [tuple(int(array.shape[axis]) for axis in self.space) for array in self.arrays]

    def level_array(self, level):
        if level is not None and (isinstance(level, bool) or not isinstance(level, int | np.integer)
                                  or not 0 <= level < len(self.arrays)):
            sizes = ", ".join(f"{k} ({', '.join(map(str, shape))})" for k, shape in enumerate(self.shapes()))
            raise InputError(f"{self.path} has no level {level!r}; its levels (z, y, x) are {sizes}, 0 the finest",
                             parameter="level")
        return self.arrays[self.chosen(level)]

    def index(self, shape, level):
        """The index of the slab: the first (only) time point and channel, every z, y, x; more of either is
        refused, naming them.
        """
        index = []
        for axis, (size, about) in enumerate(zip(shape, self.axes, strict=True)):
            if axis in self.space:
                index.append(slice(None))
                continue
            if size != 1:
                what = {"time": "time points", "channel": "channels"}.get(about["type"], "entries")
                names = f": {', '.join(self.channels)}" if about["type"] == "channel" and self.channels else ""
                raise InputError(f"{self.where(level)} holds {size} {what} (axis {about['name']!r}{names}); "
                                 "voxrender reads one time point of one channel: save the one to show as an image "
                                 "of its own")
            index.append(0)
        return tuple(index)

    def spacing(self, level):
        """The spacing (x, y, z) in mm, the origin (x, y, z) in mm or None, and notes for ``meta``."""
        if self.kind == "array":
            return (1.0, 1.0, 1.0), None, {"spacing_from": "default (a plain Zarr array carries no spacing)"}
        level = self.chosen(level)
        factors, unknown = [], []
        for axis in self.space:
            unit = self.axes[axis].get("unit")
            factors.append(MM_PER_UNIT.get(str(unit).strip().lower(), 1.0) if unit else 1.0)
            if str(unit).strip().lower() not in MM_PER_UNIT:
                unknown.append(f"{self.axes[axis]['name']} ({unit or 'no unit'})")
        scale = [self.scales[level][axis] * f for axis, f in zip(self.space, factors, strict=True)]
        spacing = check_spacing(scale[::-1], f"{self.where(level)} (its OME-Zarr scale)")
        notes = {"spacing_from": f"{self.kind} scale" + (f", taken as mm for {', '.join(unknown)}" if unknown
                                                           else "")}
        translation = self.translations[level]
        origin = None if translation is None else \
            [float(translation[axis] * f) for axis, f in zip(self.space, factors, strict=True)][::-1]
        return spacing, origin, notes

    def direction(self):
        """The direction and where it came from: the spatial axes' anatomical orientation (NGFF RFC-4), when
        each has one of a patient's six sides.
        """
        sides = []
        for axis in self.space:
            given = self.axes[axis].get("orientation")
            if isinstance(given, dict) and given.get("type") == "anatomical":
                sides.append(SIDES.get(str(given.get("value")).lower()))
        code = "".join(side or "?" for side in sides[::-1])             # x, y, z: the array's last axis first
        if len(code) != 3 or "?" in code or len({"LRPASI".index(side) // 2 for side in code}) != 3:
            return None, f"unknown: {'NGFF' if self.kind != 'array' else 'Zarr'} metadata does not tell the " \
                         "patient's orientation (stored order kept)"
        return orient.direction_of(code), "OME-Zarr axes' anatomical orientation (NGFF RFC-4)"


def _damaged_metadata():
    """What zarr raises for metadata it cannot read (garbled JSON, missing or wrong fields, an unknown codec or
    data type, a missing node).
    """
    return (ValueError, TypeError, KeyError, ArithmeticError, OSError)


def _damaged_chunks():
    """What zarr and its codecs raise for a cut or garbled chunk."""
    return (ValueError, RuntimeError, SystemError, OSError, EOFError, zlib.error)


def _settle():
    """Wait for the chunk reads zarr left running when one of them failed.

    zarr reads the chunks of a slab as tasks gathered on its own event loop; the first to fail ends the read, and
    the others stay pending, so that at exit the interpreter reports each as destroyed while pending (and a task
    resumed on the closed loop raises), after the command's one error line.  They are waited for, not cancelled:
    the loop is shared, and another thread's reads may be among them.
    """
    import asyncio

    from zarr.core.sync import sync

    async def the_others():
        others = [task for task in asyncio.all_tasks() if task is not asyncio.current_task()]
        await asyncio.gather(*others, return_exceptions=True)

    sync(the_others())


def _image(path):
    """What ``path`` holds, from its metadata: an :class:`_Image`."""
    import zarr

    if not holds_zarr(path):
        raise InputError(f"{path} holds no Zarr metadata ({', '.join(METADATA_FILES)}); give the folder of a Zarr "
                         "array or group (an OME-Zarr image)")
    try:
        node = zarr.open(store=str(path), mode="r")
        return _found(path, node)
    except InputError:
        raise
    except _damaged_metadata() as exc:
        raise InputError(f"the Zarr metadata of {path} (.zarray, .zattrs, .zgroup or zarr.json) is damaged: "
                         f"{first_line(exc)}") from None


def _found(path, node):
    """The image in ``node`` (an array, an OME-Zarr image, or a group holding one of them)."""
    import zarr

    if isinstance(node, zarr.Array):
        return _plain(path, node, "")
    multiscales = _multiscales(path, node.attrs.asdict())
    if multiscales is not None:
        return _ome(path, node, multiscales)
    arrays, groups = list(node.arrays()), list(node.groups())
    images = [(name, group) for name, group in groups if _multiscales(path, group.attrs.asdict()) is not None]
    if len(arrays) == 1 and not images:
        return _plain(path, arrays[0][1], arrays[0][0])
    if len(images) == 1 and not arrays:
        return _ome(path / images[0][0], images[0][1], _multiscales(path, images[0][1].attrs.asdict()))
    held = [f"array {name} {'x'.join(map(str, array.shape))}" for name, array in arrays] + \
        [f"image {name}" for name, _ in images]
    if not held:
        raise InputError(f"{path} is a Zarr group without arrays or OME-Zarr images; give the folder of a Zarr "
                         "array or an OME-Zarr image")
    raise InputError(f"{path} is a Zarr group of {len(held)} arrays and images ({', '.join(held[:6])}"
                     f"{', ...' * (len(held) > 6)}); give the folder of the one to read")


def _plain(path, array, name):
    """A plain array: ``[z, y, x]``, after axes of length 1."""
    shape = tuple(int(n) for n in array.shape)
    if len(shape) < 3 or any(n != 1 for n in shape[:-3]):
        raise InputError(f"{path}{'/' + name if name else ''} holds a {'x'.join(map(str, shape)) or 'scalar'} "
                         "array; voxrender needs a 3-D array [z, y, x]")
    axes = [{"name": f"axis {k}", "type": None} for k in range(len(shape) - 3)] + \
        [{"name": n, "type": "space"} for n in "zyx"]
    space = tuple(range(len(shape) - 3, len(shape)))
    return _Image(path if not name else path / name, [array], [""], axes, space, [None], [None], "array")


def _multiscales(path, attrs):
    """The first ``multiscales`` entry of a group's attributes (NGFF 0.5 keeps them under ``"ome"``), or None."""
    ome = attrs.get("ome") if isinstance(attrs.get("ome"), dict) else attrs
    multiscales = ome.get("multiscales")
    if multiscales is None:
        return None
    if not isinstance(multiscales, list) or not multiscales or not isinstance(multiscales[0], dict):
        raise InputError(f"the OME-Zarr metadata of {path} is damaged: its multiscales is not a list of images")
    return {"version": ome.get("version"), **multiscales[0]}


def _ome(path, group, multiscale):
    """An OME-Zarr image from its group and its ``multiscales`` entry."""
    def damaged(what):
        return InputError(f"the OME-Zarr metadata of {path} is damaged: {what}")

    datasets = multiscale.get("datasets")
    if not isinstance(datasets, list) or not datasets or not all(isinstance(d, dict) and isinstance(
            d.get("path"), str) for d in datasets):
        raise damaged("its datasets are not a list of paths")
    arrays = []
    for dataset in datasets:
        try:
            array = group[dataset["path"]]
        except (KeyError, FileNotFoundError):
            raise InputError(f"{path}: the dataset {dataset['path']!r} that its multiscales metadata names is "
                             "missing (its folder or its .zarray/zarr.json)") from None
        if not hasattr(array, "dtype"):
            raise damaged(f"its dataset {dataset['path']!r} is a group, not an array")
        arrays.append(array)
    ndim = len(arrays[0].shape)
    if any(len(a.shape) != ndim for a in arrays):
        raise damaged("its levels have different numbers of axes")
    axes = _axes(multiscale.get("axes"), ndim, damaged)
    space = tuple(k for k, axis in enumerate(axes) if axis["type"] == "space")
    if len(space) != 3:
        names = ", ".join(axis["name"] for axis in axes)
        raise InputError(f"{path} is an OME-Zarr image of {len(space)} spatial axes ({names}); voxrender needs a "
                         "3-D image (axes z, y, x)")
    outer = _transforms(multiscale.get("coordinateTransformations") or [], ndim, damaged, "the image's")
    scales, translations = [], []
    for dataset in datasets:
        scale, translation = _transforms(dataset.get("coordinateTransformations") or [], ndim, damaged,
                                         f"dataset {dataset['path']!r}'s")
        scale = scale if scale is not None else [1.0] * ndim
        if outer[0] is not None or outer[1] is not None:          # the image's own transforms come after
            top_scale = outer[0] if outer[0] is not None else [1.0] * ndim
            top_shift = outer[1] if outer[1] is not None else [0.0] * ndim
            translation = [s * t + u for s, t, u in zip(top_scale, translation or [0.0] * ndim, top_shift,
                                                        strict=True)]
            scale = [s * t for s, t in zip(top_scale, scale, strict=True)]
        scales.append(scale)
        translations.append(translation)
    version = multiscale.get("version") or "0.x"
    channels = _channel_names(group.attrs.asdict())
    return _Image(path, arrays, [d["path"] for d in datasets], axes, space, scales, translations,
                  f"OME-Zarr {version}", channels)


def _axes(axes, ndim, damaged):
    """The axes of an image as dicts (NGFF 0.3 gives names only; 0.1 and 0.2 none: t, c, z, y, x)."""
    if axes is None:
        axes = list("tczyx")[-ndim:] if ndim <= 5 else None
    if not isinstance(axes, list) or len(axes) != ndim:
        raise damaged(f"its axes ({axes!r:.60}) do not match its {ndim}-D arrays")
    found = []
    for axis in axes:
        if isinstance(axis, str):
            axis = {"name": axis}
        if not isinstance(axis, dict) or not isinstance(axis.get("name"), str):
            raise damaged(f"an axis ({axis!r:.40}) has no name")
        found.append({**axis, "type": axis.get("type", AXIS_TYPES.get(axis["name"].lower()))})
    return found


def _transforms(transforms, ndim, damaged, whose):
    """The scale and translation (each a list, or None) of a list of NGFF coordinate transformations."""
    if not isinstance(transforms, list):
        raise damaged(f"{whose} coordinateTransformations are not a list")
    scale = translation = None
    for transform in transforms:
        kind = transform.get("type") if isinstance(transform, dict) else None
        if kind == "identity":
            continue
        if kind not in ("scale", "translation"):
            raise damaged(f"{whose} coordinate transformation {transform!r:.60} is not a scale or translation")
        values = transform.get(kind)
        if values is None and "path" in transform:
            raise InputError(f"{whose} {kind} is kept in a file ({transform['path']}), which voxrender does not read; "
                             "give its values in the metadata")
        if not isinstance(values, list) or len(values) != ndim or not all(
                isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in values):
            raise damaged(f"{whose} {kind} {values!r:.60} is not {ndim} numbers")
        if kind == "scale":
            scale = [float(v) for v in values]
        else:
            translation = [float(v) for v in values]
    return scale, translation


def _channel_names(attrs):
    """The channels' names from OME-Zarr's ``omero`` metadata, when it has them."""
    ome = attrs.get("ome") if isinstance(attrs.get("ome"), dict) else attrs
    channels = (ome.get("omero") or {}).get("channels") if isinstance(ome.get("omero"), dict) else None
    if not isinstance(channels, list):
        return ()
    return tuple(str(c.get("label")) for c in channels if isinstance(c, dict) and c.get("label") is not None)


READER = Reader(read_zarr, suffixes=(".zarr", ".ome.zarr"), options=("level",), sniff=holds_zarr, open=open_zarr)
