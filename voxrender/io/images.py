"""A folder of 2-D images (PNG, TIFF, BMP, JPEG), one slice each, in natural order of names (imageio)."""

from __future__ import annotations

import struct
import zlib

from ..errors import InputError
from ._shared import Reader, Volume, files_in, fill_stack, first_line, listed, quiet_log, to_grey

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
    import imageio.v3 as iio

    files = [f for f in files_in(folder) if f.suffix.lower() in SUFFIXES]
    if not files:
        raise InputError(f"{folder} holds no images (PNG, TIFF, BMP, JPEG)")
    damaged = damaged_file_errors()

    def read(f):
        try:
            with quiet_log("tifffile"):
                image = iio.imread(f)
        except damaged as exc:
            raise InputError(f"cannot read image {f}: {first_line(exc)}") from None
        return to_grey(image, f.name), f.name

    values = fill_stack(files, read, "reading images", progress, folder)
    return Volume(values, (1.0, 1.0, 1.0), {"spacing_from": "default (images carry no spacing)",
                                            "slices": len(files)})


def holds_images(path):
    """A folder holding image files."""
    return path.is_dir() and any(f.suffix.lower() in SUFFIXES for f in listed(path))


READER = Reader(read_images, sniff=holds_images)
