"""Label images: which label each pixel of a multi-label picture shows.

The renderers draw the union of the labels and know nothing of them.  The label of a pixel is then looked up at
its hit point, the same way for every method: among the object's voxels whose cubes contain the point where the
pixel's ray meets the object, the one the ray enters first; where several are entered at exactly the same depth,
the smallest label (the contract's rule for ties).  So every method whose depth image keeps the contract gives
the same label image.
"""

from __future__ import annotations

import numpy as np

from .._render.geometry import ray_box_entry
from .._shared.label_sets import millilitres
from ..object.segments import label_at

# How far (voxels) a hit point computed from a float32 depth may lie from the cube it is on.
_ON_CUBE = 1e-3
# Entry depths (float64, voxels) closer than this are the same depth: a tie.
_SAME_DEPTH = 1e-7


def label_image(segments, image, clip=None):
    """The label image ``uint16 (H, W)`` of a rendered :class:`~voxrender._render.DepthImage`: 0 where the ray
    meets nothing (see the module docstring for the rule).

    Parameters
    ----------
    segments : Segments
        The object that was rendered (multi-label, or a single object: label 1).
    image : DepthImage
        Its depth image and the fitted view.
    clip : Clip, optional
        The clip it was rendered with: clipped voxels show no label.

    Examples
    --------
    >>> from voxrender.object.segments import encode_labels
    >>> from voxrender._render import render
    >>> from voxrender.space.view import View
    >>> values = np.zeros((3, 3, 4), np.uint16); values[1, 1, :2] = 3; values[1, 1, 2:] = 1
    >>> labels = label_image(encode_labels(values), render(encode_labels(values), View(size=(4, 8), scale=2.0)))
    >>> labels[2].tolist()
    [3, 3, 3, 3, 1, 1, 1, 1]
    """
    out = np.zeros(image.depth.shape, np.uint16)
    rows, columns, points = image.view.hit_points(image.depth, segments.shape)
    if not len(points):
        return out
    view, shape = image.view, segments.shape
    low = np.floor(points + 0.5 - _ON_CUBE).astype(np.int64)
    high = np.floor(points + 0.5 + _ON_CUBE).astype(np.int64)
    xs, ys = view.pixel_centres(columns, rows)
    best_depth = np.full(len(points), np.inf)
    best_label = np.zeros(len(points), np.uint16)
    corners = np.array(list(np.ndindex(2, 2, 2)))     # the (at most 8) cubes a point can lie on
    candidates = low[None] + corners[:, None]          # (8, N, 3)
    found = label_at(segments, *candidates.reshape(-1, 3).T).reshape(len(corners), -1)   # one look-up for all
    for voxel, label in zip(candidates, found, strict=True):
        label[(voxel > high).any(axis=1)] = 0
        if clip is not None:
            label[~clip.keeps(*voxel.T, view, shape)] = 0
        centre = view.to_image(*voxel.T, shape)
        met, entry = ray_box_entry(xs - centre[0], ys - centre[1], view.matrix)
        depth = np.where((label > 0) & met, entry + centre[2], np.inf)
        nearer = depth < best_depth - _SAME_DEPTH
        tie = ~nearer & (depth <= best_depth + _SAME_DEPTH)
        best_label = np.where(nearer, label, np.where(tie, np.minimum(best_label, label), best_label))
        best_depth = np.where(nearer, depth, best_depth)
    out[rows, columns] = best_label
    return out


def label_pixels(labels):
    """``{label: pixel count}`` of the labels a label image shows (0, the background, left out).

    >>> label_pixels(np.array([[0, 3, 3], [1, 0, 3]], np.uint16))
    {1: 1, 3: 3}
    """
    values, counts = np.unique(labels[labels > 0], return_counts=True)
    return {int(v): int(c) for v, c in zip(values, counts, strict=True)}


def label_list(table, voxels, spacing, pixels=None, ml=None, outside=None):
    """The rows a label list shows (``info``, ``--labels-out``, a batch's summary): each label of ``table``
    (``{label: (name, (r, g, b))}``) with its voxels, its volume in mL and, of a picture, the ``pixels`` it shows.
    The volume is ``ml[str(label)]`` when given (a label map's own count on its own grid, which resampling to cubic
    voxels would change by a slice's worth at each end), else ``voxels`` times the voxel volume of ``spacing``.
    A structure partly outside the image (``outside``, ``{str(label): mL}``) also gives ``ml_outside_image``: the
    volume it has beyond the image, which its ``ml`` (on the image's grid) does not hold.

    >>> label_list({2: ("liver", (40, 140, 40))}, {2: 1500}, (1.0, 1.0, 2.0), pixels={"2": 300})
    [{'label': 2, 'name': 'liver', 'colour': [40, 140, 40], 'voxels': 1500, 'ml': 3.0, 'pixels': 300}]
    """
    rows = []
    for label, (name, colour) in sorted(table.items()):
        count = int(voxels.get(label, 0))
        row = {"label": int(label), "name": name, "colour": [int(c) for c in colour], "voxels": count,
               "ml": (ml or {}).get(str(label), millilitres(count, spacing))}
        if (outside or {}).get(str(label)):
            row["ml_outside_image"] = outside[str(label)]
        if pixels is not None:
            row["pixels"] = int(pixels.get(str(label), 0))
        rows.append(row)
    return rows

