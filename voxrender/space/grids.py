"""Grids in patient space: how two voxel grids relate, and a label map brought onto an image's grid.

A grid is a shape ``[z, y, x]`` and its voxel-to-patient affine: the 4 x 4 matrix from a voxel index
``(x, y, z, 1)`` to its patient position (LPS, mm), as :func:`patient_affine` gives it.  A voxel is the
cube centred on its index, so a grid's *extent* runs from index -0.5 to n - 0.5 along each axis.

Arrays in, arrays out: :func:`resample_nearest` moves values from one grid to another by nearest neighbour, in any
orientation; :func:`relate` tells how two grids differ (:class:`GridRelation`); :func:`pair` puts a label map on an
image's grid, refusing one that does not overlap the image and warning of one whose extent differs.

References
----------
.. [1] DICOM PS3.3, C.7.6.2.1.1 "Image Position and Image Orientation": the voxel-to-patient mapping.
.. [2] Van Griethuysen et al., "Computational Radiomics System to Decode the Radiographic Phenotype", Cancer
   Research 77 (2017): pyradiomics checks that an image and its mask share their geometry, the check this module
   makes by patient position instead.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from . import orient

SAME_MM = 1e-4              # affines this close (every entry, mm) are the same grid
_REVERSED = [2, 1, 0]       # (x, y, z) <-> NumPy's axes [z, y, x]
_SAMPLES = 96               # voxel centres per axis that the overlap of oblique grids is sampled at


def resample_nearest(values, source_affine, target_shape, target_affine, fill=0):
    """``values`` on the source grid, resampled by nearest neighbour onto the target grid.

    Parameters
    ----------
    values : ndarray, ``[z, y, x]``
        The values on the source grid (labels, a mask).
    source_affine, target_affine : (4, 4) array_like
        Voxel index ``(x, y, z, 1)`` to patient position (mm) of each grid; any orientation (flips,
        permutations, oblique axes), spacing and origin.
    target_shape : 3 ints
        The target grid's shape ``[z, y, x]``.
    fill : scalar
        The value of target voxels whose centre falls outside the source grid.

    Returns
    -------
    ndarray, ``target_shape``
        Of ``values``' dtype: each target voxel takes the source voxel its centre lies in.  When the two grids are
        the same (shapes equal, affines within 1e-4 mm), ``values`` itself, not a copy.

    Examples
    --------
    A grid of 2 mm voxels onto one of 1 mm voxels over the same extent: each value covers two voxels a side.

    >>> coarse = np.arange(8, dtype=np.uint8).reshape(2, 2, 2)
    >>> source = np.diag([2.0, 2.0, 2.0, 1.0]); source[:3, 3] = 0.5
    >>> fine = resample_nearest(coarse, source, (4, 4, 4), np.eye(4))
    >>> fine[:, 0, 0].tolist(), fine.dtype.name
    ([0, 0, 4, 4], 'uint8')
    >>> resample_nearest(coarse, source, (2, 2, 2), source) is coarse
    True
    """
    from scipy import ndimage

    source_affine = np.asarray(source_affine, dtype=float)
    target_affine = np.asarray(target_affine, dtype=float)
    target_shape = tuple(int(n) for n in target_shape)
    if values.shape == target_shape and _same_affine(source_affine, target_affine):
        return values
    # target index -> patient -> source index, as (x, y, z); then in NumPy's axis order [z, y, x]
    to_source = np.linalg.solve(source_affine, target_affine)
    matrix = to_source[:3, :3][np.ix_(_REVERSED, _REVERSED)]
    offset = to_source[:3, 3][_REVERSED]
    if np.count_nonzero(np.abs(matrix) > 1e-12) == np.count_nonzero(np.abs(np.diag(matrix)) > 1e-12) == 3:
        matrix = np.diag(matrix)         # axes in step: scipy takes its faster zoom-and-shift path
    data = values.view(np.uint8) if values.dtype == np.bool_ else values      # ndimage takes no bools
    # "grid-constant": a source voxel fills its whole cube; "constant" would fill from its centre, losing the
    # outer half voxel of the grid (target centres 0.25 voxel outside the first centre would take the fill)
    moved = ndimage.affine_transform(data, matrix, offset, output_shape=target_shape, output=data.dtype, order=0,
                                     mode="grid-constant", cval=fill, prefilter=False)
    return moved.view(np.bool_) if values.dtype == np.bool_ else moved


@dataclass(frozen=True)
class GridRelation:
    """How a source grid (a label map's) lies on a target grid (its image's), from :func:`relate`.

    Attributes
    ----------
    same : bool
        The two grids are the same: shapes equal, affines within 1e-4 mm.
    overlap : float
        The fraction of the source's voxels whose centres fall inside the target's extent (0 to 1; exact for
        grids whose axes are parallel, to about a percent for oblique ones).
    extent_gap_mm : float
        The largest distance between corresponding corners of the two grids' bounding boxes in patient space.
    source_voxel_mm, target_voxel_mm : tuple of 3 floats
        Each grid's voxel size along its axes x, y, z.
    source_shape, target_shape : tuple of 3 ints
        Each grid's shape ``[z, y, x]``.
    source_affine, target_affine : tuple of tuples
        Each grid's 4 x 4 voxel-to-patient affine.
    """

    same: bool
    overlap: float
    extent_gap_mm: float
    source_voxel_mm: tuple
    target_voxel_mm: tuple
    source_shape: tuple
    target_shape: tuple
    source_affine: tuple
    target_affine: tuple

    @property
    def source_extent(self):
        """The source grid's bounding box in patient space: ``(low, high)``, each (x, y, z) in mm."""
        return extent(self.source_shape, self.source_affine)

    @property
    def target_extent(self):
        """The target grid's bounding box in patient space: ``(low, high)``, each (x, y, z) in mm."""
        return extent(self.target_shape, self.target_affine)

    def lines(self, source_name="label map", target_name="image", source_stored=None, target_stored=None):
        """Human lines for ``info``: each grid, and how the source lies on the target.

        ``source_stored`` and ``target_stored`` are the orientation codes the files were stored in (a volume's
        ``meta["orientation"]``), when known.

        Examples
        --------
        >>> label = np.diag([2.0, 2.0, 2.0, 1.0]); label[:3, 3] = [4.5, 0.5, 0.5]
        >>> for line in relate((4, 4, 4), label, (8, 8, 8), np.eye(4)).lines(source_stored="RAS"):
        ...     print(line)
        label map grid: 4 x 4 x 4 at 2 x 2 x 2 mm, origin (4.5, 0.5, 0.5) mm, RAS stored
        image grid: 8 x 8 x 8 at 1 x 1 x 1 mm, origin (0.0, 0.0, 0.0) mm, LPS axes
        relation: shifted by (4.0, 0.0, 0.0) mm, 2x coarser; extents differ by 4.0 mm; 50 % of it inside the image
        """
        lines = [_grid_line(f"{source_name} grid", self.source_shape, self.source_affine, source_stored),
                 _grid_line(f"{target_name} grid", self.target_shape, self.target_affine, target_stored)]
        if self.same:
            return [*lines, "relation: same grid"]
        (source_low, source_high), (target_low, target_high) = self.source_extent, self.target_extent
        shift = (source_low + source_high) / 2 - (target_low + target_high) / 2
        how = []
        if np.abs(shift).max() > 1e-3:
            how.append("shifted by ({:.1f}, {:.1f}, {:.1f}) mm".format(*shift))
        how += _scale_words(self, target_name) + _axes_words(self, target_name)
        parts = [", ".join(how) or "the same voxels"]
        if self.extent_gap_mm > 1e-3:
            parts.append(f"extents differ by {_mm(self.extent_gap_mm)} mm")
        parts.append(f"{_percent(self.overlap)} % of it inside the {target_name}")
        return [*lines, "relation: " + "; ".join(parts)]


