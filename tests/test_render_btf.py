import numpy as np
import pytest

from reference import agreement, march
from voxrender import segments
from voxrender.render import render
from voxrender.render.btf import render_btf, render_btf_literal
from voxrender.view import View

VIEWS = [(0, 0, 0, 1.0), (30, 20, 0, 1.3), (-45, 15, 10, 2.0), (60, 120, 0, 0.5), (90, 0, 0, 3.0),
         (30, 10, 0, 1.0), (-170, 63, -40, 0.7), (12, -89, 5, 2.5)]


@pytest.mark.parametrize("alpha,beta,gamma,scale", VIEWS)
def test_production_equals_literal(ball, alpha, beta, gamma, scale):
    view = View(alpha, beta, gamma, (30, 32), scale)
    encoded = segments.encode(ball)
    fast, fast_stats = render_btf(encoded, view)
    slow, slow_stats = render_btf_literal(encoded, view)
    assert fast_stats == slow_stats
    assert np.array_equal(np.isfinite(fast), np.isfinite(slow))
    assert np.allclose(fast[np.isfinite(fast)], slow[np.isfinite(slow)], atol=1e-5)


@pytest.mark.parametrize("alpha,beta,gamma,scale", VIEWS)
def test_matches_an_independent_ray_marcher(ball, alpha, beta, gamma, scale):
    size = (40, 44)
    depth = render(segments.encode(ball), View(alpha, beta, gamma, size, scale), "btf").depth
    reference = march(ball, alpha, beta, gamma, size, scale, step=0.02)
    iou, close = agreement(depth, reference, tolerance=0.03)
    assert iou == 1.0 and close == 1.0


def test_random_views_on_a_torus_match_the_marcher():
    zz, yy, xx = np.mgrid[:10, :20, :20]
    ring = np.sqrt((xx - 9.5) ** 2 + (yy - 9.5) ** 2) - 6
    mask = ring ** 2 + (zz - 4.5) ** 2 <= 6
    rng = np.random.default_rng(7)
    for alpha, beta, gamma in rng.uniform(-180, 180, size=(4, 3)):
        scale = float(rng.uniform(0.6, 2.5))
        depth = render(segments.encode(mask), View(alpha, beta, gamma, (48, 48), scale), "btf").depth
        iou, close = agreement(depth, march(mask, alpha, beta, gamma, (48, 48), scale), tolerance=0.03)
        # A ray that only grazes a cube edge for less than the marcher's step can be missed by it.
        assert iou >= 0.995 and close >= 0.99


def test_no_holes_at_large_scale():
    mask = np.ones((6, 6, 6), bool)
    for alpha, beta in [(0, 0), (45, 45), (33, 71)]:
        depth = render(segments.encode(mask), View(alpha, beta, 0, (64, 64), 5.0)).depth
        covered = np.isfinite(depth)
        # The projection of a convex cube is convex: every row of it is one unbroken run.
        for row in covered:
            where = np.flatnonzero(row)
            assert len(where) == 0 or where[-1] - where[0] + 1 == len(where)


def test_default_view_shows_slice_zero_with_x_right_and_y_down():
    mask = np.zeros((4, 6, 8), bool)
    mask[0, 0, 7] = True  # slice 0, top row, rightmost column: nearest to the viewer
    mask[3, 5, 0] = True  # last slice, bottom row, leftmost column: farthest
    depth = render(segments.encode(mask), View(size=(6, 8), scale=1.0)).depth
    assert depth[0, 7] == pytest.approx(-2.0)  # front face of slice 0 is at Z' = -1.5 - 0.5
    assert depth[5, 0] == pytest.approx(1.0)
    assert np.isfinite(depth).sum() == 2


def test_painter_order_hides_what_is_behind():
    mask = np.zeros((5, 3, 3), bool)
    mask[1] = True
    mask[3] = True
    depth, stats = render_btf(segments.encode(mask), View(size=(3, 3), scale=1.0))
    assert np.allclose(depth, -1.5) and stats["pixel_writes"] == 18  # both slabs painted, the near one wins


def test_vhf_head_against_marcher():
    from conftest import data_path
    from voxrender import io

    volume = io.read_volume(data_path("vhf_head"))
    mask = volume.values[::4, ::4, ::4] >= 300  # a quarter-resolution skull keeps the reference fast
    view = View(30, 20, 0, (96, 96), 0.9)
    depth = render(segments.encode(mask), view).depth
    iou, close = agreement(depth, march(mask, 30, 20, 0, (96, 96), 0.9, step=0.05), tolerance=1.5)
    assert iou >= 0.99 and close >= 0.98


def test_rays_along_faces_between_slices_take_the_nearer_voxel():
    # Looking along -y with 5 slices and an even picture height, every row of pixel centres lies on a face
    # between two slices; a ray there touches voxels of both slices, and the contract takes the nearer.
    rng = np.random.default_rng(1)
    mask = rng.random((5, 6, 6)) < 0.3
    view = View(90, 0, 0, (8, 8), 1.0)           # VPN (0, -1, 0)
    encoded = segments.encode(mask)
    expected = march(mask, 90, 0, 0, (8, 8), 1.0, step=0.01)
    for depth in (render_btf(encoded, view)[0], render_btf_literal(encoded, view)[0],
                  render(encoded, view, "octree-btf").depth, render(encoded, view, "octree-ftb").depth):
        assert np.array_equal(np.isfinite(depth), np.isfinite(expected))
        assert np.allclose(depth[np.isfinite(depth)], expected[np.isfinite(expected)], atol=0.02)
