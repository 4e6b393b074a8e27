"""How far apart two segmentations' surfaces are: surface elements weighted by their area, as DeepMind's
``surface-distance`` defines them, and the metrics of Metrics Reloaded built on them.

A mask's surface is taken at the corners of its voxels: each corner's 2 x 2 x 2 neighbourhood of voxels (one of 256
patterns) holds a piece of the marching-cubes surface between the voxels inside and outside, whose area in mm² the
pattern and the spacing give (:func:`surfel_areas`).  The distance of a surface element to the other surface is the
Euclidean distance transform, on the true spacing, from the other mask's surface corners.  So

- the average symmetric surface distance (ASSD) is the area-weighted mean over both surfaces;
- the robust Hausdorff distance (HD95) is the larger of the two directed 95th percentiles, by area;
- the normalised surface Dice (NSD) at a tolerance is the share of both surfaces' area within it of the other.

Voxel-border definitions (MedPy's, which count a voxel's faces) give an average distance up to a third larger on thin
structures; these are the definitions the tests hold to ``surface-distance`` itself.  The work is done in the masks'
bounding box, and the distances are looked up in a k-d tree of the surface corners rather than by a distance
transform of the whole box: its cost follows the surfaces, not the volume.

References
----------
S. Nikolov et al., "Clinically applicable segmentation of head and neck anatomy for radiotherapy: deep learning
algorithm development and validation study", J. Med. Internet Res. 23(7), 2021 (normalised surface Dice);
https://github.com/google-deepmind/surface-distance.
L. Maier-Hein et al., "Metrics reloaded: recommendations for image analysis validation", Nat. Methods 21, 2024.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

# The code of a voxel corner: the bit of each voxel of its 2 x 2 x 2 neighbourhood that is inside, by its offset
# (-1 or 0 along z, y, x): the first voxel (-1, -1, -1) is bit 128, the last (0, 0, 0) bit 1.
_CORNER_BITS = np.array([[[128, 64], [32, 16]], [[8, 4], [2, 1]]], np.uint8)


@functools.lru_cache(maxsize=64)
def surfel_areas(spacing):
    """The area in mm² of the surface each of the 256 corner codes holds, on voxels of ``spacing`` (along the
    arrays' axes, z, y, x): classic marching cubes (Lorensen's table) of the code or of its complement, whichever
    has fewer voxels inside, so that a surface's area is the same seen from either side.

    >>> areas = surfel_areas((1.0, 1.0, 1.0))
    >>> float(areas[0]), float(areas[255]), round(float(areas[1]), 4)      # one voxel inside: a corner triangle
    (0.0, 0.0, 0.2165)
    """
    from skimage.measure import marching_cubes, mesh_surface_area

    areas = np.zeros(256)
    for code in range(1, 255):                                 # 254 patterns of 8 voxels, once per spacing
        fewer = code if bin(code).count("1") <= 4 else 255 - code
        cube = ((fewer & _CORNER_BITS) > 0).astype(np.float32)
        vertices, faces, _, _ = marching_cubes(cube, 0.5, spacing=tuple(spacing), method="lorensen")
        areas[code] = mesh_surface_area(vertices, faces)
    return areas


@dataclass(frozen=True)
class SurfaceDistances:
    """The surface elements of two masks: each one's distance (mm) to the other surface and its area (mm²), of the
    test mask and of the reference, unsorted.  A mask without surface has none; the other's are then ``inf``.
    """

    test_distances: np.ndarray
    test_areas: np.ndarray
    reference_distances: np.ndarray
    reference_areas: np.ndarray

    def assd(self):
        """The average symmetric surface distance: the area-weighted mean over both surfaces (``nan`` when either
        has none).
        """
        area = self.test_areas.sum() + self.reference_areas.sum()
        if not len(self.test_areas) or not len(self.reference_areas) or not area:
            return float("nan")
        return float((self.test_distances @ self.test_areas + self.reference_distances @ self.reference_areas)
                     / area)

    def hausdorff(self, percent=95.0):
        """The robust Hausdorff distance: the larger of the two directed ``percent`` percentiles, by area, as
        ``surface-distance`` takes them (``nan`` when either has no surface).
        """
        if not len(self.test_areas) or not len(self.reference_areas):
            return float("nan")
        return max(_percentile(self.test_distances, self.test_areas, percent),
                   _percentile(self.reference_distances, self.reference_areas, percent))

    def surface_dice(self, tolerance_mm):
        """The normalised surface Dice: the share of both surfaces' area within ``tolerance_mm`` of the other."""
        area = self.test_areas.sum() + self.reference_areas.sum()
        if not area:
            return float("nan")
        within = (self.test_areas[self.test_distances <= tolerance_mm].sum()
                  + self.reference_areas[self.reference_distances <= tolerance_mm].sum())
        return float(within / area)


