"""Projections (MIP, MinIP, mean) against an independent reference: one ray at a time, sampled densely with
nearest-neighbour look-ups."""

import numpy as np
import pytest

from voxrender._render import Clip
from voxrender.errors import InputError
from voxrender.pictures._project import PROJECTIONS, depth_range, project
from voxrender.space.view import View

SAMPLES_PER_VOXEL = 256


def reference(values, view, shape=None, step=(1.0, 1.0, 1.0), clip=None, slab=None):
    """Max, min and mean of each pixel's ray (``(3, H, W)``, NaN where it keeps no voxel) and, per pixel, the
    ray's points inside the limits: samples every 1/256 voxel along the whole line, each the input voxel
    nearest to it (``round(q)``)."""
    shape = values.shape if shape is None else shape
    nz, ny, nx = shape
    step = np.asarray(step, float)
    reach = np.sqrt(float(sum(n * n for n in shape))) / 2 + 1
    t = np.arange(-reach, reach, 1 / SAMPLES_PER_VOXEL)
    r = view.matrix
    centre = np.array([(nx - 1) / 2, (ny - 1) / 2, (nz - 1) / 2])
    height, width = view.size
    out = np.full((3, height, width), np.nan)
    kept = {}
    for row in range(height):
        for column in range(width):
            x_, y_ = (float(v[0]) for v in view.pixel_centres(np.array([column]), np.array([row])))
            p = centre + x_ * r[0] + y_ * r[1] + t[:, None] * r[2]          # object points on the ray
            q = p * step
            inside = np.all((q >= -0.5) & (q <= np.array(values.shape[::-1]) - 0.5), axis=1)
            if clip is not None:
                for k, bounds in enumerate((clip.x, clip.y, clip.z)):
                    if bounds is not None and bounds[0] is not None:
                        inside &= p[:, k] >= bounds[0] - 0.5
                    if bounds is not None and bounds[1] is not None:
                        inside &= p[:, k] < bounds[1] - 0.5
                if clip.cut_depth is not None:
                    inside &= t >= clip.cut_depth
            if slab is not None:
                inside &= (t >= slab[0]) & (t <= slab[1])
            index = np.round(q[inside]).astype(int)
            found = values[index[:, 2], index[:, 1], index[:, 0]].astype(float)
            found = found[np.isfinite(found)]                 # NaN and infinite voxels are not counted
            if found.size:
                out[:, row, column] = found.max(), found.min(), found.mean()
                kept[row, column] = q[inside]
    return out, kept


def near_values(values, points, tolerance=1e-3):
    """The values of the voxels whose boxes come within ``tolerance`` of the line through ``points`` (between
    its first and last point): the slab test on each voxel near it."""
    start, end = points[0], points[-1]
    direction = end - start
    low = np.floor(np.minimum(start, end) - 1).astype(int)
    high = np.ceil(np.maximum(start, end) + 1).astype(int)
    found = set()
    for z in range(max(low[2], 0), min(high[2], values.shape[0] - 1) + 1):
        for y in range(max(low[1], 0), min(high[1], values.shape[1] - 1) + 1):
            for x in range(max(low[0], 0), min(high[0], values.shape[2] - 1) + 1):
                box_low = np.array([x, y, z]) - 0.5 - tolerance
                box_high = np.array([x, y, z]) + 0.5 + tolerance
                enter, leave = 0.0, 1.0
                for k in range(3):
                    if abs(direction[k]) < 1e-15:
                        if not box_low[k] <= start[k] <= box_high[k]:
                            enter = 2.0
                        continue
                    a, b = (box_low[k] - start[k]) / direction[k], (box_high[k] - start[k]) / direction[k]
                    enter, leave = max(enter, min(a, b)), min(leave, max(a, b))
                if enter <= leave:
                    found.add(float(values[z, y, x]))
    return found


def check(values, view, **limits):
    """``project`` agrees with the reference: the same pixels covered; the maximum and minimum the same at
    99.5 % of them, and at the rest a voxel the ray passes within 1e-3 of; the mean within 0.2 % of the range."""
    expected, kept = reference(values, view, **limits)
    got = np.stack([project(values, view, mode, **limits) for mode in PROJECTIONS])
    covered = np.isfinite(expected[0])
    assert covered.any() and (~covered).any() or limits.get("slab") is not None or covered.all()
    np.testing.assert_array_equal(np.isfinite(got[0]), covered)
    for k in range(2):
        wrong = np.argwhere(covered & (got[k] != expected[k]))
        assert len(wrong) <= 0.005 * covered.sum(), (PROJECTIONS[k], len(wrong), covered.sum())
        for row, column in wrong:
            assert got[k, row, column] in near_values(values, kept[row, column])
    # the reference's mean is off by up to a sample's share at either end of the kept part of the ray
    spread = float(np.ptp(values[np.isfinite(values)].astype(float)))
    samples = np.array([len(kept[row, column]) for row, column in np.argwhere(covered)])
    assert np.all(np.abs(got[2][covered] - expected[2][covered]) <= spread * (0.002 + 2 / samples))
    return got


