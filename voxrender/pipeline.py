"""The steps every command shares: from a path on disk to the encoded object.

A ``.vxs`` file is loaded as it is; anything else is read as a slice stack,
cropped, resampled, thresholded and encoded.  The result, :class:`Encoded`, also
keeps what renderers derive from the segments (the region octree), built once on
first use, so that a batch worker rendering many views pays for it once.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from . import io, prep, segments
from .errors import InputError

__all__ = ["ReadOptions", "PrepOptions", "Encoded", "load_segments", "is_segments_file"]


@dataclass(frozen=True)
class ReadOptions:
    """How to read a slice stack (see :func:`voxrender.io.read_volume`)."""

    format: str = "auto"
    raw: io.RawLayout | None = None
    spacing: tuple | None = None
    series: str | None = None
    frame: int | None = None
    orientation: str | None = None
    reorient: bool = True

    def read(self, path, progress=None):
        return io.read_volume(path, format=self.format, raw=self.raw, spacing=self.spacing, series=self.series,
                              frame=self.frame, orientation=self.orientation, reorient=self.reorient,
                              progress=progress)


@dataclass(frozen=True)
class PrepOptions:
    """How to turn values into a binary object (see :func:`voxrender.prep.binarize`)."""

    threshold: float | Callable = prep.otsu_threshold
    crop: tuple | None = None
    voxel: float | None = None
    resample: bool = True
    min_object: int = 0

    def __post_init__(self):
        if self.voxel is not None and not (self.voxel > 0 and math.isfinite(self.voxel)):
            raise InputError(f"{self.voxel} must be a positive size in mm", parameter="voxel")
        if self.min_object < 0:
            raise InputError(f"{self.min_object} must be 0 or more voxels", parameter="min_object")


def is_segments_file(path):
    return Path(path).suffix.lower() == ".vxs"


@dataclass
class Encoded:
    """An encoded object: its segments (with their surface normals), the seconds spent loading (``load``) and
    preparing (``prepare``) them, and the region octree, built on first use and kept (:meth:`octree`)."""

    segments: segments.Segments
    seconds: dict = field(default_factory=dict)
    _octree: object = field(default=None, repr=False)

    def octree(self):
        """The region octree of the object (built now if it has not been)."""
        if self._octree is None:
            from .octree import build   # scipy.sparse: only for the octree methods

            self._octree = build(self.segments.to_mask())
        return self._octree

    def tree_for(self, method):
        """The region octree when ``method`` traverses one (see :meth:`octree`), else ``None``."""
        from .render import method_record

        return self.octree() if method_record(method).octree else None


def load_segments(path, read=None, prepare=None, progress=None):
    """The object in ``path``: a ``.vxs`` file, or a slice stack to binarize and encode.

    Parameters
    ----------
    path : str or Path
    read : ReadOptions, optional
    prepare : PrepOptions, optional
    progress : callable, optional

    Returns
    -------
    Encoded

    Examples
    --------
    >>> import tempfile, pathlib, numpy as np
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "cube.npy"
    >>> np.save(path, np.pad(np.full((2, 2, 2), 100, np.int16), 1))
    >>> load_segments(path, prepare=PrepOptions(threshold=50)).segments.voxel_count
    8
    """
    read = read or ReadOptions()
    prepare = prepare or PrepOptions()
    started = time.perf_counter()
    if is_segments_file(path):
        if not Path(path).is_file():
            raise InputError(f"no such file: {path}")
        return Encoded(segments.load(path), {"load": time.perf_counter() - started, "prepare": 0.0})
    volume = read.read(path, progress)
    loaded = time.perf_counter()
    mask, info = prep.binarize(volume, prepare.threshold, crop=prepare.crop, voxel=prepare.voxel,
                               resample=prepare.resample, min_object=prepare.min_object, progress=progress)
    meta = {"source": str(path), "threshold": info["threshold"], "voxel_mm": info["voxel"],
            "input_shape": list(volume.shape), "input_spacing": list(volume.spacing)}
    meta.update({k: v for k, v in volume.meta.items()
                 if k in ("format", "modality", "units", "series", "orientation", "orientation_from", "reoriented")})
    encoded = segments.encode(mask, info["spacing"], meta)
    encoded.normals = grey_normals(volume, mask, info, prepare)
    encoded.meta["normals_from"] = encoded.normals.source
    return Encoded(encoded, {"load": loaded - started, "prepare": time.perf_counter() - loaded})


def grey_normals(volume, mask, info, prepare):
    """The surface normals of ``mask`` from the volume's grey values (trilinear samples of the cropped input at the
    mask's grid points); from the mask itself when the volume holds only two values (a binary input)."""
    from scipy import ndimage

    from .normals import surface_normals

    values = prep.crop(volume.values, prepare.crop)
    if len(np.unique(np.asarray(values[::7, ::7, ::7]))) <= 2:
        return surface_normals(mask)
    # a mask grid point k along an axis lies k * voxel / spacing input voxels from the first
    step = np.array([info["voxel"] / s for s in volume.spacing]) if prepare.resample else np.ones(3)

    if np.allclose(step, 1):                                  # the grid is the input's: read the voxels
        top = np.array(values.shape[::-1]) - 1
        flat = np.ravel(values)                              # a view when the volume is not cropped
        strides = np.array([1, values.shape[2], values.shape[1] * values.shape[2]])

        def sample(points):
            return flat[np.clip(points, 0, top) @ strides]
    else:
        def sample(points):
            return ndimage.map_coordinates(values, (points * step)[:, ::-1].T, order=3, mode="nearest")

    return surface_normals(mask, sample)
