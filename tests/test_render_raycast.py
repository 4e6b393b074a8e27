import numpy as np
import pytest
from reference import entries, exact

from voxrender._render import render
from voxrender._render.raycast import proximity_band, render_raycast
from voxrender.object import segments
from voxrender.space.view import View

VIEWS = [(31, 19, 7, 1.3), (-45, 15, 10, 2.0), (61, 119, 0, 0.7), (12, -80, 5, 2.5), (0, 0, 0, 1.0)]


def thin_shell(n=40, radius=15):
    """A sphere one voxel thick: 26-rays slip through it."""
    z, y, x = np.mgrid[:n, :n, :n] - (n - 1) / 2
    return np.abs(np.sqrt(x * x + y * y + z * z) - radius) <= 0.5


def against_the_reference(depth, mask, view):
    """``(late, leaks, misses)`` of a depth image against the exact reference: a late hit entered a cube the ray
    meets up to a cube's diagonal behind the first; a leak went through the object (farther, or nothing); a
    miss found nothing where the ray meets the object.  Every hit must be the entry of a cube the ray meets."""
    reference = exact(mask, view.alpha, view.beta, view.gamma, view.size, view.scale)
    met = entries(mask, view.alpha, view.beta, view.gamma, view.size, view.scale)
    for pixel in np.flatnonzero(np.isfinite(depth)):
        assert np.any(np.abs(met.get(int(pixel), np.zeros(0)) - depth.flat[pixel]) <= 1e-5)
    found = np.isfinite(reference)
    with np.errstate(invalid="ignore"):
        behind = depth - reference
    late = found & (behind > 1e-5) & (behind <= 3 ** 0.5 + 1e-6)
    leaks = found & ~(behind <= 3 ** 0.5 + 1e-6)
    misses = found & ~np.isfinite(depth)
    assert not (np.isfinite(depth) & ~found).any()
    return int(late.sum()), int(leaks.sum()), int(misses.sum())


@pytest.mark.parametrize("alpha,beta,gamma,scale", VIEWS)
def test_adaptive_rays_do_not_leak(ball, alpha, beta, gamma, scale):
    """26 in empty space, 6 near the object: no leaks and no misses against the reference (6-rays meet the
    contract exactly: tests/test_contract.py); its own count against its 6-rays says the same."""
    view = View(alpha, beta, gamma, (40, 44), scale)
    depth, stats = render_raycast(segments.encode(ball), view, connectivity="adaptive", compare=True)
    late, leaks, misses = against_the_reference(depth, ball, view)
    assert leaks == misses == 0 and stats["leaks"] == stats["misses"] == 0
    assert stats["late_hits"] == late


def test_26_rays_leak_through_a_thin_shell_and_adaptive_does_not():
    mask = thin_shell()
    encoded = segments.encode(mask)
    view = View(30, 10, 0, (64, 64), 1.5)
    _, six = render_raycast(encoded, view, connectivity="6")
    long_depth, long = render_raycast(encoded, view, connectivity="26", compare=True)
    adaptive_depth, adaptive = render_raycast(encoded, view, connectivity="adaptive", compare=True)
    _, long_leaks, _ = against_the_reference(long_depth, mask, view)
    assert long_leaks > 100 and long["leaks"] == long_leaks and long["leak_pixels"]
    assert against_the_reference(adaptive_depth, mask, view)[1:] == (0, 0)
    assert adaptive["steps_26"] + adaptive["steps_6"] < six["steps_6"]
    assert adaptive["steps_6"] > 0 and adaptive["steps_26"] > 0
    assert "leaks" not in six   # 6-rays are the contract: nothing to count against


def test_proximity_band_is_the_26_dilation():
    from skimage.morphology import dilation

    rng = np.random.default_rng(0)
    mask = rng.random((9, 10, 11)) < 0.05
    assert np.array_equal(proximity_band(mask), dilation(mask, np.ones((3, 3, 3), bool)))


def test_registry_passes_connectivity(ball):
    image = render(segments.encode(ball), View(20, 30, 0, (24, 24), 1.0), "raycast", connectivity="26")
    assert image.stats["connectivity"] == "26" and image.stats["steps_6"] == 0


def test_bad_connectivity(ball):
    from voxrender.errors import InputError

    with pytest.raises(InputError):
        render_raycast(segments.encode(ball), View(size=(8, 8), scale=1.0), connectivity="8")


