import numpy as np
import pytest
from reference import exact
from test_contract import check

from voxrender._render import render
from voxrender._render.btf import render_btf
from voxrender._render.literal.btf import render_btf_literal
from voxrender.object import segments
from voxrender.space.view import View

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
    for renderer in (render_btf, render_btf_literal):
        depth, stats = renderer(segments.encode(mask), View(size=(3, 3), scale=1.0))
        assert np.allclose(depth, -1.5) and stats["pixel_writes"] == 18  # both slabs painted, the near one last


def test_a_reversed_order_paints_what_is_behind(monkeypatch):
    """Both versions paint over and compare no depths: turned front to back, the far slab would show."""
    import voxrender._render.btf as btf

    mask = np.zeros((5, 3, 3), bool)
    mask[1] = True
    mask[3] = True
    monkeypatch.setattr(btf, "back_to_front", lambda n, direction: np.arange(n)[::-1] if direction <= 0
                        else np.arange(n))
    depth, _ = btf.render_btf(segments.encode(mask), View(size=(3, 3), scale=1.0))
    assert np.allclose(depth, 0.5)


def test_vhf_head_against_the_reference():
    from conftest import data_path

    from voxrender import io

    volume = io.read_volume(data_path("vhf_head"))
    mask = volume.values[::4, ::4, ::4] >= 300  # a quarter-resolution skull keeps the reference fast
    view = View(30, 20, 0, (96, 96), 0.9)
    for method in ("btf", "ftb"):
        check(render(segments.encode(mask), view, method).depth, mask, method, view)


def test_rays_along_faces_between_slices():
    # Looking along -y with 5 slices and an even picture height, every row of pixel centres lies on a face
    # between two slices; a ray there runs along voxels of both slices.  The contract takes the nearer; the
    # painter keeps the one painted last, which is a voxel the ray meets (checked), and both versions agree.
    rng = np.random.default_rng(1)
    mask = rng.random((5, 6, 6)) < 0.3
    view = View(90, 0, 0, (8, 8), 1.0)           # VPN (0, -1, 0)
    encoded = segments.encode(mask)
    painted, literal = render_btf(encoded, view)[0], render_btf_literal(encoded, view)[0]
    assert np.array_equal(np.isfinite(painted), np.isfinite(literal))
    assert np.allclose(painted[np.isfinite(painted)], literal[np.isfinite(literal)], atol=1e-6)
    assert check(painted, mask, "btf", view) > 0        # there are such pixels, and each is a voxel the ray meets
    expected = exact(mask, 90, 0, 0, (8, 8), 1.0)
    for method in ("octree-btf", "octree-ftb", "octree-sort", "zbuffer"):
        depth = render(encoded, view, method).depth
        assert np.array_equal(np.isfinite(depth), np.isfinite(expected))
        assert np.allclose(depth[np.isfinite(depth)], expected[np.isfinite(expected)], atol=1e-5)
