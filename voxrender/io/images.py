"""A folder of 2-D images (PNG, TIFF, BMP, JPEG), one slice each, in natural order of names (imageio)."""

from __future__ import annotations

import struct
import zlib

import numpy as np

from .._shared.text import first_line
from ..errors import InputError
from ._shared import Reader, Volume, files_in, fill_stack, listed, quiet_log, stack_type, to_grey
from ._stack import Stack

SUFFIXES = (".png", ".tif", ".tiff", ".bmp", ".jpg", ".jpeg")


def damaged_file_errors():
    """What imageio raises for an image file it cannot read, found by cutting and garbling files.

    Pillow's ``OSError`` (``UnidentifiedImageError`` among them), ``SyntaxError`` and ``ValueError`` for broken
    headers and ``DecompressionBombError`` for absurd sizes; tifffile's ``TiffFileError`` (a ``ValueError``),
    ``struct.error`` and ``zlib.error`` for cut-off files, ``RuntimeError`` for pages that contradict each other and
    ``NotImplementedError`` for compressions it cannot decode.  (A garbled TIFF header can also trip tifffile's own
    arithmetic, a ``ZeroDivisionError`` or ``TypeError``; those stay what they are, as any bug does, but for the
    ``ZeroDivisionError`` of tifffile's series detection, which the TIFF reader meets first and names.)
    """
    from PIL.Image import DecompressionBombError

    return (OSError, SyntaxError, ValueError, DecompressionBombError, struct.error, zlib.error, RuntimeError,
            NotImplementedError)


def read_images(folder, progress):
    """Read the images in ``folder`` as slices, in natural order of names (colour images become grey)."""
    files = _image_files(folder)
    values = fill_stack(files, lambda f: (_read_image(f), f.name), "reading images", progress, folder)
    return Volume(values, (1.0, 1.0, 1.0), _meta(files))


def open_images(folder):
    """The images in ``folder`` as a :class:`~voxrender.io._stack.Stack`, read a slab of files at a time; only the
    first is read now, for the slices' size and type.
    """
    files = _image_files(folder)
    first = _read_image(files[0])
    dtype = stack_type(first.dtype, folder)

    def read_slices(z0, z1):
        out = np.empty((z1 - z0, *first.shape), dtype)
        for k, f in enumerate(files[z0:z1]):
            place_slice(out, k, _read_image(f), f.name, files[0].name)
        return out

    return Stack((len(files), *first.shape), dtype, read_slices, (1.0, 1.0, 1.0), None, _meta(files),
                 sum(f.stat().st_size for f in files))


def _image_files(folder):
    files = [f for f in files_in(folder) if f.suffix.lower() in SUFFIXES]
    if not files:
        raise InputError(f"{folder} holds no images (PNG, TIFF, BMP, JPEG)")
    return files


def _read_image(f):
    """The slice of image file ``f`` (colour becomes grey), or one clean error."""
    import imageio.v3 as iio

    try:
        with quiet_log("tifffile"):
            image = iio.imread(f)
    except damaged_file_errors() as exc:
        raise InputError(f"cannot read image {f}: {first_line(exc)}") from None
    return to_grey(image, f.name)


def _meta(files):
    return {"spacing_from": "default (images carry no spacing)", "slices": len(files)}


def place_slice(out, k, data, name, first):
    """Put the slice ``data`` (of file ``name``) at ``out[k]``, a slab of a stack whose first slice is file
    ``first``.  A slice of another size is refused, as :func:`~voxrender.io._shared.fill_stack` refuses it; so is
    one of a type the stack's cannot hold, which a volume read whole would widen to: a stack's type is fixed
    when it is opened.
    """
    if data.shape != out.shape[1:]:
        raise InputError(f"slice {name} is {data.shape[-1]}x{data.shape[-2]} but {first} is "
                         f"{out.shape[2]}x{out.shape[1]}; all slices must have the same size")
    if not np.can_cast(data.dtype, out.dtype, "safe"):
        raise InputError(f"slice {name} holds {data.dtype.name} values but {first} holds {out.dtype.name}; a "
                         "stack read slab by slab keeps the type of its first slice: store every slice in one "
                         "type, or read the stack whole with read_volume")
    out[k] = data


def holds_images(path):
    """A folder holding image files."""
    return path.is_dir() and any(f.suffix.lower() in SUFFIXES for f in listed(path))


READER = Reader(read_images, sniff=holds_images, open=open_images)
