import numpy as np
import pytest

from voxrender.errors import InputError
from voxrender.pictures import shade


def test_gradient_of_a_tilted_plane():
    # Z' = 0.5 X' (voxel units) at scale 2: the normal is (0.5, 0, -1) normalised.
    x = (np.arange(20) + 0.5 - 10) / 2
    depth = np.tile(0.5 * x, (10, 1))
    normals = shade.depth_normals(depth, scale=2.0)
    assert np.allclose(normals[5, 10], np.array([0.5, 0, -1]) / np.sqrt(1.25))
    assert np.allclose(normals[5, 0], normals[5, 10])  # one-sided at the picture's edge


def test_lambert_brightness_follows_the_light():
    depth = np.zeros((5, 5))
    assert np.allclose(shade.gradient_shading(depth, light=(0, 0, -1))[2, 2], 1.0)
    assert np.allclose(shade.gradient_shading(depth, light=(1, 0, 0))[2, 2], 0.1)  # ambient only


def test_background_and_colours():
    depth = np.array([[0.0, np.inf], [1.0, 2.0]])
    rgb = shade.shade(depth, "depth", background=(1, 2, 3))
    assert rgb.dtype == np.uint8 and rgb.shape == (2, 2, 3)
    assert rgb[0, 1].tolist() == [1, 2, 3]
    assert rgb[0, 0, 0] > rgb[1, 0, 0] > rgb[1, 1, 0] > 0  # nearer is brighter


def test_depth_steps_do_not_make_shading_edges():
    depth = np.zeros((6, 6))
    depth[:, 3:] = 40.0  # an occlusion edge: a near surface in front of a far one
    brightness = shade.gradient_shading(depth, smoothing=0, depth_cue=0)
    assert np.allclose(brightness, 1.0)


def test_smooth_depth_keeps_background():
    depth = np.full((5, 5), np.inf)
    depth[1:4, 1:4] = 3.0
    smoothed = shade._smooth_depth(depth, 1.0)
    assert np.array_equal(np.isfinite(smoothed), np.isfinite(depth))
    assert np.allclose(smoothed[np.isfinite(smoothed)], 3.0)


def test_depth_to_uint16():
    out = shade.depth_to_uint16(np.array([[1.0, 3.0], [np.inf, 2.0]]))
    assert out.dtype == np.uint16 and out.tolist() == [[65535, 1], [0, 32768]]


def test_unknown_mode_and_zero_light():
    with pytest.raises(InputError):
        shade.shade(np.zeros((2, 2)), "phong")
    with pytest.raises(InputError):
        shade.gradient_shading(np.zeros((2, 2)), light=(0, 0, 0))


def test_ambient_occlusion_darkens_pits_not_planes():
    plane = np.tile(np.linspace(0, 5, 32, dtype=np.float32), (32, 1))        # a tilted plane: nothing occludes
    assert shade.ambient_occlusion(plane).max() < 0.05
    pit = np.zeros((32, 32), np.float32)
    pit[12:20, 12:20] = 6.0
    occlusion = shade.ambient_occlusion(pit)
    assert occlusion[16, 16] > 0.15 and occlusion[2, 2] == 0
    lit = shade.shade(pit, "depth-gradient", light=(0, 0, -1))
    darker = shade.shade(pit, "depth-gradient", light=(0, 0, -1), occlusion=occlusion)
    assert darker[16, 16, 0] < lit[16, 16, 0] and darker[2, 2, 0] == lit[2, 2, 0]
