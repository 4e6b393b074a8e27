"""voxrender.space.grids: a label map on another grid brought onto its image's by patient position."""

import math
import warnings

import numpy as np
import pytest

from voxrender.errors import InputError
from voxrender.io import Volume
from voxrender.space import grids
from voxrender.space.grids import patient_affine

CENTRE, RADIUS = np.array([20.3, 19.6, 17.8]), 11.0       # mm, patient LPS
IMAGE = Volume(np.zeros((36, 40, 42), np.int16), (1.0, 1.0, 1.0), {"origin": [0.0, 0.0, 0.0]})


def centres(shape, affine):
    """The patient positions (3, z, y, x) of a grid's voxel centres."""
    z, y, x = np.indices(shape, dtype=float)
    affine = np.asarray(affine)
    return np.einsum("ij,jzyx->izyx", affine[:3, :3], np.stack([x, y, z])) + affine[:3, 3, None, None, None]


def ball_on(shape, affine):
    return (np.linalg.norm(centres(shape, affine) - CENTRE[:, None, None, None], axis=0) <= RADIUS).astype(np.uint8)


def grid(direction, spacing, origin, shape):
    """A label-map Volume of the analytic ball on the grid ``direction`` (columns: voxel axes), spacing, origin."""
    volume = Volume(np.zeros(shape, np.uint8), tuple(spacing), {"origin": list(origin)}, np.asarray(direction, float))
    volume.values = ball_on(shape, patient_affine(volume))
    return volume


def turn(degrees, axis):
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    i, j = [a for a in range(3) if a != axis]
    matrix = np.eye(3)
    matrix[i, i], matrix[i, j], matrix[j, i], matrix[j, j] = c, -s, s, c
    return matrix


LABEL_GRIDS = {
    # 2x coarser, x flipped (voxel x runs toward the patient's right), shifted by a fraction of a voxel
    "shifted, coarser, flipped": grid(np.diag([-1.0, 1.0, 1.0]), (2, 2, 2), (43.3, -1.7, 0.6), (20, 22, 23)),
    # voxel x along patient y and voxel y along patient x, other spacings
    "permuted": grid([[0, 1, 0], [1, 0, 0], [0, 0, 1]], (1.5, 1.25, 0.8), (-0.4, 2.2, 3.1), (40, 34, 30)),
    # turned 10 degrees about z (and 4 about x): oblique
    "oblique": grid(turn(10, 2) @ turn(4, 0), (1.2, 1.2, 1.2), (6.0, -2.0, 0.5), (34, 36, 36)),
}


def farthest_miss(placed):
    """How far from the sphere (mm) the farthest image voxel lies whose label differs from the analytic ball."""
    differ = placed != ball_on(IMAGE.shape, patient_affine(IMAGE))
    distance = np.abs(np.linalg.norm(centres(IMAGE.shape, patient_affine(IMAGE)) - CENTRE[:, None, None, None],
                                     axis=0) - RADIUS)
    return distance[differ].max(initial=0)


@pytest.mark.parametrize("name", LABEL_GRIDS)
def test_a_ball_on_another_grid_pairs_with_the_image_within_one_voxel(name):
    label = LABEL_GRIDS[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)           # their extents differ from the image's
        placed = grids.pair(label, IMAGE)
    expected = ball_on(IMAGE.shape, patient_affine(IMAGE))
    assert placed.shape == IMAGE.shape and placed.dtype == np.uint8
    # nearest neighbour: each image voxel takes the label voxel its centre lies in, whose centre is at most half
    # that voxel's diagonal away; so a voxel that differs lies within one label voxel of the sphere
    assert farthest_miss(placed) <= max(label.spacing)
    assert (placed != expected).sum() < 0.25 * expected.sum()   # and the ball is there, not an empty map
    assert placed.sum() > 0.75 * expected.sum()


def test_a_wrong_placement_would_be_seen():
    """The check above can fail: the flipped label map's voxels taken as stored (x not flipped) put the ball 2 mm
    off, farther from the sphere than a label voxel.
    """
    label = LABEL_GRIDS["shifted, coarser, flipped"]
    wrong = Volume(label.values[:, :, ::-1], label.spacing, label.meta, label.direction)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        assert farthest_miss(grids.pair(wrong, IMAGE)) > max(label.spacing)


def test_the_same_grid_gives_the_very_array():
    label = Volume(np.ones(IMAGE.shape, np.uint8), IMAGE.spacing, dict(IMAGE.meta))
    assert grids.pair(label, IMAGE) is label.values
    affine = patient_affine(IMAGE)
    nearly = affine.copy()
    nearly[0, 3] += 5e-5
    assert grids.resample_nearest(label.values, nearly, IMAGE.shape, affine) is label.values
    moved = affine.copy()
    moved[0, 3] += 1.0
    assert grids.resample_nearest(label.values, moved, IMAGE.shape, affine) is not label.values
    assert grids.relate(IMAGE.shape, affine, IMAGE.shape, affine).lines()[-1] == "relation: same grid"


def test_no_overlap_is_refused_naming_both_extents():
    far = Volume(np.ones((10, 10, 10), np.uint8), (1.0, 1.0, 1.0), {"origin": [500.0, 0.0, 0.0]})
    with pytest.raises(InputError, match=r"seg.nii.gz does not overlap the image: it spans x 499.5 to 509.5, .* "
                                         r"and the image x -0.5 to 41.5, y -0.5 to 39.5, z -0.5 to 35.5 mm") as info:
        grids.pair(far, IMAGE, label_name="seg.nii.gz")
    assert info.value.parameter == "labels_from"