def relate(source_shape, source_affine, target_shape, target_affine):
    """How the source grid lies on the target grid: the same grid, or shifted, scaled, turned; by how much their
    extents differ, and how much of the source lies inside the target.

    Parameters
    ----------
    source_shape, target_shape : 3 ints
        The grids' shapes ``[z, y, x]``.
    source_affine, target_affine : (4, 4) array_like
        Their voxel index ``(x, y, z, 1)`` to patient position (mm) matrices.

    Returns
    -------
    GridRelation

    Examples
    --------
    >>> shifted = np.eye(4); shifted[0, 3] = 5.0                  # 5 mm along x: half of it outside
    >>> relation = relate((10, 10, 10), shifted, (10, 10, 10), np.eye(4))
    >>> relation.same, relation.overlap, relation.extent_gap_mm
    (False, 0.5, 5.0)
    >>> relate((10, 10, 10), np.eye(4), (10, 10, 10), np.eye(4)).same
    True
    """
    source_affine = np.asarray(source_affine, dtype=float)
    target_affine = np.asarray(target_affine, dtype=float)
    source_shape = tuple(int(n) for n in source_shape)
    target_shape = tuple(int(n) for n in target_shape)
    same = source_shape == target_shape and _same_affine(source_affine, target_affine)
    if same:
        overlap, gap = 1.0, 0.0
    else:
        overlap = _inside_fraction(source_shape, source_affine, target_shape, target_affine)
        (source_low, source_high) = extent(source_shape, source_affine)
        (target_low, target_high) = extent(target_shape, target_affine)
        # corresponding corners take, along each axis, both lows or both highs: the farthest pair of them
        per_axis = np.maximum(np.abs(source_low - target_low), np.abs(source_high - target_high))
        gap = float(np.linalg.norm(per_axis))
    return GridRelation(same, float(overlap), gap, _voxel_mm(source_affine), _voxel_mm(target_affine),
                        source_shape, target_shape, _frozen(source_affine), _frozen(target_affine))


