import numpy as np
import pytest
from test_contract import check

from voxrender._render import render
from voxrender._render.btf import render_btf
from voxrender._render.clip import Clip
from voxrender._render.ftb import render_ftb
from voxrender._render.literal.ftb import render_ftb_literal
from voxrender.object import segments
from voxrender.space.view import View

# The paper's Fig. 10 orientations, both ranges of alpha, gimbal lock, axis-aligned views, scales below
# 1/sqrt(2) and up to 3.
VIEWS = [(-45, 15, 1.0), (60, 120, 1.0), (30, 10, 1.0), (0, 0, 1.0), (90, 0, 2.0), (135, 45, 1.5), (200, -30, 2.0),
         (12, -89, 2.5), (-170, 63, 0.7), (45, 90, 0.5), (100, 200, 3.0)]


def assert_same(depth_a, depth_b, atol=1e-5):
    assert np.array_equal(np.isfinite(depth_a), np.isfinite(depth_b))
    assert np.allclose(depth_a[np.isfinite(depth_a)], depth_b[np.isfinite(depth_b)], atol=atol)


@pytest.mark.parametrize("alpha,beta,scale", VIEWS)
def test_production_equals_literal_images_and_statistics(ball, alpha, beta, scale):
    encoded = segments.encode(ball)
    view = View(alpha, beta, 0, (30, 32), scale)
    fast, fast_stats = render_ftb(encoded, view)
    slow, slow_stats = render_ftb_literal(encoded, view)
    assert fast_stats == slow_stats
    assert_same(fast, slow)


@pytest.mark.parametrize("seed", range(12))
def test_production_equals_literal_on_random_objects(seed):
    """Rows with many segments exercise every MERGE case, SPLIT included."""
    rng = np.random.default_rng(seed)
    mask = rng.random((8, 10, 14)) < rng.uniform(0.1, 0.6)
    alpha, beta = rng.uniform(-180, 180, 2)
    view = View(alpha, beta, 0, (26, 28), float(rng.uniform(0.5, 3)))
    clip = Clip(x=(1, 12), z=(None, 7), cut_depth=float(rng.uniform(-4, 1))) if seed % 2 else None
    fast, fast_stats = render_ftb(segments.encode(mask), view, clip=clip)
    slow, slow_stats = render_ftb_literal(segments.encode(mask), view, clip=clip)
    assert fast_stats == slow_stats
    assert_same(fast, slow)


def test_every_merge_case_occurs():
    rng = np.random.default_rng(1)
    totals = {str(c): 0 for c in range(1, 9)}
    for _ in range(4):
        mask = rng.random((8, 10, 14)) < 0.4
        _, stats = render_ftb(segments.encode(mask), View(*rng.uniform(-180, 180, 2), 0, (26, 28), 1.7))
        for c, n in stats["cases"].items():
            totals[c] += n
    assert all(n > 0 for n in totals.values()), totals


@pytest.mark.parametrize("alpha,beta,scale", VIEWS)
def test_ftb_and_btf_give_the_same_depth_image(ball, alpha, beta, scale):
    encoded = segments.encode(ball)
    view = View(alpha, beta, 0, (40, 44), scale)
    assert_same(render_ftb(encoded, view)[0], render_btf(encoded, view)[0])


def test_lit_pixels_are_never_tested_again():
    """A solid block seen face on: the back slices find their scanlines full and are skipped."""
    mask = np.ones((12, 8, 8), bool)
    depth, stats = render_ftb(segments.encode(mask), View(0, 0, 0, (16, 16), 1.0))
    assert stats["pixels_lit"] == np.isfinite(depth).sum() == 64
    assert stats["unlit_segments_start"] == 8 and stats["unlit_segments_end"] == 0
    assert stats["rows_skipped_full"] == 11 * 8  # every row behind the first slice
    assert stats["merge_calls"] == 8 and stats["cases"]["4"] == 8


