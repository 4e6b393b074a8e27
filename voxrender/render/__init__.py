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
from ..shade import rotate_depth
from ..view import View
from .btf import render_btf

__all__ = ["METHODS", "DepthImage", "render"]

METHODS = {
    "btf": render_btf,
}
# Methods that render only alpha and beta (rows stay parallel to scanlines, Theorem 1);
# gamma is then applied by rotating a supersampled pre-image (Theorem 2).
PREIMAGE_METHODS = set()


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


def render(segments, view, method="btf", progress=None, supersample=2):
    """Render ``segments`` with ``method`` from ``view`` (scale fitted when unset).

    >>> from voxrender.segments import encode
    >>> image = render(encode(np.ones((3, 3, 3), bool)), View(size=(8, 8), scale=1.0))
    >>> int(image.coverage.sum()), image.stats["voxels_projected"]
    (16, 27)
    """
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    if not segments.segment_count:
        raise InputError("the object is empty: no voxel reaches the threshold")
    view = view.fitted(segments.shape)
    started = time.perf_counter()
    if method in PREIMAGE_METHODS and view.gamma % 360:
        depth, stats = render_preimage(METHODS[method], segments, view, supersample, progress)
    else:
        depth, stats = METHODS[method](segments, view, progress=progress)
    return DepthImage(depth, view, method, stats, time.perf_counter() - started)


def render_preimage(renderer, segments, view, supersample=2, progress=None):
    """Render ``view`` as the pre-image of (alpha, beta) at ``supersample`` times the scale, turned by gamma.

    The pre-image is large enough to hold the final image at any gamma.

    >>> from voxrender.segments import encode
    >>> from voxrender.render.btf import render_btf
    >>> depth, _ = render_preimage(render_btf, encode(np.ones((2, 2, 2), bool)),
    ...                            View(gamma=45, size=(6, 6), scale=1.0))
    >>> int(np.isfinite(depth).sum())
    4
    """
    height, width = view.size
    g = np.radians(view.gamma)
    reach = abs(np.cos(g)), abs(np.sin(g))
    pre_size = (int(np.ceil((reach[1] * width + reach[0] * height) * supersample)) + 2,
                int(np.ceil((reach[0] * width + reach[1] * height) * supersample)) + 2)
    pre_view = View(view.alpha, view.beta, 0.0, pre_size, view.scale * supersample)
    pre, stats = renderer(segments, pre_view, progress=progress)
    stats = dict(stats, preimage_size=list(pre_size), supersample=supersample)
    return rotate_depth(pre, view.gamma, view.size, pre_view.scale, view.scale), stats
