"""A multi-page TIFF, one page a slice (imageio and tifffile), its spacing from ImageJ or OME metadata."""

from __future__ import annotations

import re

import numpy as np

from ..errors import InputError
from ._shared import Reader, Volume, check_fits, first_line, quiet_log, to_grey
from .images import damaged_file_errors

SUFFIXES = (".tif", ".tiff")


def read_tiff(path, progress):
    """Read the pages of a TIFF as slices (colour pages become grey).

    The slices are tifffile's first series (ImageJ's and tifffile's own stacks, OME's), or, when that series is one
    page, every page of the file of that page's shape and type: a stack written page by page is a series a page.
    A file whose list of pages breaks off before the pages it promised is cut short, not a shorter stack.
    """
    import tifffile

    try:
        with quiet_log("tifffile") as logged, tifffile.TiffFile(path) as tif:
            series = _first_series(tif, path)
            first = tif.pages.first
            pages = len(tif.pages)
            broken = next((line for line in logged if "invalid page offset" in line), None)
            shape, read = series.shape, series.asarray
            if len(tif.series) > 1 and series.ndim - (first.samplesperpixel > 1) == 2:     # a series a page
                alike = [k for k, page in enumerate(tif.pages)
                         if page.shape == first.shape and page.dtype == first.dtype]
                shape = (len(alike), *first.shape)
                read = lambda: tif.asarray(key=alike)                                   # noqa: E731
            check_fits(shape, series.dtype, path)
            values = read()
    except InputError:
        raise
    except (*damaged_file_errors(), IndexError) as exc:          # IndexError: a file of no series
        raise InputError(f"cannot read TIFF {path}: {first_line(exc)}") from None
    promised = series.shape[0] if (tif.is_shaped or tif.is_imagej) and series.ndim > 2 else None
    if broken and (values.ndim == 2 or promised is None or len(values) < promised):   # pages past the break lost
        raise InputError(f"{path} is cut short or damaged: its list of pages breaks off after {pages} "
                         f"page{'s' * (pages > 1)} ({broken.split('> ')[-1]})")
    if values.ndim == 2:
        raise InputError(f"{path} is a single 2-D image; give a multi-page TIFF or a folder of slices")
    if values.ndim == 4 and values.shape[-1] in (3, 4):
        values = np.stack([to_grey(page, path.name) for page in values])
    spacing, spacing_from = _tiff_spacing(path)
    return Volume(values, spacing, {"spacing_from": spacing_from})


def _first_series(tif, path):
    """The first series tifffile finds in an open file; its detection dividing by a page of size zero, asserting
    that pages agree, or looking up a tag a page lacks (a page without its ImageWidth: ``KeyError: 256``) is a
    damaged file.
    """
    try:
        return tif.series[0]
    except (ZeroDivisionError, AssertionError, KeyError):
        raise InputError(f"cannot read TIFF {path}: its page shapes, tags or series description are damaged") \
            from None


def _tiff_spacing(path):
    """Voxel spacing (x, y, z) in mm from OME or ImageJ metadata, and where it came from; 1 mm when neither says."""
    import tifffile

    units = {"mm": 1.0, "millimeter": 1.0, "um": 1e-3, "µm": 1e-3, "micron": 1e-3, "micrometer": 1e-3,
             "nm": 1e-6, "cm": 10.0, "m": 1000.0}
    try:
        with quiet_log("tifffile"), tifffile.TiffFile(path) as tif:
            if tif.ome_metadata:
                sizes, scale = [], []
                for axis in "XYZ":
                    found = re.search(rf'PhysicalSize{axis}="([0-9.eE+-]+)"', tif.ome_metadata)
                    unit = re.search(rf'PhysicalSize{axis}Unit="([^"]+)"', tif.ome_metadata)
                    sizes.append(float(found.group(1)) if found else None)
                    scale.append(units.get(unit.group(1), 1e-3) if unit else 1e-3)   # OME's default unit: µm
                if all(s is not None and s > 0 for s in sizes):
                    return tuple(s * f for s, f in zip(sizes, scale, strict=True)), "OME metadata"
            if tif.imagej_metadata:
                page = tif.pages[0]
                factor = units.get(str(tif.imagej_metadata.get("unit", "")).replace("\\u00B5", "µ"), 1.0)
                resolution = []
                for tag in ("XResolution", "YResolution"):
                    value = page.tags.get(tag)
                    numerator, denominator = value.value if value is not None else (1, 1)
                    resolution.append(denominator / numerator if numerator else 1.0)
                z = float(tif.imagej_metadata.get("spacing", 1.0))
                spacing = tuple(v * factor for v in (*resolution, z))
                if all(v > 0 for v in spacing):
                    return spacing, "ImageJ metadata"
    except (OSError, ValueError, KeyError, TypeError):      # metadata of the wrong shape: no spacing from it
        pass
    return (1.0, 1.0, 1.0), "default (the TIFF has no ImageJ or OME spacing)"


READER = Reader(read_tiff, SUFFIXES)