@pytest.fixture
def volume():
    return np.random.default_rng(23).integers(0, 1000, size=(9, 11, 13)).astype(np.int16)


@pytest.mark.parametrize("angles", [(90, 0, 0), (0, 180, 0), (30, 10, 0), (-45, 15, 0),
                                    (60, 120, 25), (17, -73, 200)])
def test_agrees_with_the_reference(volume, angles):
    check(volume, View(*angles, size=(28, 32), scale=1.77))   # no ray runs along a face


def test_agrees_on_another_grid_with_clip_cut_and_slab(volume):
    values = volume[:, :, :8].astype(np.float32)
    # object voxels 1.5 input voxels along x, 0.8 along z: the object grid is 5 x 11 x 11
    limits = {"shape": (11, 11, 5), "step": (1.5, 1.0, 0.8)}
    view = View(35, -20, 10, size=(18, 18), scale=1.1)
    check(values, view, **limits)
    check(values, view, **limits, clip=Clip(x=(1, 4), z=(2, None), cut_depth=-1.5))
    check(values, view, **limits, slab=(-2.0, 1.5))
    check(values, View.preset("left", size=(16, 16), scale=0.9), **limits, clip=Clip(y=(3, 9), cut_depth=-1.2),
          slab=(-3.0, 2.5))


def test_non_finite_voxels_are_ignored(volume):
    values = volume.astype(float)
    values[4, :, :] = np.nan
    values[:, 5, 2:] = np.inf
    values[:, 1:, 6] = -np.inf
    values[2:, 1:, 1:5] = np.nan          # some rays meet nothing else: NaN
    view = View(30, 10, 0, size=(16, 16), scale=1.2)
    got = check(values, view)
    assert np.isfinite(got).all(axis=0).sum() > 50
    check(values, View(90, 0, 0, size=(16, 16), scale=1.2))
    # a volume of nothing but NaN: every pixel is NaN
    for mode in PROJECTIONS:
        assert np.isnan(project(np.full((3, 3, 3), np.nan), view, mode)).all()


def test_anterior_mip_is_the_max_over_y(volume):
    """Anterior (alpha 90): X' is x, Y' is -z (the head up), the viewer looks along +y."""
    nz, ny, nx = volume.shape
    view = View.preset("anterior", size=(nz, nx), scale=1.0)
    np.testing.assert_array_equal(project(volume, view, "mip"), volume.max(axis=1)[::-1, :])
    np.testing.assert_array_equal(project(volume, view, "minip"), volume.min(axis=1)[::-1, :])
    np.testing.assert_allclose(project(volume, view, "mean"), volume.mean(axis=1)[::-1, :], rtol=1e-6)


def test_reads_a_memory_map_without_copying(tmp_path, volume):
    path = tmp_path / "v.npy"
    np.save(path, volume)
    mapped = np.load(path, mmap_mode="r")
    view = View(30, 10, 0, size=(16, 16), scale=1.0)
    np.testing.assert_array_equal(project(mapped, view), project(volume, view))


def test_depth_range():
    assert depth_range(View(alpha=90), (4, 6, 8)) == (-3.0, 3.0)
    low, high = depth_range(View(30, 10, 5), (9, 11, 13))
    assert low == -high and 6.5 < high < np.sqrt(9 ** 2 + 11 ** 2 + 13 ** 2) / 2


@pytest.mark.parametrize("call, parameter", [
    (lambda v: project(v, View(scale=1.0), "max"), "projection"),
    (lambda v: project(v, View()), "scale"),
    (lambda v: project(v, View(scale=1.0), slab=(2.0, 1.0)), "slab"),
    (lambda v: project(v, View(scale=1.0), slab=(0.0, np.inf)), "slab"),
    (lambda v: project(v, View(scale=1.0), step=(1.0, 0.0, 1.0)), "step"),
    (lambda v: project(v[0], View(scale=1.0)), "values"),
])
def test_bad_input(volume, call, parameter):
    with pytest.raises(InputError) as caught:
        call(volume)
    assert caught.value.parameter == parameter


def test_long_volumes_along_any_axis(monkeypatch):
    """Rays along z run through 70 layers, in two runs of faces on two threads, the same as in one; rays along x
    read their layers in blocks (x is next to x in memory)."""
    import voxrender.pictures._project_rays as module

    values = np.random.default_rng(3).integers(-500, 500, size=(70, 6, 5)).astype(np.int16)
    view = View(8, -6, 30, size=(10, 10), scale=1.0)
    monkeypatch.setattr(module, "THREADS", 2)
    two = check(values, view)
    monkeypatch.setattr(module, "THREADS", 1)
    np.testing.assert_array_equal(project(values, view), two[0])
    check(np.ascontiguousarray(values.transpose(1, 2, 0)), View(90, 80, 10, size=(10, 10), scale=1.0))