def _percentile(distances, areas, percent):
    """The distance below which ``percent`` % of the surface's area lies: the first, in order of distance, whose
    running share of the area reaches it.
    """
    order = np.argsort(distances, kind="stable")
    share = np.cumsum(areas[order]) / areas.sum()
    at = min(int(np.searchsorted(share, percent / 100.0)), len(order) - 1)
    return float(distances[order][at])


def surface_distances(test, reference, spacing):
    """The :class:`SurfaceDistances` of two boolean masks ``[z, y, x]`` of one grid, whose voxels are ``spacing``
    (x, y, z) mm.

    Each surface corner's distance to the other surface's nearest corner is found in a k-d tree of those corners
    (scipy's ``cKDTree``), on the true spacing: the distance the Euclidean distance transform of the whole box
    gives there, at the cost of the surfaces, not of the volume (ten times less on a head's soft tissue).

    >>> ball = np.zeros((9, 9, 9), bool); ball[2:7, 2:7, 2:7] = True
    >>> moved = np.roll(ball, 1, axis=2)
    >>> found = surface_distances(ball, moved, (1.0, 1.0, 1.0))
    >>> round(found.surface_dice(1.0), 3), found.hausdorff() <= 1.0
    (1.0, True)
    """
    from scipy.spatial import cKDTree

    test, reference = np.asarray(test, bool), np.asarray(reference, bool)
    sampling = np.array([float(s) for s in spacing][::-1])     # z, y, x: the arrays' axes
    either = test | reference
    if not either.any():
        empty = np.zeros(0)
        return SurfaceDistances(empty, empty, empty, empty)
    box = []
    for axis in range(3):                                      # the masks' box, from their projections on each axis
        held = np.flatnonzero(either.any(axis=tuple(a for a in range(3) if a != axis)))
        box.append(slice(int(held[0]), int(held[-1]) + 1))
    box = tuple(box)
    areas = surfel_areas(tuple(sampling))
    codes, points = [], []
    for mask in (test, reference):
        code = _corner_codes(np.pad(mask[box], 1))              # background all round: every corner of the surface
        at = np.nonzero((code != 0) & (code != 255))
        codes.append(code[at])
        points.append(np.stack(at, axis=1) * sampling)
    found = []
    for own, other in ((0, 1), (1, 0)):
        if len(points[other]) and len(points[own]):
            distances = cKDTree(points[other]).query(points[own], workers=-1)[0]
        else:
            distances = np.full(len(points[own]), np.inf)
        found += [distances, areas[codes[own]]]
    return SurfaceDistances(*found)


def _corner_codes(mask):
    """The code of each voxel corner (:data:`_CORNER_BITS`), on the grid of the voxels shifted by half a voxel:
    element ``p`` is the corner between voxels ``p - 1`` and ``p``.
    """
    from scipy import ndimage

    return ndimage.correlate(mask.astype(np.uint8), _CORNER_BITS, mode="constant", cval=0)


def dice(test, reference):
    """Sørensen-Dice of two boolean masks: ``2 |A ∩ B| / (|A| + |B|)``; ``nan`` when both are empty."""
    test, reference = np.asarray(test, bool), np.asarray(reference, bool)
    total = int(test.sum()) + int(reference.sum())
    return float(2 * int((test & reference).sum()) / total) if total else float("nan")


def components(mask):
    """The number of pieces of a boolean mask, voxels joined by a face, an edge or a corner (26-connectivity)."""
    from scipy import ndimage

    return int(ndimage.label(np.asarray(mask, bool), structure=np.ones((3, 3, 3), bool))[1])
