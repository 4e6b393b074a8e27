"""A folder of 2-D images (PNG, TIFF, BMP, JPEG), one slice each, in natural order of names (imageio)."""

from __future__ import annotations

from ..errors import InputError
from ._shared import Reader, Volume, files_in, fill_stack, first_line, listed, to_grey

SUFFIXES = (".png", ".tif", ".tiff", ".bmp", ".jpg", ".jpeg")


def read_images(folder, progress):
    """Read the images in ``folder`` as slices, in natural order of names (colour images become grey)."""
    import imageio.v3 as iio

    files = [f for f in files_in(folder) if f.suffix.lower() in SUFFIXES]
    if not files:
        raise InputError(f"{folder} holds no images (PNG, TIFF, BMP, JPEG)")

    def read(f):
        try:
            return to_grey(iio.imread(f), f.name), f.name
        except InputError:
            raise
        except Exception as exc:  # imageio raises many types for a bad file
            raise InputError(f"cannot read image {f}: {first_line(exc)}") from None

    values = fill_stack(files, read, "reading images", progress)
    return Volume(values, (1.0, 1.0, 1.0), {"spacing_from": "default (images carry no spacing)",
                                            "slices": len(files)})


def holds_images(path):
    """A folder holding image files."""
    return path.is_dir() and any(f.suffix.lower() in SUFFIXES for f in listed(path))


READER = Reader(read_images, sniff=holds_images)
