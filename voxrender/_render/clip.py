"""Clipping and cutaway views (the dynamic-screen paper's section 7), applied as loop limits.

Object-space clip limits keep the voxels with ``x0 <= x < x1`` (likewise y, z); the
image-space cut plane drops every voxel whose centre is nearer than ``Z' = cut_depth``,
so the picture shows the inside of the object.  Both act on run-length segments as
they are read (a run is shortened or skipped), with no re-encoding.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError


@dataclass(frozen=True)
class Clip:
    """Clip limits ``(lo, hi)`` per object axis (half-open, ``None`` for open) and a cut depth.

    Examples
    --------
    >>> clip = Clip(x=(2, None))
    >>> from voxrender.space.view import View
    >>> keep, starts, ends = clip.apply_runs(np.array([0, 0]), np.array([0, 0]), np.array([0, 4]),
    ...                                      np.array([1, 6]), View(scale=1.0), (1, 1, 8))
    >>> keep.tolist(), starts.tolist(), ends.tolist()
    ([False, True], [2, 4], [1, 6])
    """

    x: tuple | None = None
    y: tuple | None = None
    z: tuple | None = None
    cut_depth: float | None = None

    def __post_init__(self):
        if self.cut_depth is not None and not math.isfinite(self.cut_depth):
            raise InputError(f"{self.cut_depth} must be a finite depth in voxels", parameter="cut_depth")

    @property
    def active(self):
        return any(v is not None for v in (self.x, self.y, self.z, self.cut_depth))

    def box(self, box):
        """The part of a bounding box ``((z0, z1), (y0, y1), (x0, x1))`` (inclusive) within the clip limits, so
        that a picture is framed on what is kept; ``None`` when nothing is.

        >>> Clip(x=(2, None)).box(((0, 5), (0, 5), (0, 9)))
        ((0, 5), (0, 5), (2, 9))
        """
        limited = []
        for (lo, hi), bounds in zip(box, (self.z, self.y, self.x), strict=True):
            if bounds is not None:
                lo = lo if bounds[0] is None else max(lo, bounds[0])
                hi = hi if bounds[1] is None else min(hi, bounds[1] - 1)
            if lo > hi:
                return None
            limited.append((lo, hi))
        return tuple(limited)

    def apply_runs(self, z, y, starts, ends, view, shape):
        """Clip runs ``[starts, ends]`` of rows ``(z, y)``; return ``(keep, starts, ends)``.

        ``view`` places the cut plane; ``shape = (nz, ny, nx)`` is the volume's.
        """
        starts = np.asarray(starts, dtype=np.int64)
        ends = np.asarray(ends, dtype=np.int64)
        keep = np.ones(starts.shape, bool)
        for bounds, index in ((self.y, y), (self.z, z)):
            if bounds is not None:
                lo, hi = bounds
                keep &= (index >= (lo if lo is not None else -np.inf)) & (index < (hi if hi is not None else np.inf))
        if self.x is not None:
            lo, hi = self.x
            if lo is not None:
                starts = np.maximum(starts, lo)
            if hi is not None:
                ends = np.minimum(ends, hi - 1)
        if self.cut_depth is not None:
            nx = shape[2]
            # Z' of a voxel centre is r20 (x - cx) + rest(y, z), rest being Z' at x = cx; keep Z' >= cut_depth.
            r20 = view.matrix[2, 0]
            rest = view.to_image((nx - 1) / 2, y, z, shape)[2]
            if abs(r20) < 1e-12:
                keep &= rest >= self.cut_depth - 1e-9
            else:
                bound = (nx - 1) / 2 + (self.cut_depth - rest) / r20
                if r20 > 0:
                    starts = np.maximum(starts, np.ceil(bound - 1e-9).astype(np.int64))
                else:
                    ends = np.minimum(ends, np.floor(bound + 1e-9).astype(np.int64))
        return keep & (starts <= ends), starts, ends

    def keeps(self, x, y, z, view, shape):
        """Whether the voxels at integer ``(x, y, z)`` of a ``shape = (nz, ny, nx)`` volume survive the clip."""
        keep = np.ones(np.broadcast(x, y, z).shape, bool)
        for bounds, index in ((self.x, x), (self.y, y), (self.z, z)):
            if bounds is not None:
                lo, hi = bounds
                keep &= (index >= (lo if lo is not None else 0)) & (index < (hi if hi is not None else 1 << 62))
        if self.cut_depth is not None:
            keep &= view.to_image(x, y, z, shape)[2] >= self.cut_depth - 1e-9
        return keep

    def apply_mask(self, mask, view):
        """The voxels of ``mask[z, y, x]`` that survive the clip, as a new mask (for references and tests)."""
        z, y, x = np.indices(mask.shape)
        return mask & self.keeps(x, y, z, view, mask.shape)
