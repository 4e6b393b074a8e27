"""The octree build's memory estimate (octree.build_bytes) bounds what the build takes, and check_build_memory
refuses an object whose estimate is over the limit, before building anything."""

import gc
import tracemalloc

import numpy as np
import pytest

from voxrender.errors import InputError
from voxrender.object import octree
from voxrender.object.segments import encode


def _objects():
    rng = np.random.default_rng(7)
    n = 40
    z, y, x = np.indices((n, n, n)) - (n - 1) / 2
    steps = np.arange(n) * 0.5
    gyroid = (np.sin(steps)[None, None] * np.cos(steps)[None, :, None]
              + np.sin(steps)[None, :, None] * np.cos(steps)[:, None, None]
              + np.sin(steps)[:, None, None] * np.cos(steps)[None, None])
    return {"ball": x ** 2 + y ** 2 + z ** 2 <= (0.4 * n) ** 2,
            "box": np.pad(np.ones((n // 2, n - 3, n - 5), bool), ((n // 4, n // 4), (1, 2), (2, 3))),
            "gyroid": gyroid > 0.3,
            "noise": rng.random((n, n, n)) < 0.5,
            "sparse noise": rng.random((n, n, n)) < 0.01}


def _build_peak(segments):
    """The peak of NumPy's allocations while the octree, its linear octree and its face adjacency are built."""
    gc.collect()
    tracemalloc.start()
    try:
        octree.sections(octree.build_from_segments(segments))
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("name", list(_objects()))
def test_estimate_bounds_the_build(name):
    segments = encode(_objects()[name])
    peak = _build_peak(segments)
    estimate = octree.build_bytes(segments)
    assert peak <= estimate <= 4 * peak, (name, peak, estimate)


def test_estimate_grows_with_threads_and_runs():
    segments = encode(_objects()["noise"])
    assert octree.build_bytes(segments, threads=1) < octree.build_bytes(segments, threads=4)
    assert octree.build_bytes(segments) > octree.build_bytes(encode(_objects()["box"]))


def test_check_refuses_over_and_accepts_under_the_estimate():
    segments = encode(_objects()["gyroid"])
    estimate = octree.build_bytes(segments)
    octree.check_build_memory(segments, estimate)
    octree.check_build_memory(segments, 2 * estimate)
    with pytest.raises(InputError) as refusal:
        octree.check_build_memory(segments, estimate - 1)
    assert refusal.value.parameter == "max_memory"
    message = refusal.value.message
    assert "binned by 2" in message and "ftb, btf, raycast" in message and "allow more memory" in message
    assert "kB" in message or "MB" in message


def test_refusal_names_sizes_in_words():
    segments = encode(_objects()["ball"])
    with pytest.raises(InputError, match=r"about [\d.]+ [kMG]B to build, more than the 1 kB of memory allowed"):
        octree.check_build_memory(segments, 1000)


# Rendering in bounded memory: ftb reads the runs a group of slabs at a time.

@pytest.mark.parametrize("seed", range(6))
def test_ftb_in_groups_of_slabs_is_the_pass_in_one(seed, monkeypatch):
    """Groups of one or a few slabs give the depth image, the item buffer's boxes and every count of one pass."""
    from voxrender._render import ftb
    from voxrender._render.clip import Clip
    from voxrender._render.preimage import render_preimage
    from voxrender.space.view import View

    rng = np.random.default_rng(seed)
    encoded = encode(rng.random((9, 11, 14)) < rng.uniform(0.1, 0.6))
    view = View(*rng.uniform(-180, 180, 2), 0, (26, 28), float(rng.uniform(0.5, 3)))
    clip = Clip(x=(1, 12), z=(None, 7), cut_depth=float(rng.uniform(-4, 1))) if seed % 2 else None
    whole, whole_stats, (whole_owner, whole_boxes) = ftb.render_ftb(encoded, view, clip=clip, items=True)
    turned = render_preimage(ftb.render_ftb, encoded, View(view.alpha, view.beta, 30, (20, 20), 1.0), clip=clip)
    monkeypatch.setattr(ftb, "_SPANS_AT_ONCE", int(rng.integers(1, 60)))
    assert len(ftb._slab_groups(encoded, ftb._plan_screen(encoded, view))) > 3
    parts, parts_stats, (parts_owner, parts_boxes) = ftb.render_ftb(encoded, view, clip=clip, items=True)
    assert parts_stats == whole_stats
    assert np.array_equal(parts, whole)
    lit = whole_owner >= 0
    assert np.array_equal(parts_owner >= 0, lit)
    assert np.array_equal(parts_boxes[parts_owner[lit]], whole_boxes[whole_owner[lit]])
    turned_parts = render_preimage(ftb.render_ftb, encoded, View(view.alpha, view.beta, 30, (20, 20), 1.0), clip=clip)
    assert np.array_equal(turned_parts[0], turned[0]) and turned_parts[1] == turned[1]


# raycast steps its rays through a bitmap made from the runs a slice at a time, not through a bool volume.

@pytest.mark.parametrize("shape", [(5, 7, 9), (6, 9, 64), (7, 5, 130), (9, 13, 67)])
def test_bitmap_reads_dilates_and_blocks_as_the_bool_mask(shape):
    from voxrender._render.clip import Clip
    from voxrender._render.raycast import Bitmap, empty_space, proximity_band
    from voxrender.space.view import View

    rng = np.random.default_rng(sum(shape))
    mask = rng.random(shape) < 0.05
    mask[0, 0, -1] = mask[-1, -1, 0] = True                  # the corners, where padding and carries are
    bits = Bitmap.of_segments(encode(mask))
    z, y, x = np.indices(shape).reshape(3, -1)
    assert np.array_equal(bits[z, y, x], mask[z, y, x])
    assert np.array_equal(proximity_band(bits)[z, y, x], proximity_band(mask)[z, y, x])
    for block in (2, 4, 8):
        assert np.array_equal(empty_space(bits, block), empty_space(mask, block))
    view = View(30, 20, 0, (16, 16), 1.0)
    clip = Clip(x=(1, shape[2] - 2), y=(2, None), cut_depth=-1.5)
    assert np.array_equal(Bitmap.of_segments(encode(mask), view, clip)[z, y, x],
                          clip.apply_mask(mask, view)[z, y, x])


@pytest.mark.parametrize("seed", range(8))
def test_a_clipped_octree_is_built_from_the_clipped_runs_as_from_the_clipped_mask(seed):
    from voxrender._render.clip import Clip
    from voxrender._render.octree_btf import _clipped
    from voxrender.space.view import View

    rng = np.random.default_rng(seed)
    mask = rng.random((9, 11, 14)) < 0.4
    view = View(*rng.uniform(-180, 180, 3), (20, 20), 1.0)
    clip = Clip(x=(int(rng.integers(0, 4)), int(rng.integers(8, 15))), z=(None, int(rng.integers(3, 9))),
                cut_depth=float(rng.uniform(-4, 2)) if seed % 2 else None)
    clipped = _clipped(encode(mask), view, clip)
    assert np.array_equal(clipped.to_mask(), clip.apply_mask(mask, view))
    from_runs, from_mask = octree.build_from_segments(clipped), octree.build(clip.apply_mask(mask, view))
    assert np.array_equal(from_runs.color, from_mask.color) and np.array_equal(from_runs.origin, from_mask.origin)
