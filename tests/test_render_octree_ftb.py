import numpy as np
import pytest
from reference import exact

from voxrender._render.clip import Clip
from voxrender._render.literal.octree_ftb import B as BLOCKED
from voxrender._render.literal.octree_ftb import render_octree_ftb_literal
from voxrender._render.octree_btf import render_octree_btf, visible_axes
from voxrender._render.octree_ftb import render_octree_ftb, seen_from_the_front
from voxrender.object import octree, segments
from voxrender.space.view import View, angles_from_vpn, vpn_from_angles

PAPER_VPNS = [(1, -2, 1), (-1, -2, 1), (1, -1, 0), (0, -1, 0)]  # Zhao and Davis's Tables II and III
# one VPN of each viewing class: XYZ, XY, XZ, YZ, X, Y, Z, with both signs
CLASS_VPNS = [(1, 2, -3), (-2, 1, 0), (1, 0, 2), (0, -1, -1), (-1, 0, 0), (0, 1, 0), (0, 0, -1)]


def random_object(rng):
    shape = tuple(int(k) for k in rng.integers(3, 20, 3))
    mask = rng.random(shape) < rng.uniform(0.05, 0.9)
    box = tuple(slice(int(rng.integers(0, k // 2 + 1)), int(rng.integers(k // 2 + 1, k + 1))) for k in shape)
    mask[box] = rng.random() < 0.5          # a solid block or a hole: large octants of both colours
    return mask


def random_views(rng, count):
    for k in range(count):
        if k < len(CLASS_VPNS):
            alpha, beta, gamma = angles_from_vpn(CLASS_VPNS[k])
        else:
            alpha, beta, gamma = *rng.uniform(-180, 180, 2), rng.uniform(-90, 90)
        yield View(alpha, beta, gamma, (24, 26), float(rng.uniform(0.5, 2.0)))


def drop_own_counts(stats):
    """The production version's extra statistics, which the literal version has not."""
    stats.pop("white_seen")
    stats.pop("black_seconds")


def assert_same(a, b):
    """The same coverage and depths within 1e-5 voxels (the two versions compute depths independently)."""
    assert np.array_equal(np.isfinite(a), np.isfinite(b))
    assert np.allclose(a[np.isfinite(a)], b[np.isfinite(b)], atol=1e-5)


def literal_stats(encoded, view, clip=None):
    depth, stats = render_octree_ftb_literal(encoded, view, clip=clip)
    stats.pop("bitmap_bytes")
    return depth, stats


@pytest.mark.parametrize("seed", range(6))
def test_production_equals_the_literal_version_statistics_included(seed):
    rng = np.random.default_rng(seed)
    encoded = segments.encode(random_object(rng))
    for view in random_views(rng, 10):
        depth, stats = render_octree_ftb(encoded, view)
        expected_depth, expected = literal_stats(encoded, view)
        drop_own_counts(stats)
        assert stats == expected, view
        assert_same(depth, expected_depth)


def test_production_equals_the_literal_version_when_clipped():
    rng = np.random.default_rng(9)
    encoded = segments.encode(random_object(rng) | random_object(rng)[:1, :1, :1].any())
    for view in random_views(rng, 3):
        clip = Clip(x=(1, 9), z=(2, 12), cut_depth=-0.5)
        depth, stats = render_octree_ftb(encoded, view, clip=clip)
        expected_depth, expected = literal_stats(encoded, view, clip)
        drop_own_counts(stats)
        assert stats == expected
        assert_same(depth, expected_depth)


@pytest.mark.parametrize("mask", [np.ones((4, 4, 4), bool), np.zeros((5, 3, 2), bool), np.ones((1, 1, 1), bool)])
def test_single_octant_trees(mask):
    view = View(30, 20, 10, (16, 16), 2.0)
    depth, stats = render_octree_ftb(segments.encode(mask), view)
    expected_depth, expected = literal_stats(segments.encode(mask), view)
    drop_own_counts(stats)
    assert stats == expected
    assert_same(depth, expected_depth)


def test_seen_white_leaves_are_those_the_bitmaps_leave_unblocked():
    # Point 2 of the module docstring: a white leaf is unblocked in the literal traversal exactly when the
    # breadth-first search from the front reaches it.
    rng = np.random.default_rng(3)
    for view in random_views(rng, 8):
        encoded = segments.encode(random_object(rng))
        arrivals = {}
        tree = octree.build(encoded.to_mask())
        render_octree_ftb_literal(encoded, view, arrivals=arrivals, tree=tree)
        axes = visible_axes(vpn_from_angles(view.alpha, view.beta, view.gamma))
        seen = seen_from_the_front(tree, axes)[0]
        unblocked_white = {node for node, found in arrivals.items() if tree.color[node] == octree.WHITE
                           and not all(value == BLOCKED for value in found.values())}
        assert set(np.flatnonzero(seen).tolist()) == unblocked_white


def test_blocked_octants_are_never_descended():
    # Only the children of unblocked grey octants are visited: nothing below a blocked octant.
    rng = np.random.default_rng(4)
    encoded = segments.encode(random_object(rng))
    for view in random_views(rng, 8):
        stats = render_octree_ftb(encoded, view)[1]
        visited = stats["white_visited"] + stats["black_visited"] + stats["grey_visited"]
        assert visited == 1 + 8 * (stats["grey_visited"] - stats["grey_blocked"])


def test_fewer_faces_than_back_to_front_and_the_same_picture():
    zz, yy, xx = np.mgrid[:30, :30, :30] - 14.5
    ball = xx ** 2 + yy ** 2 + zz ** 2 <= 13 ** 2
    encoded = segments.encode(ball)
    for vpn in PAPER_VPNS:
        view = View(*angles_from_vpn(vpn), (48, 48), 1.2)
        depth, stats = render_octree_ftb(encoded, view)
        btf_depth, btf_stats = render_octree_btf(encoded, view)
        assert np.array_equal(depth, btf_depth)
        assert stats["black_faces"] < 0.5 * btf_stats["black_faces"]
        assert stats["pixels_accumulated"] < btf_stats["pixels_accumulated"]
        assert stats["pixels_painted"] == np.isfinite(depth).sum()


def test_vhf_head_octree_ftb_equals_the_literal_version_and_the_contract():
    from conftest import data_path

    from voxrender import io

    mask = io.read_volume(data_path("vhf_head")).values[::4, ::4, ::4] >= 300
    encoded = segments.encode(mask)
    for vpn in PAPER_VPNS:
        view = View(*angles_from_vpn(vpn), (160, 160), 1.0)
        depth, stats = render_octree_ftb(encoded, view)
        expected_depth, expected = literal_stats(encoded, view)
        drop_own_counts(stats)
        assert stats == expected
        assert_same(depth, expected_depth)
        # At (1, -1, 0) and (0, -1, 0) rows of pixel centres lie exactly on faces between slices: ties, which
        # both versions settle as the contract does, by keeping the nearer depth.
        assert_same(depth, render_octree_btf(encoded, view)[0])
        assert_same(depth, exact(mask, view.alpha, view.beta, view.gamma, view.size, view.scale))
