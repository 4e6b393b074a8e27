"""A multi-page TIFF, one page a slice (tifffile), its spacing from ImageJ or OME metadata."""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from .._shared.text import first_line
from ..errors import InputError
from ._shared import Reader, Volume, check_fits, check_holds, quiet_log, stack_type, to_grey
from ._stack import Stack
from .images import damaged_file_errors, place_slice

SUFFIXES = (".tif", ".tiff")


def read_tiff(path, progress):
    """Read the pages of a TIFF as slices (colour pages become grey).

    The slices are tifffile's first series (ImageJ's and tifffile's own stacks, OME's), or, when that series is one
    page, every page of the file of that page's shape and type: a stack written page by page is a series a page.
    A file whose list of pages breaks off before the pages it promised is cut short, not a shorter stack.
    """
    pages = _pages_of(path)
    check_fits(pages.shape, pages.dtype, path)
    spacing, spacing_from = _tiff_spacing(path)
    return Volume(_grey(pages.read(0, pages.shape[0]), path), spacing, {"spacing_from": spacing_from})


def open_tiff(path):
    """The pages of a TIFF as a :class:`~voxrender.io._stack.Stack`, read a slab of pages at a time: at their
    offsets when they are stored uncompressed, else by tifffile, those pages only.
    """
    pages = _pages_of(path)
    colour = len(pages.shape) == 4 and pages.shape[-1] in (3, 4)
    first = _grey(pages.read(0, 1), path)[0] if colour else None      # grey colour pages keep their type
    dtype = stack_type(first.dtype if colour else pages.dtype, path)

    def read_slices(z0, z1):
        values = _grey(pages.read(z0, z1), path)
        if not colour:
            return values.astype(dtype, copy=False)
        out = np.empty(values.shape, dtype)
        for k, page in enumerate(values):
            place_slice(out, k, page, f"page {z0 + k} of {path.name}", "page 0")
        return out

    spacing, spacing_from = _tiff_spacing(path)
    shape = pages.shape[:3] if colour else pages.shape
    return Stack(shape, dtype, read_slices, spacing, None, {"spacing_from": spacing_from}, path.stat().st_size,
                 sequential=pages.offsets is None and pages.keys is None)


@dataclass
class _Pages:
    """The pages of a TIFF that make its stack: ``shape`` (pages first, colour samples last) and ``dtype`` as
    stored (in the file's byte order); ``offsets`` where each page's data starts, when every page is stored whole
    and uncompressed, else ``keys``, their numbers in the file (``None``: the series is read whole, its pages not
    one a slice); ``series``: they are tifffile's first series, not a page of each.
    """

    path: object
    shape: tuple
    dtype: np.dtype
    offsets: np.ndarray | None = None
    keys: list | None = None
    series: bool = True

    def read(self, k0, k1):
        """Pages ``k0 .. k1 - 1`` as an array ``[k1 - k0, ...]`` in native byte order: a whole series by tifffile,
        which knows its layouts best, a slab at its offsets or by its pages' numbers; a damaged file is bad input.
        """
        whole = self.series and (k0, k1) == (0, self.shape[0])
        if self.offsets is not None and not whole:
            return self._at_offsets(k0, k1)
        import tifffile

        try:
            with quiet_log("tifffile"), tifffile.TiffFile(self.path) as tif:
                if self.series and (whole or self.keys is None):
                    values = _first_series(tif, self.path).asarray()[k0:k1]
                else:
                    values = tif.asarray(key=self.keys[k0:k1])
        except InputError:
            raise
        except (*damaged_file_errors(), IndexError) as exc:
            raise InputError(f"cannot read TIFF {self.path}: {first_line(exc)}") from None
        values = values.reshape(k1 - k0, *self.shape[1:])
        return values.astype(values.dtype.newbyteorder("="), copy=False)

    def _at_offsets(self, k0, k1):
        """Pages read at their offsets: consecutive ones by one call (no memory map, whose pages stay resident)."""
        page = int(np.prod(self.shape[1:]))
        starts = self.offsets[k0:k1]
        runs = np.flatnonzero(np.diff(starts) != page * self.dtype.itemsize) + 1   # where a page does not follow on
        out = np.empty((k1 - k0, *self.shape[1:]), self.dtype.newbyteorder("="))
        for lo, hi in zip([0, *runs], [*runs, k1 - k0], strict=True):
            values = np.fromfile(self.path, self.dtype, count=(hi - lo) * page, offset=int(starts[lo]))
            if values.size != (hi - lo) * page:
                raise InputError(f"{self.path} ends within page {k0 + lo + values.size // page}; the file is "
                                 "truncated")
            out[lo:hi] = values.reshape(hi - lo, *self.shape[1:])
        return out


def _pages_of(path):
    """The pages that make the stack of the TIFF ``path`` (see :func:`read_tiff`), checked: a file cut short or
    damaged, or a single image, is bad input.
    """
    import tifffile

    try:
        with quiet_log("tifffile") as logged, tifffile.TiffFile(path) as tif:
            series = _first_series(tif, path)
            first = tif.pages.first
            count = len(tif.pages)
            broken = next((line for line in logged if "invalid page offset" in line), None)
            byteorder = tif.byteorder
            one_series = not (len(tif.series) > 1 and series.ndim - (first.samplesperpixel > 1) == 2)
            if not one_series:                                                             # a series a page
                pages = [page for page in tif.pages if page.shape == first.shape and page.dtype == first.dtype]
                shape = (len(pages), *first.shape)
            else:
                pages = list(series.pages)
                shape = series.shape
                if len(pages) != shape[0] or any(page is None or page.shape != shape[1:] for page in pages):
                    pages = None                                     # the pages are not the slices
            dtype = np.dtype(byteorder + series.dtype.char)
            offsets = keys = None
            if one_series and series.dataoffset is not None and len(shape) > 2:               # one block of data
                offsets = series.dataoffset + np.arange(shape[0]) * _page_bytes(shape, dtype)
            elif pages is not None and all(page.is_final for page in pages):
                offsets = np.array([page.dataoffsets[0] for page in pages], np.int64)
            elif pages is not None:
                keys = [page.index for page in pages]
            promised = series.shape[0] if (tif.is_shaped or tif.is_imagej) and series.ndim > 2 else None
    except InputError:
        raise
    except (*damaged_file_errors(), IndexError) as exc:          # IndexError: a file of no series
        raise InputError(f"cannot read TIFF {path}: {first_line(exc)}") from None
    if broken and (len(shape) == 2 or promised is None or shape[0] < promised):   # pages past the break lost
        raise InputError(f"{path} is cut short or damaged: its list of pages breaks off after {count} "
                         f"page{'s' * (count > 1)} ({broken.split('> ')[-1]})")
    if len(shape) == 2:
        raise InputError(f"{path} is a single 2-D image; give a multi-page TIFF or a folder of slices")
    if offsets is not None:
        check_holds(path, int(offsets.max()) + _page_bytes(shape, dtype), path.stat().st_size)
    return _Pages(path, tuple(shape), dtype, offsets, keys, one_series)


def _page_bytes(shape, dtype):
    return int(np.prod(shape[1:], dtype=np.int64)) * dtype.itemsize


def _grey(values, path):
    """Pages ``[k, ...]`` as grey slices: colour pages become luminance (see :func:`~voxrender.io._shared.to_grey`)."""
    if values.ndim == 4 and values.shape[-1] in (3, 4):
        return np.stack([to_grey(page, path.name) for page in values])
    return values


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


READER = Reader(read_tiff, SUFFIXES, open=open_tiff)
