"""Renderers: one module per algorithm, and the registry ``METHODS`` of :class:`Method` records.

Every renderer is a function ``f(segments, view, progress=None, clip=None, **options)`` that takes
:class:`~voxrender.object.segments.Segments` and a :class:`~voxrender.space.view.View` with its scale set, and
returns ``(depth, stats)``: the float32 depth image of the view contract (``+inf`` where the ray meets
nothing) and a dict of the algorithm's own counts.  Its record says what else it needs.  Adding a
renderer is one module and one record (see ``docs/design.md``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..space.view import View
from .btf import render_btf
from .clip import Clip
from .ftb import render_ftb
from .octree_btf import render_octree_btf
from .octree_ftb import render_octree_ftb
from .octree_sort import render_octree_sort, render_zbuffer
from .preimage import render_preimage
from .raycast import render_raycast

__all__ = ["Method", "METHODS", "DEFAULT_METHOD", "DepthImage", "Clip", "render", "method_record", "octree_for",
           "framing_box"]


@dataclass(frozen=True)
class Method:
    """What the rest of voxrender needs to know about one rendering algorithm.

    Parameters
    ----------
    function : callable
        The renderer, ``function(segments, view, progress=None, clip=None, **options) -> (depth, stats)``.
    summary : str
        The algorithm and its paper, in a line.
    options : tuple of str
        The keyword options it takes besides ``progress`` and ``clip`` (e.g. ``"connectivity"``).
    preimage : bool
        It renders only alpha and beta (object rows parallel to scanlines, Theorem 1); gamma turns its
        supersampled pre-image (Theorem 2).  Such a method must return its item buffer (``items``).
    items : bool
        Called with ``items=True`` it also returns its item buffer ``(owner, boxes)``.
    octree : bool
        It traverses the region octree and takes it as ``tree=`` (built from the segments when not given).
    """

    function: Callable
    summary: str
    options: tuple = ()
    preimage: bool = False
    items: bool = False
    octree: bool = False

    def __post_init__(self):
        if self.preimage and not self.items:
            raise ValueError("a pre-image method must return its item buffer (items=True)")


METHODS = {
    "ftb": Method(render_ftb, "the dynamic screen, front to back (Reynolds, Gordon and Chen)",
                  preimage=True, items=True),
    "btf": Method(render_btf, "back to front, voxel by voxel (Frieder, Gordon and Reynolds)"),
    "raycast": Method(render_raycast, "discrete ray casting, 6-, 26- or adaptive rays (Cohen-Or and Kaufman)",
                      options=("connectivity", "compare")),
    "octree-btf": Method(render_octree_btf, "Meagher's back-to-front octree display", octree=True),
    "octree-ftb": Method(render_octree_ftb, "front-to-back octree display with blocking quadtrees (Zhao and Davis)",
                         octree=True),
    "octree-sort": Method(render_octree_sort, "the sorted linear octree (Chandran, Gupta and Patgawkar)",
                          options=("order",), octree=True),
    "zbuffer": Method(render_zbuffer, "the back-face-culled z-buffer of the same voxels (idem, Table 4)",
                      options=("count_writes",), octree=True),
}
DEFAULT_METHOD = "ftb"


def method_record(name, options=()):
    """The :class:`Method` registered as ``name``, which must take every one of ``options`` (names); an
    :class:`InputError` naming the choices otherwise.

    >>> method_record("raycast").options
    ('connectivity', 'compare')
    """
    if name not in METHODS:
        raise InputError(f"unknown method {name!r}; choose one of {', '.join(METHODS)}", parameter="method")
    record = METHODS[name]
    unknown = sorted(set(options) - set(record.options))
    if unknown:
        raise InputError(f"method {name!r} takes no option {unknown[0]!r} "
                         f"(its options: {', '.join(record.options) or 'none'})", parameter=unknown[0])
    return record


def octree_for(method, encoded, max_memory=None):
    """The region octree of ``encoded`` (a :class:`~voxrender.object.pipeline.Encoded`, which builds it once) when
    ``method`` traverses one, else ``None``; an octree that would need more than ``max_memory`` bytes is refused.
    """
    return encoded.octree(max_memory) if method_record(method).octree else None


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


def framing_box(segments, clip=None):
    """The bounding box a picture of ``segments`` is framed on: the object's, within the clip limits."""
    box = segments.bounding_box()
    return (clip.box(box) or box) if clip is not None and box is not None else box


def render(segments, view, method=DEFAULT_METHOD, progress=None, supersample=2, clip=None, fit="object",
           tree=None, **options):
    """Render ``segments`` with ``method`` from ``view``.

    Parameters
    ----------
    segments : Segments or Encoded
        The object, or the encoded object :func:`voxrender.load_segments` gives, whose region octree the
        octree methods then use (read from its ``.vxo``, or built once and kept).
    view : View
        Angles and picture size; an unset ``scale`` is fitted (see ``fit``).
    method : str
        A name in ``METHODS``.
    progress : callable, optional
        ``progress(iterable, length, label)``, e.g. a progress bar.
    supersample : int
        The pre-image's scale over the picture's, for methods that turn a pre-image by gamma.
    clip : Clip, optional
        Clip limits and cut plane.
    fit : {"object", "volume"}
        How an unset scale frames the picture: the object as this view sees it (its projected bounding box
        within the clip limits, centred, with a small margin), or the whole volume at any rotation, centred on
        the volume centre.
    tree : RegionOctree, optional
        The object's region octree, for octree methods (built here when not given).
    **options
        The method's own options (its record's ``options``, e.g. ``connectivity`` for ``raycast``).

    Returns
    -------
    DepthImage
        The depth image, the fitted view, the renderer's statistics and its seconds.

    Examples
    --------
    >>> from voxrender.object.segments import encode
    >>> image = render(encode(np.ones((3, 3, 3), bool)), View(size=(8, 8), scale=1.0))
    >>> int(image.coverage.sum()), image.stats["pixels_lit"]
    (16, 16)
    """
    record = method_record(method, options)
    encoded = segments if hasattr(segments, "octree") and hasattr(segments, "segments") else None
    if encoded is not None:                                   # an Encoded, which keeps its octree
        segments = encoded.segments
    segments.check()                                          # a file's runs, before they index anything
    if encoded is not None:
        tree = encoded.octree() if record.octree and tree is None else tree
    if not segments.segment_count:
        raise InputError("the object is empty: no voxel reaches the threshold")
    if fit not in ("object", "volume"):
        raise InputError(f"{fit!r}: choose 'object' or 'volume'", parameter="fit")
    if int(supersample) < 1:
        raise InputError(f"{supersample!r}: must be a whole number >= 1", parameter="supersample")
    view = view.fitted(segments.shape, framing_box(segments, clip), fit)
    if record.octree:
        options["tree"] = tree
    started = time.perf_counter()
    if record.preimage and view.gamma % 360:
        depth, stats = render_preimage(record.function, segments, view, supersample, progress, clip, **options)
    else:
        depth, stats = record.function(segments, view, progress=progress, clip=clip, **options)
    return DepthImage(depth, view, method, stats, time.perf_counter() - started)
