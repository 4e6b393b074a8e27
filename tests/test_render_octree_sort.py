import numpy as np
import pytest
from reference import exact

from voxrender import samples
from voxrender._render.clip import Clip
from voxrender._render.literal.octree_sort import recode_literal, render_octree_sort_literal, render_zbuffer_literal
from voxrender._render.octree_sort import decode, recode, render_octree_sort, render_zbuffer, visible_faces, voxel_codes
from voxrender.object import octree, segments
from voxrender.space.view import View

# The linear-octree paper's Table 2: (x, y, z), Q, Q' for VPN (1.0, 1.1, 1.2), Q' for VPN (-2.0, 1.5, 1.0).
TABLE_2 = [((3, 3, 3), "00", "00", "60"), ((2, 3, 3), "01", "01", "40"), ((3, 2, 3), "02", "04", "64"),
           ((2, 2, 3), "03", "05", "44"), ((3, 3, 2), "04", "20", "61"), ((2, 3, 2), "05", "21", "41"),
           ((3, 2, 2), "06", "24", "65"), ((2, 2, 2), "07", "25", "45"), ((1, 3, 3), "10", "02", "20"),
           ((3, 1, 2), "24", "30", "71"), ((3, 3, 1), "40", "40", "62")]


def staircase():
    """The linear-octree paper's Fig. 2 staircase as a mask."""
    return samples.staircase() > samples.SAMPLE_THRESHOLD


def test_table_2_codes_and_recodes():
    tree = octree.build(staircase())
    codes = voxel_codes(tree)
    assert sorted(int(q, 8) for _, q, _, _ in TABLE_2) == sorted(codes.tolist())
    for xyz, q, first, second in TABLE_2:
        assert decode([int(q, 8)], 2)[0].tolist() == list(xyz)
        for vpn, expected in (((1.0, 1.1, 1.2), first), ((-2.0, 1.5, 1.0), second)):
            assert recode(np.array([int(q, 8)]), 2, vpn)[0] == int(expected, 8) == recode_literal(int(q, 8), 2, vpn)


@pytest.mark.parametrize("vpn,expected", [
    ((1.0, 1.1, 1.2), [(3, 3, 3), (2, 3, 3), (1, 3, 3), (3, 2, 3), (2, 2, 3), (3, 3, 2), (2, 3, 2), (3, 2, 2),
                       (2, 2, 2), (3, 1, 2), (3, 3, 1)]),
    ((-2.0, 1.5, 1.0), [(1, 3, 3), (2, 3, 3), (2, 3, 2), (2, 2, 3), (2, 2, 2), (3, 3, 3), (3, 3, 2), (3, 3, 1),
                        (3, 2, 3), (3, 2, 2), (3, 1, 2)]),
])
def test_sorted_orders_of_the_paper(vpn, expected):
    codes = voxel_codes(octree.build(staircase()))
    order = np.argsort(recode(codes, 2, vpn), kind="stable")
    assert [tuple(v) for v in decode(codes[order], 2).tolist()] == expected


def test_recode_orders_front_to_back_for_random_views():
    rng = np.random.default_rng(0)
    codes = np.arange(8 ** 3)
    xyz = decode(codes, 3)
    for vpn in rng.normal(size=(50, 3)):
        order = np.argsort(recode(codes, 3, vpn), kind="stable")
        # Each voxel must come before every voxel it could hide: any voxel behind it along all axes.
        position = np.empty(len(order), int)
        position[order] = np.arange(len(order))
        sign = np.where(vpn >= 0, 1, -1)
        a, b = rng.integers(0, len(codes), (2, 2000))
        behind = np.all((xyz[a] - xyz[b]) * sign >= 0, axis=1) & np.any(xyz[a] != xyz[b], axis=1)
        assert behind.sum() > 50 and np.all(position[a][behind] < position[b][behind])


def test_visible_faces_table_3():
    assert visible_faces((1, 1, 1)) == ["eastern", "southern", "front"]
    assert visible_faces((-1, 0, -2)) == ["western", "back"]


@pytest.mark.parametrize("seed", range(6))
def test_production_equals_literal_and_btf(seed):
    rng = np.random.default_rng(seed)
    mask = rng.random((6, 7, 5)) < 0.4
    encoded = segments.encode(mask)
    view = View(*rng.uniform(-180, 180, 2), rng.uniform(-90, 90), (20, 22), float(rng.uniform(0.5, 2.5)))
    clip = Clip(x=(1, 4)) if seed % 2 else None
    kept = mask.copy()
    if clip:
        kept[:, :, :1] = kept[:, :, 4:] = False
    reference = exact(kept, view.alpha, view.beta, view.gamma, view.size, view.scale)
    for fast, slow, options in [(render_octree_sort, render_octree_sort_literal, {}),
                                (render_octree_sort, render_octree_sort_literal, {"order": "painter"}),
                                (render_zbuffer, render_zbuffer_literal, {})]:
        depth, stats = fast(encoded, view, clip=clip, **options)
        literal, literal_stats = slow(encoded, view, clip=clip, **options)
        assert stats == literal_stats
        for other in (literal, reference):
            assert np.array_equal(np.isfinite(depth), np.isfinite(other))
            assert np.allclose(depth[np.isfinite(depth)], other[np.isfinite(other)], atol=1e-5)