def test_skipping_empty_space_reaches_the_same_voxels_with_the_same_logical_steps(ball):
    """Jumps over empty space (the chessboard distance of ``empty_space``) land where the steps one by one land:
    the same hit voxels, the same counts of 26- and 6-steps, in fewer iterations."""
    from voxrender._render.raycast import _cast, empty_space

    rng = np.random.default_rng(4)
    specks = np.zeros((40, 44, 48), bool)
    specks[rng.integers(0, 40, 30), rng.integers(0, 44, 30), rng.integers(0, 48, 30)] = True
    specks[10:30, 30:34, 5:40] = True
    for mask in (np.pad(ball, 12), specks):
        for angles in ((30, 10, 0), (0, 0, 0), (90, 45, 0), (-61, 123, 17)):
            view = View(*angles, (48, 52), 0.8)
            for connectivity in ("adaptive", "26"):
                band = proximity_band(mask) if connectivity == "adaptive" else None
                stepped = _cast(mask, band, view, connectivity)
                jumped = _cast(mask, band, view, connectivity, space=empty_space(mask))
                assert np.array_equal(stepped[0], jumped[0]) and stepped[1] == jumped[1], (angles, connectivity)
                assert jumped[2] <= stepped[2]


def test_a_jump_is_the_steps_one_by_one():
    from voxrender.space.lines import Stepper

    rng = np.random.default_rng(2)
    n = 5000
    starts = rng.uniform(0, 50, (n, 3))
    ends = starts + rng.normal(0, 40, (n, 3))
    ends[:100] = starts[:100] + [30.0, 0, 0]            # along an axis
    ends[100:200] = starts[100:200] + [20.0, 20.0, 0]   # at 45 degrees
    one, other = Stepper(starts, ends), Stepper(starts, ends)
    for _ in range(4):
        six = rng.random(n) < 0.3
        one.step(np.ones(n, bool), six)
        other.step(np.ones(n, bool), six)
        one.switch(np.zeros(n, bool))
        other.switch(np.zeros(n, bool))
        taken = one.jump(rng.integers(0, 25, n))
        for k in range(25):
            other.step(k < taken, np.zeros(n, bool))
        assert np.array_equal(one.voxels, other.voxels) and (taken > 0).mean() > 0.5


def stepped_one_by_one(mask, band, view, connectivity):
    """The rays of ``_cast`` stepped by :class:`voxrender.space.lines.Stepper` one voxel at a time, every ray every
    round (no jumps, no closed forms): the hit voxel per pixel and the logical steps.  Views off the axes only
    (no ray along a face between voxel columns)."""
    from voxrender._render.raycast import _rays_of
    from voxrender.space.lines import Stepper

    rays, starts, ends, between = _rays_of(view, mask.shape)
    assert not between.any()
    stepper = Stepper(starts, ends)
    hit_voxel = np.full((view.size[0] * view.size[1], 3), -1, np.int64)
    steps = {"26": 0, "6": 0}
    going = np.ones(len(rays), bool)
    while going.any():
        voxel = stepper.voxels
        inside = np.all((voxel >= 0) & (voxel < np.array(mask.shape[::-1])), axis=1)
        x, y, z = np.where(inside[:, None], voxel, 0).T
        occupied = going & inside & mask[z, y, x]
        hit_voxel[rays[occupied]] = voxel[occupied]
        going &= inside & ~occupied
        six = {"6": going.copy(), "26": np.zeros(len(rays), bool)}.get(connectivity)
        if six is None:
            six = band[z, y, x] & going
        taken_26, taken_6 = stepper.step(going, six)
        steps["26"] += taken_26
        steps["6"] += taken_6
    return hit_voxel, steps


def small_objects(rng):
    """Random small objects in a larger empty volume: specks, a slab, a ball and a one-voxel shell, placed off
    the centre, so that most rays pass the object's box and those that meet it cross empty space first."""
    shape = tuple(int(n) for n in rng.integers(36, 60, 3))
    mask = np.zeros(shape, bool)
    corner = [int(rng.integers(2, n - 22)) for n in shape]
    z0, y0, x0 = corner
    kind = rng.integers(3)
    if kind == 0:
        mask[z0 + rng.integers(0, 20, 25), y0 + rng.integers(0, 20, 25), x0 + rng.integers(0, 20, 25)] = True
    elif kind == 1:
        mask[z0:z0 + 18, y0 + 5:y0 + 7, x0:x0 + 15] = True
    else:
        z, y, x = np.ogrid[:20, :20, :20]
        radius = np.sqrt((z - 9.5) ** 2 + (y - 9.5) ** 2 + (x - 9.5) ** 2)
        mask[z0:z0 + 20, y0:y0 + 20, x0:x0 + 20] = (radius <= 8) if rng.random() < 0.5 else np.abs(radius - 7) <= 0.5
    return mask