def test_gamma_by_preimage_matches_the_contract():
    """Exact wherever the visible box lit one of the nine pre-image pixels around the turned centre (checked
    pixel by pixel); and such misses are few."""
    zz, yy, xx = np.mgrid[:24, :26, :28]
    blob = ((xx - 13) ** 2 + (yy - 12) ** 2 + (zz - 11) ** 2 <= 100) & ((xx + yy) % 7 != 0)  # grooved ball
    encoded = segments.encode(blob)
    for alpha, beta, gamma in [(30, 20, 35), (-60, 100, -120), (10, 10, 90)]:
        view = View(alpha, beta, gamma, (72, 80), 2.0)
        assert check(render(encoded, view, "ftb").depth, blob, "ftb", view) <= 0.002 * 72 * 80


def test_cutaway_shows_the_inside_of_a_hollow_ball():
    zz, yy, xx = np.mgrid[:21, :21, :21] - 10
    radius = np.sqrt(xx ** 2 + yy ** 2 + zz ** 2)
    shell = (radius <= 9) & (radius >= 7)
    view = View(0, 0, 0, (32, 32), 1.0)
    closed = render(segments.encode(shell), view, "ftb").depth
    opened = render(segments.encode(shell), view, "ftb", clip=Clip(cut_depth=-2.0)).depth
    assert closed[16, 16] == pytest.approx(-9.5)
    assert opened[16, 16] == pytest.approx(6.5)  # the far inner wall, seen through the cut


def test_vhf_head_ftb_equals_btf():
    from conftest import data_path

    from voxrender import io

    mask = io.read_volume(data_path("vhf_head")).values[::2, ::2, ::2] >= 300
    encoded = segments.encode(mask)
    for alpha, beta in [(-45, 15), (60, 120), (30, 10)]:
        view = View(alpha, beta, 0, (200, 200), 0.8)
        assert_same(render_ftb(encoded, view)[0], render_btf(encoded, view)[0])


def test_production_equals_literal_off_centre(ball):
    """With the picture centred off the volume centre (the default framing), the literal versions follow."""
    from voxrender._render.literal.btf import render_btf_literal
    from voxrender._render.literal.octree_btf import render_octree_btf_literal
    from voxrender._render.octree_btf import render_octree_btf

    encoded = segments.encode(ball)
    view = View(40, 25, 0, (30, 32), 1.6, centre=(1.7, -2.2))
    for fast, slow in ((render_ftb, render_ftb_literal), (render_btf, render_btf_literal),
                       (render_octree_btf, render_octree_btf_literal)):
        (depth, stats), (literal, literal_stats) = fast(encoded, view), slow(encoded, view)
        stats.pop("black_seconds", None)
        assert stats == literal_stats
        assert_same(depth, literal)


def test_merges_sorted_by_walk_order_when_the_runs_are_not(monkeypatch):
    """Spans are merged in walk order within a call; when their run order is not (checked), they are sorted by it,
    which gives the same image and counts."""
    from voxrender._render import ftb

    rng = np.random.default_rng(3)
    for _ in range(6):
        encoded = segments.encode(rng.random((8, 10, 14)) < 0.4)
        view = View(*rng.uniform(-180, 180, 2), 0, (26, 28), float(rng.uniform(0.5, 3)))
        fast, fast_stats = render_ftb(encoded, view)
        with monkeypatch.context() as patch:
            patch.setattr(ftb, "_in_walk_order", lambda *_: False)
            sorted_, sorted_stats = render_ftb(encoded, view)
        assert sorted_stats == fast_stats
        assert np.array_equal(sorted_, fast)


def test_merges_batched_by_rank_over_all_slices(monkeypatch):
    """Two blobs on different scanlines of different slices: the merges of both run in the same batches, as many
    as the busiest scanline has calls, not one set of batches per slice."""
    from voxrender._render import ftb

    mask = np.zeros((4, 12, 6), bool)
    mask[0, 1:3, 1:5] = True            # front slice, rows 1-2
    mask[3, 8:10, 1:5] = True           # back slice, rows 8-9
    batches, layout = [], ftb._merge_layout

    def counted(*args):
        result = layout(*args)
        batches.append(len(result[0]) - 1)      # its first item: the bounds of the batches
        return result

    monkeypatch.setattr(ftb, "_merge_layout", counted)
    depth, stats = render_ftb(segments.encode(mask), View(0, 0, 0, (16, 16), 1.0))
    assert stats["merge_calls"] == 4 and np.isfinite(depth).sum() == 16
    assert batches == [1]
