"""Gamma by rotating a pre-image (the dynamic-screen paper's Theorem 2).

Rotations alpha and beta fix the view direction; gamma only turns the picture
about the view axis.  A method that needs object rows parallel to scanlines
(Theorem 1) renders the pre-image of (alpha, beta, 0), supersampled, and the
pre-image is turned by gamma.  Depth does not change under that turn.

The renderer returns its item buffer (which box lit each pre-image pixel);
each final pixel re-evaluates the ray-box entry of the boxes that lit the
3 x 3 pre-image pixels around its rotated centre and keeps the nearest hit:
the depth is then exact wherever the visible box is among those nine.
"""

from __future__ import annotations

import numpy as np

from ..space.view import View
from .geometry import ray_box_entry


def preimage_view(view, supersample):
    """The (alpha, beta, 0) view at ``supersample`` times the scale that holds ``view`` at any gamma.

    Each side's parity is chosen so that, at gamma a multiple of 90 degrees, every final
    pixel centre falls on a pre-image pixel centre.

    >>> preimage_view(View(gamma=90, size=(10, 12), scale=1.0), 2).size
    (27, 23)
    """
    height, width = view.size
    g = np.radians(view.gamma)
    c, s = abs(np.cos(g)), abs(np.sin(g))
    along_x, along_y = (width, height) if c >= s else (height, width)

    def side(extent, final):
        n = int(np.ceil(extent * supersample)) + 2
        return n + (n - supersample * final - supersample + 1) % 2

    cx, cy = view.centre                                   # the picture's centre, in the pre-image: Rz(-gamma)
    centre = (float(np.cos(g) * cx + np.sin(g) * cy), float(-np.sin(g) * cx + np.cos(g) * cy))
    return View(view.alpha, view.beta, 0.0, (side(s * width + c * height, along_y),
                                             side(c * width + s * height, along_x)), view.scale * supersample,
                centre)


def _turn_items(owner, boxes, shape, view, pre_view):
    """Final depth image of ``view`` from a pre-image's item buffer (see the module docstring).

    ``owner`` is the ``(Hp, Wp)`` index of the box that lit each pre-image pixel (-1: none); ``boxes`` holds
    per box its object-space centre x, y, z and half-extent along x (a run of voxels).
    """
    height, width = view.size
    pre_height, pre_width = pre_view.size
    big_x, big_y = np.meshgrid(*view.pixel_centres())
    g = np.radians(view.gamma)
    pre_x = np.cos(g) * big_x + np.sin(g) * big_y      # Rz(-gamma) (X', Y')
    pre_y = -np.sin(g) * big_x + np.cos(g) * big_y
    u, v = (np.rint(c).astype(np.int64) for c in pre_view.pixel_index(pre_x, pre_y))
    matrix = pre_view.matrix
    depth = np.full((height, width), np.inf)
    for dv in (-1, 0, 1):
        for du in (-1, 0, 1):
            col, row = u + du, v + dv
            inside = (col >= 0) & (col < pre_width) & (row >= 0) & (row < pre_height)
            who = np.full((height, width), -1)
            who[inside] = owner[row[inside], col[inside]]
            has = who >= 0
            box = boxes[who[has]]
            xc, yc, zc = pre_view.to_image(box[:, 0], box[:, 1], box[:, 2], shape)
            hit, entry = ray_box_entry(pre_x[has] - xc, pre_y[has] - yc, matrix, box[:, 3])
            candidate = np.where(hit, zc + entry, np.inf)
            depth[has] = np.minimum(depth[has], candidate)
    return depth.astype(np.float32)


def render_preimage(renderer, segments, view, supersample=2, progress=None, clip=None, **options):
    """Render ``view`` as the pre-image of (alpha, beta) at ``supersample`` times the scale, turned by gamma.

    Parameters
    ----------
    renderer : callable
        A renderer that takes ``items=True`` and then also returns its item buffer ``(owner, boxes)``.
    segments : Segments
    view : View
        With ``scale`` set.
    supersample : int
        The pre-image's scale over the picture's.
    progress, clip, **options
        Passed to ``renderer``.

    Returns
    -------
    depth : ndarray of float32, (H, W)
    stats : dict
        The renderer's, with ``preimage_size`` and ``supersample``.

    Examples
    --------
    >>> from voxrender.object.segments import encode
    >>> from voxrender._render.ftb import render_ftb
    >>> depth, stats = render_preimage(render_ftb, encode(np.ones((2, 2, 2), bool)),
    ...                                View(gamma=45, size=(6, 6), scale=1.0))
    >>> int(np.isfinite(depth).sum()), stats["supersample"]
    (4, 2)
    """
    pre_view = preimage_view(view, supersample)
    pre, stats, (owner, boxes) = renderer(segments, pre_view, progress=progress, clip=clip, items=True, **options)
    depth = _turn_items(owner, boxes, segments.shape, view, pre_view)
    return depth, dict(stats, preimage_size=list(pre_view.size), supersample=supersample)