@pytest.mark.parametrize("seed", range(6))
def test_the_fast_rays_hit_and_step_as_the_stepper_one_by_one(seed):
    """The production cast (flat arrays, jumps over empty space and to the object's box, ways out counted in
    closed form) hits the voxels and counts the logical steps of the literal stepper taken one voxel at a time."""
    from voxrender._render.raycast import _cast, empty_space

    rng = np.random.default_rng(seed)
    mask = small_objects(rng)
    band = proximity_band(mask)
    for _ in range(3):
        alpha, beta, gamma = rng.uniform(-180, 180, 3)
        view = View(alpha, beta, gamma, (int(rng.integers(30, 50)), int(rng.integers(30, 50))),
                    float(rng.uniform(0.5, 1.6)))
        for connectivity in ("adaptive", "26", "6"):
            reference = stepped_one_by_one(mask, band, view, connectivity)
            space = empty_space(mask) if connectivity != "6" else None
            hit_voxel, steps, _ = _cast(mask, band if connectivity == "adaptive" else None, view, connectivity,
                                        space=space)
            assert np.array_equal(hit_voxel, reference[0]), (seed, view, connectivity)
            assert steps == reference[1], (seed, view, connectivity)
            assert (hit_voxel[:, 0] >= 0).any() or not mask.any()


def test_a_diagonal_line_above_its_interval_goes_up_every_step():
    """At alpha = -45 two extents are equal to rounding, and a line's error can sit at or above the top of its
    interval, where it goes up at every step (the closed form's extra case): the steps one by one agree."""
    from voxrender._render.raycast import _closed
    from voxrender.space.lines import Stepper

    rng = np.random.default_rng(3)
    n = 4000
    starts = rng.uniform(0, 40, (n, 3))
    ends = starts + rng.uniform(20, 80, (n, 1)) * View(-45, 15, 0).matrix[2]
    lines = Stepper(starts, ends)
    a, b, c = lines.extent.T
    count = rng.integers(1, 40, n)
    up_y, up_z, refused = _closed((lines.e_y, lines.e_z, a, b, c), count, wary=True)
    holds = (lines.e_y >= b - a) & (lines.e_z >= c - a) & ~refused
    above = holds & ((lines.e_y >= b) | (lines.e_z >= c))
    before = lines.q.copy()
    for k in range(40):
        lines.step(k < count, np.zeros(n, bool))
    moved = lines.q - before
    assert above.sum() > n // 10
    assert np.array_equal(moved[holds], np.stack([count, up_y, up_z], axis=1)[holds])


def test_the_bitmap_written_run_by_run_is_the_mask_packed():
    """Runs written into words directly (first and last word's bits, whole words between) give the bits of the
    mask: rows of several words, runs long and short, touching word edges; the same as the clipped path's slices
    decoded one at a time with a clip that keeps everything."""
    from voxrender._render import Clip
    from voxrender._render.raycast import Bitmap

    rng = np.random.default_rng(5)
    for nx in (1, 63, 64, 65, 128, 129, 300):
        mask = rng.random((3, 4, nx)) < 0.5
        mask[0, 0] = True                               # a row that is one run over all its words
        mask[1, 1, rng.integers(0, nx, 3)] = False      # long runs cut here and there
        mask[1, 1, :] |= np.arange(nx) % 128 < 70       # runs across word edges
        encoded = segments.encode(mask)
        words = Bitmap.of_segments(encoded).words
        packed = np.packbits(mask, axis=2, bitorder="little")
        assert np.array_equal(words.view(np.uint8)[:, :, :packed.shape[2]], packed), nx
        assert not words.view(np.uint8)[:, :, packed.shape[2]:].any()
        everything = Clip(x=(0, None))
        assert np.array_equal(Bitmap.of_segments(encoded, View(scale=1.0), everything).words, words)