def test_views_of_arrays_are_read_in_place(volume):
    """A transposed, flipped and cropped view of an array (as the canonical frame and a crop make them) gives
    what its copy gives."""
    seen = np.flip(volume.transpose(2, 0, 1), axis=1)[1:, :, 2:-1]
    for angles in ((30, 10, 0), (90, 0, 0), (10, 80, 0), (60, 120, 25)):
        view = View(*angles, size=(16, 16), scale=1.0)
        for mode in PROJECTIONS:
            np.testing.assert_array_equal(project(seen, view, mode), project(np.ascontiguousarray(seen), view, mode))


@pytest.mark.parametrize("shape", [(1, 5, 6), (4, 1, 7), (1, 1, 1)])
def test_volumes_one_voxel_thick(shape):
    values = np.random.default_rng(1).integers(0, 9, size=shape).astype(np.uint8)
    check(values, View(10, 80, 20, size=(14, 14), scale=1.7))


def test_a_mask_projects(volume):
    mask = volume > 700
    check(mask, View(0, 0, 0, size=(14, 14), scale=1.7), clip=Clip(x=(2, 5), cut_depth=0.3))
    assert np.isnan(project(mask, View(30, 10, 0, size=(8, 8), scale=1.0), slab=(100.0, 101.0))).all()


def skull(rng, shape=(40, 36, 44)):
    """A bright shell (bone) inside dim noise, air around it: the structure the skipping is for."""
    z, y, x = np.indices(shape)
    centre = (np.array(shape) - 1) / 2
    r = np.sqrt(sum(((k - c) / (n / 2)) ** 2 for k, c, n in zip((z, y, x), centre, shape, strict=True)))
    values = rng.normal(40, 15, shape)
    values[r > 0.8] = -1000
    shell = (r > 0.65) & (r <= 0.8)
    values[shell] = rng.normal(1200, 300, shell.sum())
    return values.astype(np.int16)


def every_face(monkeypatch, values, view, mode, **limits):
    """The projection without skipping: every ray across every face (the path the skipping must equal)."""
    import voxrender.pictures._project as module

    with monkeypatch.context() as patch:
        patch.setattr(module, "_SKIP", False)
        return project(values, view, mode, **limits)


@pytest.mark.parametrize("seed", range(6))
def test_skipping_changes_nothing(monkeypatch, seed):
    """The maximum and minimum with the blocks skipped are those of every face, bit for bit: random views,
    clip limits, cut depth, slab, another grid, NaN voxels, and the slice buffers or the voxels read straight."""
    import voxrender.pictures._project_skip as module

    rng = np.random.default_rng(seed)
    values = skull(rng)
    if seed % 3 == 2:
        values = values.astype(np.float32)
        values[rng.random(values.shape) < 0.02] = np.nan
        values[5:9, :, :] = np.nan
    view = View(*rng.uniform(-180, 180, 3), size=(40, 44), scale=rng.uniform(0.8, 1.3))
    limits = [{}, {"clip": Clip(x=(3, 38), y=(2, None), cut_depth=-6.0)}, {"slab": (-9.0, 12.0)},
              {"shape": (40, 36, 22), "step": (2.0, 1.0, 1.0)}][seed % 4]
    monkeypatch.setattr(module, "BLOCK_FACES", 4)           # several blocks across these small volumes
    monkeypatch.setattr(module, "PAIRS_PER_PIXEL", [(0, 0), (10 ** 9, 10 ** 9), (20, 20)][seed % 3])
    for mode in ("mip", "minip"):
        np.testing.assert_array_equal(project(values, view, mode, **limits),
                                      every_face(monkeypatch, values, view, mode, **limits))


def test_block_bounds_are_bounds():
    """Each ray's bound of a block is above (for the minimum, below) every voxel it meets at the block's faces."""
    import voxrender.pictures._project_rays as rays_module
    import voxrender.pictures._project_skip as module

    rng = np.random.default_rng(5)
    values = skull(rng)
    for angles in ((30, 10, 0), (-115.6, 50.4, 0), (70, -20, 33)):
        view = View(*angles, size=(40, 44), scale=1.0)
        rays = rays_module.Rays(values.shape, view, values.shape, np.ones(3), None, None)
        layers = rays_module.Layers(values, rays)
        faces = range(int(layers.first.min()) + 1, int(layers.last.max()) + 1)
        blocks = [range(max(j - 1, faces.start), min(j + 5, faces.stop)) for j in range(faces.start, faces.stop, 5)]
        paths = module.Paths(values, rays, layers)
        for mode, fold in (("mip", np.maximum), ("minip", np.minimum)):
            bounds = module.block_bounds(values, rays, layers, mode, blocks)
            for k, block in enumerate(blocks):
                met = np.full(rays.count, rays_module.ignored(mode, values.dtype))
                module.fold_pairs(paths, mode, met, block, np.arange(rays.count))
                assert np.all(fold(bounds[k], met) == bounds[k])
            # and not a loose one: below the shell's values where the ray meets only air or the noise inside it
            assert mode == "minip" or np.mean(bounds < 1000) > 0.3
