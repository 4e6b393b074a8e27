import numpy as np
import pytest
from reference import rotation

from voxrender.errors import InputError
from voxrender.space.view import (
    PRESETS,
    View,
    angles_from_matrix,
    angles_from_vpn,
    fit_scale,
    rotation_matrix,
    vpn_from_angles,
)


def test_rotation_matrix_is_the_papers_product():
    for angles in [(10, 20, 30), (-45, 15, 0), (60, 120, -70)]:
        assert np.allclose(rotation_matrix(*angles), rotation(*angles))


def test_theorem_1_rows_stay_parallel_to_scanlines():
    # After alpha and beta, an object row (along x) keeps a constant Y'.
    r = rotation_matrix(37, -71, 0)
    assert abs(r[1, 0]) < 1e-12


def test_theorem_2_round_trip_on_random_rotations():
    rng = np.random.default_rng(2)
    for _ in range(500):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        w, x, y, z = q
        t = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        alpha, beta, gamma = angles_from_matrix(t)
        assert -90 <= beta <= 90
        assert np.allclose(rotation_matrix(alpha, beta, gamma), t, atol=1e-9)


@pytest.mark.parametrize("beta", [90.0, -90.0])
def test_theorem_2_gimbal_lock(beta):
    for alpha, gamma in [(0, 0), (30, 10), (-120, 75), (179, -179)]:
        t = rotation_matrix(alpha, beta, gamma)
        a, b, g = angles_from_matrix(t)
        assert b == beta and g == 0.0
        assert np.allclose(rotation_matrix(a, b, g), t, atol=1e-9)


def test_angles_from_matrix_rejects_non_rotations():
    with pytest.raises(InputError):
        angles_from_matrix(np.diag([1, 1, -1]))


def test_vpn_round_trip():
    rng = np.random.default_rng(3)
    for vpn in list(rng.normal(size=(200, 3))) + [np.array(v, float) for v in
                                                  [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, 0, 1), (1, -2, 1)]]:
        angles = angles_from_vpn(vpn)
        assert angles[2] == 0.0
        assert np.allclose(vpn_from_angles(*angles), vpn / np.linalg.norm(vpn), atol=1e-9)


def test_vpn_rejects_zero():
    with pytest.raises(InputError):
        angles_from_vpn((0, 0, 0))


# The viewer of each preset, in LPS object axes (x to the patient's left, y to the back, z to the head),
# and which object axis points up (-Y') in the picture.
PRESET_GEOMETRY = {
    "anterior": ((0, -1, 0), (0, 0, 1)),
    "posterior": ((0, 1, 0), (0, 0, 1)),
    "left": ((1, 0, 0), (0, 0, 1)),
    "right": ((-1, 0, 0), (0, 0, 1)),
    "superior": ((0, 0, 1), (0, -1, 0)),
    "inferior": ((0, 0, -1), (0, -1, 0)),
}


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_presets_put_the_viewer_where_named(name):
    toward_viewer, up = PRESET_GEOMETRY[name]
    r = View.preset(name).matrix
    assert np.allclose(-r[2], toward_viewer, atol=1e-12)
    assert np.allclose(-r[1], up, atol=1e-12)
    assert PRESETS[name][2] == 0.0  # no preset needs a pre-image rotation


def test_fit_scale_fits_every_rotation():
    shape = (20, 30, 40)
    view = View(alpha=33, beta=71, gamma=12, size=(100, 80)).fitted(shape)
    corners = np.array(np.meshgrid([-0.5, 39.5], [-0.5, 29.5], [-0.5, 19.5])).reshape(3, -1).T
    centre = np.array([19.5, 14.5, 9.5])
    for angles in [(0, 0, 0), (33, 71, 12), (45, 45, 45), (90, 35.26, 45)]:
        projected = (rotation_matrix(*angles) @ (corners - centre).T)[:2] * view.scale
        assert np.all(np.abs(projected[0]) <= 40 + 1e-9) and np.all(np.abs(projected[1]) <= 50 + 1e-9)
    assert view.scale == fit_scale(shape, (100, 80))


def test_pixel_centres_follow_the_contract():
    view = View(size=(3, 4), scale=2.0)
    xs, ys = view.pixel_centres()
    assert xs.tolist() == [-0.75, -0.25, 0.25, 0.75]
    assert ys.tolist() == [-0.5, 0.0, 0.5]
    columns, rows = view.pixel_index(xs, ys)
    assert columns.tolist() == [0, 1, 2, 3] and rows.tolist() == [0, 1, 2]
    outside, _ = view.pixel_centres(np.array([-1, 4]), np.array([0]))
    assert outside.tolist() == [-1.25, 1.25]


def test_object_and_image_space_follow_the_contract():
    """p' = R (p - c) with c the volume centre, and back."""
    view = View(30, -20, 75, scale=1.0)
    shape = (7, 5, 9)
    points = np.random.default_rng(3).uniform(-2, 10, size=(3, 50))
    centre = (np.array(shape[::-1]) - 1) / 2
    expected = rotation_matrix(30, -20, 75) @ (points - centre[:, None])
    image = np.array(view.to_image(*points, shape))
    assert np.allclose(image, expected, atol=1e-12)
    assert np.allclose(np.array(view.to_object(*image, shape)), points, atol=1e-12)


def test_view_rejects_bad_values():
    with pytest.raises(InputError):
        View(scale=0)
    with pytest.raises(InputError):
        View(size=(0, 5))
    with pytest.raises(InputError):
        View(alpha=float("nan"))
    with pytest.raises(InputError):
        View.preset("sideways")


def test_axis_aligned_views_have_exact_matrices():
    # cos 90 computed in floating point is 6e-17; the octree methods read the viewing class (which VPN
    # components are zero) from the matrix, and rays along voxel faces must stay on them.
    from voxrender.space.view import rotation_matrix
    for alpha in (-180, -90, 0, 90, 270):
        for beta in (0, 90, 180):
            matrix = rotation_matrix(alpha, beta, 90)
            assert set(np.unique(matrix).tolist()) <= {-1.0, 0.0, 1.0}


def test_a_box_thinner_than_a_pixel_is_framed_on_a_pixel_centre():
    """A slab one voxel thick seen edge-on at under a pixel per voxel: its middle on a pixel centre, so a ray meets
    it; a box a pixel wide or more keeps its middle at the picture's middle, as before.
    """
    from voxrender.space.view import frame_together

    shape, box = (50, 600, 1), ((0, 49), (0, 599), (0, 0))
    for size in ((512, 512), (511, 511), (300, 200)):
        for view in (View(size=size).fitted(shape, box), View(size=size).fitted(shape, box, fit="volume"),
                     *frame_together([View(size=size), View(0, 90, size=size)], shape, box)):
            (x0, x1), _ = view.extent(shape, box)
            columns, _ = view.pixel_index(np.array([x0, x1]), 0.0)
            assert np.ceil(columns[0]) <= np.floor(columns[1]), (size, view)        # a column of pixel centres
    cube = ((0, 9), (0, 9), (0, 4))
    assert View(size=(100, 100)).fitted((10, 10, 10), cube).centre == (-2.5, 0.0)
