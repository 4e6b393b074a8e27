"""Renderers: one module per algorithm, and the registry ``METHODS`` from name to function.

Every renderer takes :class:`~voxrender.segments.Segments` and a fitted
:class:`~voxrender.view.View` and returns ``(depth, stats)``: the float32 depth
image of the view contract (``+inf`` where the ray meets nothing) and a dict of
the algorithm's own counts.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..view import View
from .btf import render_btf
from .clip import Clip
from .ftb import render_ftb
from .preimage import render_preimage
from .octree_btf import render_octree_btf
from .octree_ftb import render_octree_ftb
from .octree_sort import render_octree_sort, render_zbuffer
from .raycast import render_raycast

__all__ = ["METHODS", "DEFAULT_METHOD", "DepthImage", "Clip", "render", "render_preimage"]

METHODS = {
    "ftb": render_ftb,
    "btf": render_btf,
    "raycast": render_raycast,
    "octree-btf": render_octree_btf,
    "octree-ftb": render_octree_ftb,
    "octree-sort": render_octree_sort,
    "zbuffer": render_zbuffer,
}
DEFAULT_METHOD = "ftb"
# Methods that render only alpha and beta (rows stay parallel to scanlines, Theorem 1);
# gamma is then applied by rotating a supersampled pre-image (Theorem 2).
PREIMAGE_METHODS = {"ftb"}


@dataclass
class DepthImage:
    """A rendered view: ``depth`` (float32, H x W, ``+inf`` background), the renderer's ``stats``, the ``view``."""

    depth: np.ndarray
    view: View
    method: str
    stats: dict = field(default_factory=dict)
    seconds: float = 0.0

    @property
    def coverage(self):
        return np.isfinite(self.depth)


def render(segments, view, method=DEFAULT_METHOD, progress=None, supersample=2, clip=None, fit="volume",
           **options):
    """Render ``segments`` with ``method`` from ``view`` (scale fitted when unset).

    ``supersample`` is the pre-image's scale factor for methods that apply gamma by
    rotating a pre-image; ``clip`` is a :class:`Clip` (clip limits, cut plane) or ``None``;
    ``fit`` chooses what an unset scale fits at any rotation: the ``"volume"`` (the contract's
    default) or the ``"object"`` (its bounding box; it still turns about the volume centre);
    further ``options`` go to the method (``connectivity`` for ``raycast``).

    >>> from voxrender.segments import encode
    >>> image = render(encode(np.ones((3, 3, 3), bool)), View(size=(8, 8), scale=1.0))
    >>> int(image.coverage.sum()), image.stats["pixels_lit"]
    (16, 16)
    """
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    if not segments.segment_count:
        raise InputError("the object is empty: no voxel reaches the threshold")
    if fit not in ("volume", "object"):
        raise InputError(f"--fit {fit!r}: choose volume or object")
    view = view.fitted(segments.shape, segments.bounding_box() if fit == "object" else None)
    started = time.perf_counter()
    if method in PREIMAGE_METHODS and view.gamma % 360:
        depth, stats = render_preimage(METHODS[method], segments, view, supersample, progress, clip)
    else:
        depth, stats = METHODS[method](segments, view, progress=progress, clip=clip, **options)
    return DepthImage(depth, view, method, stats, time.perf_counter() - started)
