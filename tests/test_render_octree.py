import time

import numpy as np
import pytest
from reference import exact

from voxrender._render.clip import Clip
from voxrender._render.literal.octree_btf import render_octree_btf_literal
from voxrender._render.literal.octree_ftb import QUAD_TAB, BlockingBitmap, render_octree_ftb_literal
from voxrender._render.octree_btf import front_to_back_children, render_octree_btf
from voxrender.object import segments
from voxrender.space.view import View, angles_from_vpn

PAPER_VPNS = [(1, -2, 1), (-1, -2, 1), (1, -1, 0), (0, -1, 0)]  # Zhao and Davis's Tables II and III


def blocky(seed=2):
    rng = np.random.default_rng(seed)
    mask = rng.random((12, 14, 10)) < 0.3
    mask[2:9, 3:10, 2:8] = True
    return mask


def views():
    rng = np.random.default_rng(5)
    for vpn in PAPER_VPNS:
        yield View(*angles_from_vpn(vpn), (32, 34), 1.4)
    yield View(90, 0, 0, (9, 8), 1.0)   # VPN (0, -1, 0): rows of pixel centres on faces between slices (ties)
    for _ in range(4):
        yield View(*rng.uniform(-180, 180, 2), rng.uniform(-90, 90), (32, 34), float(rng.uniform(0.6, 2.0)))


def assert_same(a, b):
    assert np.array_equal(np.isfinite(a), np.isfinite(b))
    assert np.allclose(a[np.isfinite(a)], b[np.isfinite(b)], atol=1e-5)


def test_front_to_back_order_of_children():
    # VPN (1, 1, 1): the paper's order 7, (6, 5, 3), (4, 1, 2), 0 in its labels (all-high = 7) is, in the
    # linear-octree labels used here (all-high = 0), the nearest, then 1-, 2- and 3-bit neighbours.
    order = front_to_back_children((1, 1, 1))
    zhao = [7 - label for label in order]
    assert zhao[0] == 7 and set(zhao[1:4]) == {6, 5, 3} and set(zhao[4:7]) == {4, 1, 2} and zhao[7] == 0


def test_quad_tab_gives_each_child_a_quadrant():
    for axis in range(3):
        # children that differ only along the axis share a quadrant; the four quadrants all occur
        assert sorted(set(QUAD_TAB[:, axis])) == [0, 1, 2, 3]
        assert all(np.bincount(QUAD_TAB[:, axis]) == 2)


def test_blocking_bitmap_size_is_4_to_the_n_bytes():
    for n in (2, 5, 8):
        assert abs(3 * len(BlockingBitmap(n).bits) - 4 ** n) <= 3


def contract(mask, view):
    return exact(mask, view.alpha, view.beta, view.gamma, view.size, view.scale)


@pytest.mark.parametrize("view", list(views()))
def test_octree_btf_production_equals_literal_and_the_contract(view):
    mask = blocky()
    encoded = segments.encode(mask)
    started = time.perf_counter()
    depth, stats = render_octree_btf(encoded, view)
    elapsed = time.perf_counter() - started
    literal, literal_stats = render_octree_btf_literal(encoded, view)
    assert 0 < stats.pop("black_seconds") <= elapsed      # the time in black octants is part of the render's
    assert stats == literal_stats
    assert_same(depth, literal)
    assert_same(depth, contract(mask, view))


@pytest.mark.parametrize("view", list(views()))
def test_octree_ftb_literal_gives_the_contract_and_blocks(view):
    mask = blocky()
    encoded = segments.encode(mask)
    depth, stats = render_octree_ftb_literal(encoded, view)
    assert_same(depth, contract(mask, view))
    _, btf_stats = render_octree_btf(encoded, view)
    assert stats["black_faces"] < btf_stats["black_faces"]
    assert stats["grey_visited"] <= btf_stats["grey_visited"]
    assert stats["white_blocked"] + stats["black_blocked"] + stats["grey_blocked"] > 0


def test_clipped_octree_views():
    mask = blocky()
    encoded = segments.encode(mask)
    view = View(30, 20, 0, (32, 34), 1.2)
    z, y, x = np.indices(mask.shape)
    r = view.matrix
    centre_depth = r[2, 0] * (x - 4.5) + r[2, 1] * (y - 6.5) + r[2, 2] * (z - 5.5)
    expected = contract(mask & (x >= 2) & (x < 7) & (centre_depth >= -1.0 - 1e-9), view)
    clip = Clip(x=(2, 7), cut_depth=-1.0)
    assert_same(render_octree_btf(encoded, view, clip=clip)[0], expected)
    assert_same(render_octree_btf_literal(encoded, view, clip=clip)[0], expected)
    assert_same(render_octree_ftb_literal(encoded, view, clip=clip)[0], expected)
