"""The steps every format's volume goes through once its reader has read it, whichever way it was asked for
(:func:`voxrender.io.read_volume`, :func:`voxrender.io.open_stack`, or a folder of masks reading its files): the
reader's options checked, a 3-D stack of real numbers, its place in the patient frame filled in, and the canonical
frame.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..space import orient
from ..space.grids import voxel_affine
from ._shared import check_spacing, real_numbers


def options_for(reader, format, given):
    """The options of ``given`` (``{name: value or None}``) that ``reader`` takes; one it does not take, refused."""
    for name, value in given.items():
        if value is not None and name not in reader.options:
            raise InputError(f"{format} input takes no {name}", parameter=name)
    return {name: given.get(name) for name in reader.options}


def read_with(reader, path, format, progress, given, orientation=None, reorient=True, spacing=None):
    """The volume of ``path`` as ``reader`` (the :class:`~voxrender.io._shared.Reader` of ``format``) reads it, in
    the canonical patient frame: :func:`voxrender.io.read_volume` once the format is known.
    """
    if path.is_file() and not path.stat().st_size:       # every reader would say it its own way, or not at all
        raise InputError(f"{path} is an empty file (0 bytes); it was cut off or not written")
    volume = reader.function(path, progress, **options_for(reader, format, given))
    if volume.values.ndim != 3 or min(volume.values.shape) < 1:
        raise InputError(f"{path} does not hold a 3-D stack (shape {volume.values.shape})")
    volume.values = real_numbers(volume.values, path)
    if placed(volume, path, format, orientation, reorient):
        volume.values, volume.spacing, volume.direction, volume.meta["reoriented"] = orient.to_canonical(
            volume.values, volume.spacing, volume.direction, volume.meta.get("orientation_from", "the header"))
    if spacing is not None:
        volume.spacing = check_spacing(spacing)
        volume.meta["spacing_from"] = "given"
    return volume


def placed(volume, path, format, orientation, reorient):
    """Fill in ``volume.meta`` (a :class:`Volume` or a :class:`~voxrender.io._stack.Stack`) as both readers do:
    format, source, orientation, affine and the origin of the canonical grid; return whether to reorient it.
    """
    volume.meta.setdefault("format", format)
    volume.meta.setdefault("source", str(path))
    if orientation is not None:
        volume.direction = orient.direction_of(orientation)
        volume.meta["orientation_from"] = "given"
    if volume.direction is None:
        volume.meta.setdefault("orientation_from", "unknown: the input does not say (stored order kept)")
        return False
    volume.meta["orientation"] = orient.code_of(volume.direction)
    volume.meta["affine"] = voxel_affine(volume.direction, volume.spacing, volume.meta.get("origin")).tolist()
    if reorient and "origin" in volume.meta:          # the position of the voxel that becomes values[0, 0, 0]
        corner = orient.canonical_corner(volume.shape, volume.direction)
        volume.meta["origin"] = (np.asarray(volume.meta["affine"])[:3] @ [*corner, 1.0]).tolist()
    return reorient