def pair(label_volume, image_volume, label_name="the label map", *, image_name="the image",
         parameter="labels_from", partial=False):
    """The values of ``label_volume`` on the grid of ``image_volume``, placed by patient position.

    Both grids come from :func:`patient_affine`.  A label map that does not overlap the image at all
    is bad input; one whose extent differs from the image's by more than an image voxel is placed with a warning
    (``warnings.warn``) that gives the distance in mm.  Labels are moved by nearest neighbour
    (:func:`resample_nearest`), never blended.

    Parameters
    ----------
    label_volume, image_volume : Volume
        The label map (any shape, spacing, origin or orientation) and the image it belongs to.
    label_name, image_name : str
        What to call them in messages (a file's name).
    parameter : str, optional
        The keyword at fault in the error when they do not overlap.
    partial : bool
        The label map covers only part of its image by design (a DICOM SEG stores only the frames that hold a
        segment): no warning for a smaller extent, only for one that reaches outside the image.

    Returns
    -------
    ndarray, ``image_volume.shape``
        The labels on the image's grid, of the label map's dtype; 0 where the image reaches beyond the label map.
        The label map's own array when the grids are the same.

    Raises
    ------
    InputError
        When no voxel of the label map lies inside the image.

    Examples
    --------
    >>> from voxrender.io import Volume
    >>> image = Volume(np.zeros((4, 4, 4), np.int16), (1.0, 1.0, 1.0), {"origin": [0.0, 0.0, 0.0]})
    >>> labels = Volume(np.ones((2, 2, 2), np.uint8), (2.0, 2.0, 2.0), {"origin": [0.5, 0.5, 0.5]})
    >>> int(pair(labels, image).sum())
    64
    """
    source_affine, target_affine = patient_affine(label_volume), patient_affine(image_volume)
    relation = relate(label_volume.shape, source_affine, image_volume.shape, target_affine)
    if relation.same:
        return label_volume.values
    if relation.overlap == 0:
        raise InputError(f"{label_name} does not overlap {image_name}: it spans {_span(*relation.source_extent)} "
                         f"and {image_name} {_span(*relation.target_extent)} (patient LPS); give the label map made "
                         "from this image", parameter=parameter)
    voxel = max(relation.target_voxel_mm)
    if relation.extent_gap_mm > voxel and (not partial or relation.overlap < 0.999):
        warnings.warn(f"{label_name} and {image_name} differ in extent by {_mm(relation.extent_gap_mm)} mm, more than "
                      f"one voxel ({voxel:.3g} mm); it is placed by patient position, {_percent(relation.overlap)} % "
                      f"of it inside {image_name}", stacklevel=2)
    return resample_nearest(label_volume.values, source_affine, image_volume.shape, target_affine)