def test_the_extent_warning_fires_when_extents_differ_by_more_than_a_voxel():
    # 2 mm voxels over exactly the image's extent (42 x 40 x 36 mm): no warning
    matching = Volume(np.ones((18, 20, 21), np.uint8), (2.0, 2.0, 2.0), {"origin": [0.5, 0.5, 0.5]})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        placed = grids.pair(matching, IMAGE)
    assert placed.all()                       # every image voxel lies in a label voxel: none lost at the edges
    # three voxels more along x: a warning with the distance in mm
    longer = Volume(np.ones((36, 40, 45), np.uint8), (1.0, 1.0, 1.0), {"origin": [0.0, 0.0, 0.0]})
    with pytest.warns(UserWarning, match=r"the label map and the image differ in extent by 3.0 mm, more than one "
                                         r"voxel \(1 mm\)"):
        grids.pair(longer, IMAGE)
    # within a voxel: no warning
    shifted = Volume(np.ones(IMAGE.shape, np.uint8), (1.0, 1.0, 1.0), {"origin": [0.6, 0.0, 0.0]})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        grids.pair(shifted, IMAGE)


def test_relate_tells_how_the_grids_differ():
    label = LABEL_GRIDS["shifted, coarser, flipped"]
    relation = grids.relate(label.shape, patient_affine(label), IMAGE.shape, patient_affine(IMAGE))
    assert not relation.same and relation.source_voxel_mm == (2.0, 2.0, 2.0)
    lines = relation.lines(source_stored="RAS")
    assert lines[0] == "label map grid: 23 x 22 x 20 at 2 x 2 x 2 mm, origin (43.3, -1.7, 0.6) mm, RAS stored"
    assert lines[1] == "image grid: 42 x 40 x 36 at 1 x 1 x 1 mm, origin (0.0, 0.0, 0.0) mm, LPS axes"
    assert lines[2].startswith("relation: shifted by (") and "2x coarser, flipped x; extents differ by" in lines[2]
    # the extents: x 43.3 + 1 down to 43.3 - 44 - 1 = -1.7, y -2.7 to 41.3, z -0.4 to 39.6
    low, high = relation.source_extent
    assert np.allclose(low, [-1.7, -2.7, -0.4]) and np.allclose(high, [44.3, 41.3, 39.6])
    gap = np.linalg.norm([max(1.2, 2.8), max(2.2, 1.8), max(0.1, 4.1)])
    assert relation.extent_gap_mm == pytest.approx(gap)
    oblique = LABEL_GRIDS["oblique"]
    words = grids.relate(oblique.shape, patient_affine(oblique), IMAGE.shape, patient_affine(IMAGE)).lines()
    assert "oblique by 10.8 degrees" in words[0] and "1.2x coarser, turned 10.8 degrees" in words[2]
    permuted = LABEL_GRIDS["permuted"]
    words = grids.relate(permuted.shape, patient_affine(permuted), IMAGE.shape, patient_affine(IMAGE)).lines()
    assert "voxels 1.25 x 1.5 x 0.8 times the image's, its x, y, z along the image's y, x, z" in words[2]


@pytest.mark.parametrize("oblique", [False, True])
def test_the_overlap_is_the_fraction_of_centres_inside(oblique):
    """Against every centre counted: exact for parallel axes, within a percent for oblique ones (sampled)."""
    direction = turn(7, 1) if oblique else np.diag([1.0, -1.0, 1.0])
    label = Volume(np.zeros((30, 200, 50), np.uint8), (0.5, 0.3, 1.7), {"origin": [25.0, 30.0, -9.0]}, direction)
    affine = patient_affine(label)
    to_image = np.linalg.solve(patient_affine(IMAGE), affine)
    index = np.einsum("ij,jzyx->izyx", to_image[:3, :3], np.stack(np.indices(label.shape)[::-1]).astype(float))
    index += to_image[:3, 3, None, None, None]
    sizes = np.array(IMAGE.shape[::-1])[:, None, None, None]
    counted = np.mean(np.all((index >= -0.5) & (index <= sizes - 0.5), axis=0))
    found = grids.relate(label.shape, affine, IMAGE.shape, patient_affine(IMAGE)).overlap
    assert 0.05 < counted < 0.95
    assert found == pytest.approx(counted, abs=0.01 if oblique else 1e-12)


def test_resample_keeps_the_dtype_and_fills_outside():
    values = np.array([[[True, False], [False, True]]])
    source = np.eye(4)
    source[:3, 3] = [1.0, 0.0, 0.0]                                 # one voxel to the +x
    moved = grids.resample_nearest(values, source, (1, 2, 3), np.eye(4))
    assert moved.dtype == np.bool_ and moved.tolist() == [[[False, True, False], [False, False, True]]]
    moved = grids.resample_nearest(np.full((1, 2, 2), 7, np.int16), source, (1, 2, 3), np.eye(4), fill=-1)
    assert moved.dtype == np.int16 and moved.tolist() == [[[-1, 7, 7], [-1, 7, 7]]]
