"""The public face: ``import voxrender`` and the names a script needs, imported on first use."""

import subprocess
import sys

import numpy as np
import pytest

import voxrender
from voxrender.errors import InputError


def test_every_public_name_resolves_to_what_its_module_defines():
    import importlib

    for name in voxrender.__all__:
        value = getattr(voxrender, name)
        if name != "__version__":
            module = importlib.import_module(voxrender._PUBLIC[name], "voxrender")
            assert value is getattr(module, name), name
    assert set(voxrender.__all__) <= set(dir(voxrender))
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        _ = voxrender.nothing


def test_import_voxrender_loads_no_module_until_a_name_is_used():
    code = ("import sys, voxrender; print(sorted(m for m in sys.modules if m.startswith('voxrender') "
            "or m in ('numpy', 'click', 'skimage', 'scipy')))")
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True).stdout.strip() == "['voxrender']"


def ball(n=24, radius=9):
    zz, yy, xx = np.mgrid[:n, :n, :n]
    return (xx - (n - 1) / 2) ** 2 + (yy - (n - 1) / 2) ** 2 + (zz - (n - 1) / 2) ** 2 <= radius ** 2


def test_snapshot_of_grey_values_a_mask_and_a_file_give_the_same_picture(tmp_path):
    grey = np.where(ball(), 1000, 0).astype(np.int16)
    np.save(tmp_path / "ball.npy", grey)
    from_grey = voxrender.snapshot(grey, threshold=500, size=(48, 48))
    assert from_grey.shape == (48, 48, 3) and from_grey.dtype == np.uint8
    assert from_grey[24, 24].any() and not from_grey[0, 0].any()
    np.testing.assert_array_equal(voxrender.snapshot(ball(), size=(48, 48)), from_grey)
    np.testing.assert_array_equal(voxrender.snapshot(tmp_path / "ball.npy", threshold=500, size=(48, 48)), from_grey)
    assert voxrender.snapshot(grey, size=(48, 48)).any()          # Otsu's threshold by default


def test_snapshot_views_and_spacing():
    grey = np.where(ball(), 1000, 0).astype(np.int16)
    grey[:, :, :6] = 0                                             # the ball without its x < 6 cap: not symmetric
    left = voxrender.snapshot(grey, threshold=500, view="left", size=(48, 48))
    np.testing.assert_array_equal(voxrender.snapshot(grey, threshold=500, view=(90, 90, 0), size=(48, 48)), left)
    np.testing.assert_array_equal(
        voxrender.snapshot(grey, threshold=500, view=voxrender.View(90, 90, size=(48, 48)), size=(8, 8)), left)
    assert not np.array_equal(voxrender.snapshot(grey, threshold=500, view="right", size=(48, 48)), left)
    def extent(rgb):                                                # (rows, columns) the object covers
        return tuple(int(np.count_nonzero(rgb.any(axis=(2, axis)))) for axis in (1, 0))

    cubic = extent(voxrender.snapshot(grey, threshold=500, view="anterior", size=(64, 64), scale=1.0))
    # slices 0.5 mm apart: resampled to 0.5 mm voxels, so at a pixel a voxel the picture is twice as wide
    squashed = extent(voxrender.snapshot(grey, threshold=500, spacing=(1, 1, 0.5), view="anterior", size=(64, 64),
                                         scale=1.0))
    assert abs(squashed[0] - cubic[0]) <= 1 and abs(squashed[1] - 2 * cubic[1]) <= 2, (cubic, squashed)


def test_snapshot_of_labels_colours_each_label():
    labels = np.zeros((24, 24, 24), np.uint8)
    labels[4:12, 4:20, 4:20] = 1
    labels[12:20, 4:20, 4:20] = 2
    rgb = voxrender.snapshot(labels, labels=True, view="anterior", size=(48, 48), scale=2.0)
    top, bottom = rgb[14, 24], rgb[34, 24]                          # z grows upward: label 2 at the top
    assert top.any() and bottom.any() and not np.array_equal(top // 16, bottom // 16)
    only_two = voxrender.snapshot(labels, labels=[2], view="anterior", size=(48, 48), scale=2.0)
    assert only_two[14, 24].any() and not only_two[34, 24].any()
    grey = np.where(labels > 0, 1000, 0).astype(np.int16)
    paired = voxrender.snapshot(grey, labels=labels, view="anterior", size=(48, 48), scale=2.0)
    np.testing.assert_array_equal(paired, rgb)


@pytest.mark.parametrize("call, parameter", [
    (lambda: voxrender.snapshot(np.zeros((4, 4)), threshold=1), "source"),
    (lambda: voxrender.snapshot(ball(), view="sideways"), "view"),
    (lambda: voxrender.snapshot(ball(), view=(1, 2)), "view"),
    (lambda: voxrender.snapshot(ball(), method="magic"), "method"),
    (lambda: voxrender.snapshot(ball(), spacing=(1, 0, 1)), "spacing"),
    (lambda: voxrender.snapshot(ball(), labels=np.zeros((3, 3, 3), np.uint8)), "labels_from"),
])
def test_snapshot_errors_name_the_parameter(call, parameter):
    with pytest.raises(InputError) as caught:
        call()
    assert caught.value.parameter == parameter


def test_snapshot_takes_the_voxel_types_a_file_may_hold():
    mask = ball()
    np.testing.assert_array_equal(voxrender.snapshot(mask.astype(np.float16) * 1000, threshold=500, size=(32, 32)),
                                  voxrender.snapshot(mask, size=(32, 32)))
    with pytest.raises(InputError, match="the source array holds complex128 values"):
        voxrender.snapshot(mask.astype(complex))


def test_render_and_picture_take_what_load_segments_gives_and_use_its_octree(tmp_path):
    """The module docstring's steps, with the encoded object itself (it was ``.segments`` or an AttributeError)."""
    np.save(tmp_path / "ball.npy", np.where(ball(), 1000, 0).astype(np.int16))
    encoded = voxrender.load_segments(tmp_path / "ball.npy", prepare=voxrender.PrepOptions(threshold=500))
    view = voxrender.View(30, 20, size=(32, 32), scale=1.0)
    assert not encoded.has_octree
    image = voxrender.render(encoded, view, method="octree-ftb")
    assert encoded.has_octree                                       # built once, kept for the next picture
    np.testing.assert_array_equal(image.depth, voxrender.render(encoded.segments, view, method="octree-ftb").depth)
    options = voxrender.RenderOptions(method="octree-btf")
    np.testing.assert_array_equal(voxrender.picture(encoded, view, options).rgb,
                                  voxrender.picture(encoded.segments, view, options).rgb)