def outside(label_volume, image_volume):
    """The values of ``label_volume``'s nonzero voxels whose centres lie outside ``image_volume``'s extent, as one
    1-D array (a slice of the label map at a time): what placing it on the image's grid loses.

    >>> from voxrender.io import Volume
    >>> image = Volume(np.zeros((2, 4, 4), np.int16), (1.0, 1.0, 1.0), {"origin": [0.0, 0.0, 0.0]})
    >>> labels = Volume(np.full((4, 1, 1), 7, np.uint8), (1.0, 1.0, 1.0), {"origin": [1.0, 1.0, 0.0]})
    >>> outside(labels, image).tolist()                  # the label map's slices z 2 and 3 lie beyond the image
    [7, 7]
    """
    to_target = np.linalg.solve(patient_affine(image_volume), patient_affine(label_volume))
    sizes = np.asarray(image_volume.shape[::-1], dtype=float)      # x, y, z
    found = []
    for z in range(label_volume.shape[0]):
        plane = np.asarray(label_volume.values[z])
        rows, columns = np.nonzero(plane)
        if not len(rows):
            continue
        points = np.stack([columns, rows, np.full(len(rows), z)]).astype(float)
        index = to_target[:3, :3] @ points + to_target[:3, 3:]
        inside = _within(index[0], sizes[0]) & _within(index[1], sizes[1]) & _within(index[2], sizes[2])
        found.append(plane[rows[~inside], columns[~inside]])
    return np.concatenate(found) if found else np.zeros(0, np.asarray(label_volume.values[:0]).dtype)


def extent(shape, affine):
    """The bounding box in patient space of a grid's voxel cubes: ``(low, high)``, each (x, y, z) in mm.

    >>> [p.tolist() for p in extent((2, 3, 4), np.eye(4))]
    [[-0.5, -0.5, -0.5], [3.5, 2.5, 1.5]]
    """
    sizes = np.asarray(shape, dtype=float)[::-1]                   # x, y, z
    corners = np.array(np.meshgrid(*[(-0.5, n - 0.5) for n in sizes], indexing="ij")).reshape(3, -1)
    points = np.asarray(affine, dtype=float)[:3, :3] @ corners + np.asarray(affine, dtype=float)[:3, 3:]
    return points.min(axis=1), points.max(axis=1)


def _inside_fraction(source_shape, source_affine, target_shape, target_affine):
    """The fraction of the source's voxel centres inside the target's extent: exact when each source axis runs
    along a target axis, else from a lattice of up to 96 centres a side.
    """
    to_target = np.linalg.solve(target_affine, source_affine)      # source index -> target index, (x, y, z)
    matrix, offset = to_target[:3, :3], to_target[:3, 3]
    source_sizes, target_sizes = source_shape[::-1], np.asarray(target_shape[::-1], dtype=float)
    along = np.abs(matrix) > 1e-9
    if np.all(along.sum(axis=0) == 1) and np.all(along.sum(axis=1) == 1):
        fraction = 1.0                   # each target axis depends on one source axis: a product of fractions
        for j, k in zip(*np.nonzero(along), strict=True):
            position = matrix[j, k] * np.arange(source_sizes[k]) + offset[j]
            fraction *= np.mean(_within(position, target_sizes[j]))
        return float(fraction)
    # centres of equal bins along each source axis; the target coordinates as a sum of broadcast terms
    samples = [(np.arange(m) + 0.5) * n / m - 0.5 for n in source_sizes for m in [min(n, _SAMPLES)]]
    shapes = [(1, 1, -1), (1, -1, 1), (-1, 1, 1)]                 # x, y, z on NumPy's axes
    inside = True
    for j in range(3):
        position = offset[j] + sum(matrix[j, k] * samples[k].reshape(shapes[k]) for k in range(3))
        inside = inside & _within(position, target_sizes[j])
    return float(np.mean(inside))


def _within(position, size):
    """Whether index positions lie in a grid axis's extent, -0.5 to ``size`` - 0.5 (a centre on the edge counts)."""
    return (position >= -0.5 - 1e-6) & (position <= size - 0.5 + 1e-6)


def _same_affine(a, b):
    return bool(np.all(np.abs(np.asarray(a)[:3] - np.asarray(b)[:3]) <= SAME_MM))


def _voxel_mm(affine):
    return tuple(float(v) for v in np.linalg.norm(np.asarray(affine)[:3, :3], axis=0))


def _frozen(affine):
    return tuple(tuple(float(v) for v in row) for row in np.asarray(affine))


def _direction(affine):
    matrix = np.asarray(affine, dtype=float)[:3, :3]
    return matrix / np.linalg.norm(matrix, axis=0)


