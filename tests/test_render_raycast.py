import numpy as np
import pytest

from reference import agreement, march
from voxrender import segments
from voxrender.render import render
from voxrender.render.btf import render_btf
from voxrender.render.raycast import proximity_band, render_raycast
from voxrender.view import View

VIEWS = [(31, 19, 7, 1.3), (-45, 15, 10, 2.0), (61, 119, 0, 0.7), (12, -80, 5, 2.5), (0, 0, 0, 1.0)]


def thin_shell(n=40, radius=15):
    """A sphere one voxel thick: 26-rays slip through it."""
    z, y, x = np.mgrid[:n, :n, :n] - (n - 1) / 2
    return np.abs(np.sqrt(x * x + y * y + z * z) - radius) <= 0.5


@pytest.mark.parametrize("alpha,beta,gamma,scale", VIEWS)
@pytest.mark.parametrize("connectivity", ["6", "adaptive"])
def test_6_and_adaptive_rays_meet_the_contract(ball, alpha, beta, gamma, scale, connectivity):
    view = View(alpha, beta, gamma, (40, 44), scale)
    depth, stats = render_raycast(segments.encode(ball), view, connectivity=connectivity)
    reference, _ = render_btf(segments.encode(ball), view)
    iou, close = agreement(depth, reference, tolerance=1e-4)
    assert iou >= 0.99 and close >= 0.99
    assert stats.get("leaks", 0) == 0 and stats.get("misses", 0) == 0


def test_6_rays_against_the_marcher(ball):
    depth, _ = render_raycast(segments.encode(ball), View(-45, 15, 10, (40, 44), 2.0), connectivity="6")
    iou, close = agreement(depth, march(ball, -45, 15, 10, (40, 44), 2.0), tolerance=0.03)
    assert iou >= 0.99 and close >= 0.99


def test_26_rays_leak_through_a_thin_shell_and_adaptive_does_not():
    encoded = segments.encode(thin_shell())
    view = View(30, 10, 0, (64, 64), 1.5)
    _, six = render_raycast(encoded, view, connectivity="6")
    _, long = render_raycast(encoded, view, connectivity="26")
    _, adaptive = render_raycast(encoded, view, connectivity="adaptive")
    assert long["leaks"] > 100 and long["leak_pixels"]
    assert adaptive["leaks"] == 0 and adaptive["misses"] == 0
    assert adaptive["steps_26"] + adaptive["steps_6"] < six["steps_6"]
    assert adaptive["steps_6"] > 0 and adaptive["steps_26"] > 0


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
