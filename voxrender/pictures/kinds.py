"""What a picture draws: the object's surface (:data:`SURFACE`) or a projection of the grey values along the rays
(:data:`PROJECTIONS`: the maximum, the minimum, the mean), each a record of what it needs and gives, as
:data:`voxrender.METHODS` is for the renderers.  The rest of voxrender asks the record (``options.drawn``), never
which projection it is.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Drawn:
    """One kind of picture.

    Parameters
    ----------
    name : str
        Its name: ``surface``, or the projection's (``--projection``).
    help : str
        What it shows, in words.
    grey_values : bool
        It draws the grey values: it needs them (a :class:`~voxrender.qc.study.Study`, read beside the object),
        and a window shows them.
    depth : bool
        Its pixels have a depth (the depth outputs, normals and shading).
    labels : bool
        It draws the labels, each in its colour (a label image, a picture per label).
    plane : callable, optional
        A projection's own projection of the volume ``values[z, y, x]`` along y, whose 1st to 99th percentile is its
        window when none is given: every view of it is then shown alike (:meth:`voxrender.qc.study.Study.window`).

    Notes
    -----
    The framing of every kind is the surface's: the same fitted view, so a projection lies on its surface picture
    pixel for pixel.
    """

    name: str
    help: str
    grey_values: bool
    depth: bool
    labels: bool
    plane: Callable | None = None


SURFACE = Drawn("surface", "the object's surface, shaded", grey_values=False, depth=True, labels=True)
# fmax and fmin pass over NaN voxels and reduce without a copy of the volume
PROJECTIONS = {
    "mip": Drawn("mip", "the maximum of the grey values along each ray", True, False, False,
                 lambda values: np.fmax.reduce(values, axis=1)),
    "minip": Drawn("minip", "the minimum of the grey values along each ray", True, False, False,
                   lambda values: np.fmin.reduce(values, axis=1)),
    "mean": Drawn("mean", "the mean of the grey values along each ray, weighted by the length within each voxel",
                  True, False, False, lambda values: np.add.reduce(values, axis=1, dtype=np.float64) / values.shape[1]),
}