def _mm(distance):
    """A distance for a message: to a tenth of a mm, or in powers of ten for a damaged header's absurd ones."""
    return f"{distance:.1f}" if distance < 1e6 else f"{distance:.3g}"


def _percent(fraction):
    """A fraction as a whole percentage that says 'all' and 'none' only when they are so."""
    value = round(fraction * 100)
    return 99 if value == 100 and fraction < 1 else 1 if value == 0 and fraction > 0 else value


def _span(low, high):
    return ", ".join(f"{axis} {lo:.1f} to {hi:.1f}" for axis, lo, hi in zip("xyz", low, high, strict=True)) + " mm"


def _grid_line(title, shape, affine, stored):
    voxel = " x ".join(f"{v:.4g}" for v in _voxel_mm(affine))
    origin = ", ".join(f"{v:.1f}" for v in np.asarray(affine)[:3, 3])
    direction = _direction(affine)
    axes = f"{stored} stored" if stored else f"{orient.code_of(direction)} axes"
    tilt = orient.nearest_axes(direction)[2]
    if tilt > orient.OBLIQUE_DEGREES:
        axes += f", oblique by {tilt:.1f} degrees"
    return f"{title}: {' x '.join(str(n) for n in shape[::-1])} at {voxel} mm, origin ({origin}) mm, {axes}"


def _along_patient_axes(affine):
    """A grid's voxel size along each patient axis (x, y, z): that of the voxel axis nearest it."""
    axis, _, _ = orient.nearest_axes(_direction(affine))
    voxel = _voxel_mm(affine)
    return np.array([voxel[axis.index(j)] for j in range(3)])


def _scale_words(relation, target_name):
    ratio = _along_patient_axes(relation.source_affine) / _along_patient_axes(relation.target_affine)
    if np.allclose(ratio, 1, rtol=0.01):
        return []
    if np.allclose(ratio, ratio[0], rtol=0.01):
        factor = ratio[0] if ratio[0] > 1 else 1 / ratio[0]
        return [f"{factor:.3g}x {'coarser' if ratio[0] > 1 else 'finer'}"]
    return ["voxels {:.3g} x {:.3g} x {:.3g} times the {}'s".format(*ratio, target_name)]


def _axes_words(relation, target_name):
    """The turn from the target's axes to the source's: a permutation, flips and an oblique tilt, in words."""
    turn = np.linalg.solve(_direction(relation.target_affine), _direction(relation.source_affine))
    axis, sign, tilt = orient.nearest_axes(turn)
    words = []
    if axis != [0, 1, 2]:
        words.append(f"its x, y, z along the {target_name}'s " + ", ".join("xyz"[a] for a in axis))
    flipped = [letter for letter, s in zip("xyz", sign, strict=True) if s < 0]
    if flipped:
        words.append("flipped " + ", ".join(flipped))
    if tilt > orient.OBLIQUE_DEGREES:
        words.append(f"turned {tilt:.1f} degrees")
    return words


def patient_affine(volume):
    """The 4 x 4 matrix from a voxel index ``(x, y, z, 1)`` of ``volume.values`` (as it is now: reoriented, when
    :func:`voxrender.io.read_volume` did) to its patient position (LPS, mm): from its direction, spacing and
    origin, each the identity, 1 mm or zero where the input does not say.  Pairs a label map with its image.

    >>> from voxrender.io import Volume
    >>> volume = Volume(np.zeros((2, 3, 4)), (0.5, 0.5, 2.0), {"origin": [10.0, 0.0, 0.0]})
    >>> patient_affine(volume)[:3].tolist()
    [[0.5, 0.0, 0.0, 10.0], [0.0, 0.5, 0.0, 0.0], [0.0, 0.0, 2.0, 0.0]]
    """
    return voxel_affine(np.eye(3) if volume.direction is None else volume.direction, volume.spacing,
                   volume.meta.get("origin"))


def voxel_affine(direction, spacing, origin=None):
    """The 4 x 4 voxel (x, y, z) -> patient (LPS, mm) matrix of the stored volume (origin 0 when unknown)."""
    affine = np.eye(4)
    affine[:3, :3] = np.asarray(direction, dtype=float) * np.asarray(spacing, dtype=float)[None, :]
    affine[:3, 3] = origin if origin is not None else 0.0
    return np.round(affine, 6)

