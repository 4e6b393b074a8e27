"""Views: rotations, the projection contract, view-plane normals and Theorem 2.

The contract (``docs/design.md``): a voxel is the closed unit cube centred on its grid
point ``p = (x, y, z)``; image space is ``p' = R (p - c)`` with ``c`` the volume
centre and ``R = Rz(gamma) Ry(beta) Rx(alpha)``; the projection is orthographic,
the viewer at ``Z' = -inf`` looking toward ``+Z'``; pixel ``(row j, column i)``
has its centre at ``X' = (i + 0.5 - W/2) / scale``, ``Y' = (j + 0.5 - H/2) / scale``.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from ..errors import InputError

# Viewer positions for a stack read in DICOM patient order (LPS): x runs to the
# patient's left, y to the back, z up to the head.  Image up is the head (or, seen
# from above and below, the face); see the README's table.
PRESETS = {
    "inferior": (0.0, 0.0, 0.0),
    "anterior": (90.0, 0.0, 0.0),
    "posterior": (90.0, 180.0, 0.0),
    "left": (90.0, 90.0, 0.0),
    "right": (90.0, -90.0, 0.0),
    "superior": (0.0, 180.0, 0.0),
}


def rotation_matrix(alpha, beta, gamma=0.0):
    """``Rz(gamma) @ Ry(beta) @ Rx(alpha)``, angles in degrees (the paper's Eq. 2).

    >>> np.round(rotation_matrix(90, 0, 0)).astype(int)
    array([[ 1,  0,  0],
           [ 0,  0, -1],
           [ 0,  1,  0]])
    """
    (ca, sa), (cb, sb), (cg, sg) = (_cos_sin(angle) for angle in (alpha, beta, gamma))
    rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    rz = np.array([[cg, -sg, 0], [sg, cg, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _cos_sin(degrees):
    """Cosine and sine, exact at multiples of 90 degrees: an axis-aligned view then has exact zeros in its
    matrix (cos 90 would be 6e-17), so rays along voxel faces stay on them and the octree methods see the
    viewing class (one, two or three visible faces) the view really has.
    """
    if float(degrees) % 90 == 0:
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[int(float(degrees) // 90) % 4]
    radians = math.radians(degrees)
    return math.cos(radians), math.sin(radians)


def angles_from_matrix(matrix):
    """Theorem 2: angles ``(alpha, beta, gamma)`` in degrees with ``rotation_matrix(...) == matrix``.

    Of the two solutions, ``(alpha, beta, gamma)`` and ``(alpha + 180, 180 - beta, gamma + 180)``, the one with
    ``gamma = 0`` is returned when there is one, so that no pre-image rotation is needed (a turntable about the
    head's axis keeps ``gamma = 0`` all the way round), else the one with ``-90 <= beta <= 90``.  When
    ``beta = +-90`` (gimbal lock) only ``alpha -+ gamma`` is determined (the paper's Eq. 4): ``gamma = 0`` is
    chosen, for the same reason.

    >>> angles = angles_from_matrix(rotation_matrix(30, -20, 75))
    >>> [round(a, 6) for a in angles]
    [30.0, -20.0, 75.0]
    >>> [round(a, 6) for a in angles_from_matrix(rotation_matrix(10, 90, 25))]
    [-15.0, 90.0, 0.0]
    >>> [round(a, 6) for a in angles_from_matrix(rotation_matrix(90, 150, 0))]
    [90.0, 150.0, 0.0]
    """
    t = np.asarray(matrix, dtype=float)
    if t.shape != (3, 3) or not np.allclose(t @ t.T, np.eye(3), atol=1e-6) or np.linalg.det(t) < 0:
        raise InputError("not a rotation matrix", parameter="matrix")
    sin_beta = -t[2, 0]
    if abs(sin_beta) < 1 - 1e-12:
        beta = math.asin(max(-1.0, min(1.0, sin_beta)))
        alpha = math.atan2(t[2, 1], t[2, 2])  # sin a cos b, cos a cos b with cos b > 0
        gamma = math.atan2(t[1, 0], t[0, 0])  # cos b sin g, cos b cos g
        if abs(abs(gamma) - math.pi) < 1e-9:  # the other solution has gamma = 0
            alpha, beta, gamma = alpha + math.pi, math.pi - beta, 0.0
    else:
        beta = math.copysign(math.pi / 2, sin_beta)
        gamma = 0.0
        # beta = +90: t12 = sin(a - g), t13 = cos(a - g); beta = -90: t12 = -sin(a + g), t13 = -cos(a + g)
        alpha = math.atan2(t[0, 1], t[0, 2]) if sin_beta > 0 else math.atan2(-t[0, 1], -t[0, 2])
    return tuple(float(_wrap(math.degrees(v))) for v in (alpha, beta, gamma))


def _wrap(degrees):
    """Angle in (-180, 180]."""
    wrapped = (degrees + 180.0) % 360.0 - 180.0
    return 180.0 if wrapped == -180.0 else wrapped


def vpn_from_angles(alpha, beta, gamma=0.0):
    """The view plane normal: the unit vector in object space (x, y, z) that points at the viewer.

    >>> np.round(vpn_from_angles(0, 0), 6).tolist()
    [-0.0, -0.0, -1.0]
    """
    return -rotation_matrix(alpha, beta, gamma)[2]


def angles_from_vpn(vpn):
    """Angles ``(alpha, beta, 0)`` in degrees that put the viewer on the side ``vpn`` points to.

    ``vpn`` is the octree papers' view plane normal, in object coordinates (x, y, z),
    pointing from the object toward the viewer.

    >>> [round(a, 3) for a in angles_from_vpn((0, 0, -1))]
    [0.0, 0.0, 0.0]
    >>> v = np.array([1.0, 1.0, 1.0]) / 3 ** 0.5
    >>> bool(np.allclose(vpn_from_angles(*angles_from_vpn(v)), v))
    True
    """
    v = np.asarray(vpn, dtype=float)
    norm = np.linalg.norm(v) if v.shape == (3,) else 0
    if not norm or not np.isfinite(norm):
        raise InputError(f"{tuple(vpn)} is not a non-zero direction i, j, k", parameter="vpn")
    i, j, k = v / norm
    # The view direction d = -vpn is R's last row: (-sin b, sin a cos b, cos a cos b).
    beta = math.asin(max(-1.0, min(1.0, i)))
    alpha = math.atan2(-j, -k) if math.hypot(j, k) > 1e-12 else 0.0
    return (_wrap(math.degrees(alpha)) + 0.0, math.degrees(beta) + 0.0, 0.0)


def fit_scale(shape, size, box=None):
    """Pixels per voxel that fit a ``shape = (nz, ny, nx)`` volume in ``size = (H, W)`` at any rotation.

    With ``box = ((z0, z1), (y0, y1), (x0, x1))`` (inclusive voxel indices, e.g. the object's bounding
    box) the scale fits that box instead, still turning about the volume centre (the contract's ``c``).

    >>> round(fit_scale((10, 10, 10), (100, 200)), 4)
    5.7735
    >>> round(fit_scale((10, 10, 10), (100, 100), ((0, 9), (0, 9), (0, 9))), 4)
    5.7735
    """
    if box is None:
        return min(size) / math.sqrt(sum(n * n for n in shape))
    centre = [(n - 1) / 2 for n in shape]
    reach = [max(abs(lo - 0.5 - c), abs(hi + 0.5 - c)) for (lo, hi), c in zip(box, centre, strict=True)]
    return min(size) / (2 * math.sqrt(sum(r * r for r in reach)))


@dataclass(frozen=True)
class View:
    """A view of the contract: angles in degrees, ``size = (H, W)`` pixels, ``scale`` pixels per voxel.

    Image space is ``p' = Rz(gamma) Ry(beta) Rx(alpha) (p - c)``, ``c`` the volume centre; the viewer looks along
    ``+Z'``, with ``X'`` to the right and ``Y'`` down.

    Parameters
    ----------
    alpha, beta, gamma : float
        The rotation angles in degrees (the dynamic-screen paper's Eq. 2); :data:`PRESETS` names the patient
        views.
    size : (H, W)
        Picture size in pixels.
    scale : float, optional
        Pixels per voxel; ``None``: fitted when rendered (see :meth:`fitted`).
    centre : (X', Y')
        The image-space point at the middle of the picture: the contract's ``(0, 0)`` (the volume centre) unless
        the default framing centres the object as this view sees it.

    Examples
    --------
    >>> v = View(alpha=30, size=(64, 48)).fitted((8, 8, 8))
    >>> round(v.scale, 3)
    3.464
    >>> v.matrix.shape
    (3, 3)
    """

    alpha: float = 0.0
    beta: float = 0.0
    gamma: float = 0.0
    size: tuple[int, int] = (512, 512)
    scale: float | None = None
    centre: tuple = (0.0, 0.0)

    def __post_init__(self):
        height, width = self.size
        if int(height) < 1 or int(width) < 1:
            raise InputError(f"{width}x{height} must be at least 1x1 pixels", parameter="size")
        if self.scale is not None and not (self.scale > 0 and math.isfinite(self.scale)):
            raise InputError(f"{self.scale} must be a positive number of pixels per voxel", parameter="scale")
        for name in ("alpha", "beta", "gamma"):
            if not math.isfinite(getattr(self, name)):
                raise InputError(f"{getattr(self, name)} must be a finite angle in degrees", parameter=name)

    @cached_property
    def matrix(self):
        """``R = Rz(gamma) Ry(beta) Rx(alpha)``, computed once per view (renderers ask for it per slice)."""
        return rotation_matrix(self.alpha, self.beta, self.gamma)

    # The contract's mappings.  Every renderer, the clipper, the pre-image turn and the ray caster use these,
    # so that the contract is written once.

    def to_image(self, x, y, z, shape):
        """Image-space ``(X', Y', Z')`` of object points ``(x, y, z)`` of a ``shape = (nz, ny, nx)`` volume.

        ``p' = R (p - c)``, written out per component, so that one point or many give the same bits.

        >>> [float(v) for v in View(alpha=90).to_image(2.0, 0.0, 0.0, (3, 3, 3))]
        [1.0, 1.0, -1.0]
        """
        nz, ny, nx = shape
        px, py, pz = np.asarray(x) - (nx - 1) / 2, np.asarray(y) - (ny - 1) / 2, np.asarray(z) - (nz - 1) / 2
        r = self.matrix
        return tuple(r[k, 0] * px + r[k, 1] * py + r[k, 2] * pz for k in range(3))

    def to_object(self, x, y, z, shape):
        """Object ``(x, y, z)`` of image-space points ``(X', Y', Z')``: the inverse of :meth:`to_image`.

        >>> [float(v) for v in View(alpha=90).to_object(1.0, 1.0, -1.0, (3, 3, 3))]
        [2.0, 0.0, 0.0]
        """
        centre = (np.array(shape[::-1], dtype=float) - 1) / 2
        r = self.matrix
        return tuple(centre[k] + np.asarray(x) * r[0, k] + np.asarray(y) * r[1, k] + np.asarray(z) * r[2, k]
                     for k in range(3))

    def pixel_centres(self, columns=None, rows=None):
        """Image-space ``X'`` of pixel ``columns`` and ``Y'`` of pixel ``rows`` (default: all of them).

        Indices outside the picture are allowed (renderers test windows that overhang it).

        >>> View(size=(2, 4), scale=1.0).pixel_centres()
        (array([-1.5, -0.5,  0.5,  1.5]), array([-0.5,  0.5]))
        """
        height, width = self.size
        columns = np.arange(width) if columns is None else columns
        rows = np.arange(height) if rows is None else rows
        return ((columns + 0.5 - width / 2) / self.scale + self.centre[0],
                (rows + 0.5 - height / 2) / self.scale + self.centre[1])

    def hit_points(self, depth, shape, beyond=0.0):
        """Where each covered pixel's ray meets the object: ``(rows, columns, points)``, ``points`` ``(N, 3)``
        object ``(x, y, z)`` at depth ``depth + beyond`` (float64), for a depth image of this view.

        >>> view = View(size=(1, 2), scale=1.0)
        >>> rows, columns, points = view.hit_points(np.array([[np.inf, -0.5]], np.float32), (1, 1, 1))
        >>> columns.tolist(), points.tolist()
        ([1], [[0.5, 0.0, -0.5]])
        """
        rows, columns = np.nonzero(np.isfinite(depth))
        xs, ys = self.pixel_centres(columns, rows)
        zs = depth[rows, columns].astype(np.float64) + beyond
        return rows, columns, np.stack(self.to_object(xs, ys, zs, shape), axis=-1).reshape(-1, 3)

    def pixel_index(self, x, y):
        """Continuous ``(column, row)`` of image points ``(X', Y')``: whole numbers at pixel centres.

        >>> [float(v) for v in View(size=(2, 4), scale=1.0).pixel_index(-1.5, 0.5)]
        [0.0, 1.0]
        """
        height, width = self.size
        return ((np.asarray(x) - self.centre[0]) * self.scale + width / 2 - 0.5,
                (np.asarray(y) - self.centre[1]) * self.scale + height / 2 - 0.5)

    def fitted(self, shape, box=None, fit="object", margin=0.05):
        """The view with ``scale`` set, when it is ``None``.

        ``fit="object"`` (with ``box``, the object's bounding box ``((z0, z1), (y0, y1), (x0, x1))``, inclusive
        voxel indices): the scale and centre that frame the box as this view sees it, with a ``margin`` on
        every side; ``fit="volume"``: the whole volume at any rotation, centred on the volume centre.

        >>> v = View(size=(100, 100)).fitted((10, 10, 10), ((0, 9), (0, 9), (0, 4)))
        >>> round(v.scale, 3), [round(c, 3) for c in v.centre]
        (9.091, [-2.5, 0.0])
        """
        if self.scale is not None:
            return self
        if fit == "volume" or box is None:
            return replace(self, scale=fit_scale(shape, self.size), centre=(0.0, 0.0))._on_a_pixel(shape, box)
        (x0, x1), (y0, y1) = self.extent(shape, box)
        height, width = self.size
        scale = min(width / ((x1 - x0) * (1 + 2 * margin)), height / ((y1 - y0) * (1 + 2 * margin)))
        return replace(self, scale=float(scale), centre=((x0 + x1) / 2, (y0 + y1) / 2))._on_a_pixel(shape, box)

    def _on_a_pixel(self, shape, box):
        """The view moved by less than a pixel, where the box is thinner than a pixel as it sees it (a slab one voxel
        thick, edge-on), so that the box's middle falls on a pixel centre and a ray meets the slab: between two
        pixel centres it would leave the picture blank.  Boxes a pixel wide or more are left where they are.

        >>> view = View(size=(100, 100), scale=0.5)._on_a_pixel((64, 64, 1), ((0, 63), (0, 63), (0, 0)))
        >>> view.centre                         # one voxel across X', half a pixel: moved by half a pixel
        (-1.0, 0.0)
        """
        if box is None:
            return self
        middle = []
        for (low, high), pixels, centre in zip(self.extent(shape, box), self.size[::-1], self.centre, strict=True):
            if (high - low) * self.scale >= 1:
                middle.append(centre)
            else:           # the pixel centre nearest the picture's middle, at the box's middle
                middle.append((low + high) / 2 - (pixels // 2 + 0.5 - pixels / 2) / self.scale)
        return replace(self, centre=tuple(middle))

    def extent(self, shape, box):
        """``((X'min, X'max), (Y'min, Y'max))``: the image-space extent of a bounding box's cubes in this view."""
        (z0, z1), (y0, y1), (x0, x1) = box
        corners = np.array(list(itertools.product((x0 - 0.5, x1 + 0.5), (y0 - 0.5, y1 + 0.5), (z0 - 0.5, z1 + 0.5))))
        xs, ys, _ = self.to_image(*corners.T, shape)
        return (float(xs.min()), float(xs.max())), (float(ys.min()), float(ys.max()))

    @classmethod
    def preset(cls, name, **kwargs):
        """A named view (see ``PRESETS``)."""
        if name not in PRESETS:
            raise InputError(f"unknown view {name!r}; choose one of {', '.join(PRESETS)}", parameter="view")
        alpha, beta, gamma = PRESETS[name]
        return cls(alpha=alpha, beta=beta, gamma=gamma, **kwargs)




def frame_together(views, shape, box):
    """``views`` framing the object in ``box`` with one scale, the largest at which every view holds it, each
    centred on the object as it sees it; so the size does not jump between the views of a sheet or turntable.

    >>> views = [View(0, 0, size=(100, 100)), View(0, 90, size=(100, 100))]
    >>> [round(v.scale, 3) for v in frame_together(views, (10, 10, 10), ((0, 9), (0, 9), (0, 4)))]
    [9.091, 9.091]
    """
    fitted = [v.fitted(shape, box) for v in views]
    scale = min(v.scale for v in fitted)
    return [replace(v, scale=scale)._on_a_pixel(shape, box) for v in fitted]
