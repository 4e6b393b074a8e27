"""The renderer registry and protocol: records, option checks, and the recipe "add a renderer" (docs/design.md)."""

import numpy as np
import pytest

from voxrender._render import METHODS, Method, render
from voxrender._render.geometry import paint_boxes
from voxrender.errors import InputError
from voxrender.object import segments
from voxrender.pictures._picture import RenderOptions, picture
from voxrender.space.view import View


def test_registry_and_errors(ball):
    encoded = segments.encode(ball)
    assert set(METHODS) == {"ftb", "btf", "raycast", "octree-btf", "octree-ftb", "octree-sort", "zbuffer"}
    with pytest.raises(InputError, match="unknown method") as info:
        render(encoded, View(), "nope")
    assert info.value.parameter == "method"
    with pytest.raises(InputError, match="empty"):
        render(segments.encode(np.zeros((2, 2, 2), bool)), View())


def test_an_option_a_method_does_not_take_names_both(ball):
    encoded = segments.encode(ball)
    with pytest.raises(InputError, match="method 'ftb' takes no option 'connectivity'") as info:
        render(encoded, View(scale=1.0, size=(8, 8)), "ftb", connectivity="6")
    assert info.value.parameter == "connectivity"
    with pytest.raises(InputError, match="method 'btf' takes no option"):
        RenderOptions("btf", {"connectivity": "6"})
    image = render(encoded, View(30, 10, 0, (24, 24), 1.5), "raycast", connectivity="6")
    assert image.stats["connectivity"] == "6"


def test_a_pre_image_method_must_return_its_item_buffer():
    with pytest.raises(ValueError, match="item buffer"):
        Method(lambda segments, view: None, "no items", preimage=True)


def render_toy(segments, view, progress=None, clip=None, items=False, depth_offset=0.0):
    """A toy renderer written by the recipe: every voxel painted with the contract's ``paint_boxes``,
    keeping the nearest depth (a z-buffer); its item buffer is the voxel that won each pixel."""
    z, y, x = np.nonzero(segments.to_mask())
    found = paint_boxes(view, segments.shape, x, y, z)
    height, width = view.size
    depth = np.full(height * width, np.inf)
    np.minimum.at(depth, found.pixels, found.depths + depth_offset)
    depth = depth.reshape(height, width).astype(np.float32)
    stats = {"voxels": len(x), "options": {"depth_offset": depth_offset}}
    if not items:
        return depth, stats
    owner = np.full(height * width, -1)
    winner = found.depths + depth_offset == depth.ravel()[found.pixels].astype(float)
    owner[found.pixels[winner]] = found.owner[winner]
    boxes = np.stack([x, y, z, np.full(len(x), 0.5)], axis=1).astype(float)
    return depth, stats, (owner.reshape(height, width), boxes)


def test_a_toy_renderer_added_by_the_recipe(ball, monkeypatch):
    """One function and one record: render(), picture() and the pre-image path then take it like any method."""
    monkeypatch.setitem(METHODS, "toy", Method(render_toy, "a toy z-buffer", options=("depth_offset",),
                                               preimage=True, items=True))
    encoded = segments.encode(ball)
    view = View(30, 20, 0, (40, 40), 1.5)
    toy = render(encoded, view, "toy")
    assert np.array_equal(toy.depth, render(encoded, view, "btf").depth)
    shifted = render(encoded, view, "toy", depth_offset=2.0)
    assert shifted.stats["options"] == {"depth_offset": 2.0}          # options reach the method ...
    turned = render(encoded, View(30, 20, 35, (40, 40), 1.5), "toy", depth_offset=2.0)
    assert turned.stats["options"] == {"depth_offset": 2.0}           # ... on the pre-image path too
    assert turned.stats["supersample"] == 2
    result = picture(encoded, view, RenderOptions("toy", size=(40, 40), scale=1.5))
    assert result.rgb.shape == (40, 40, 3) and result.image.method == "toy"
    with pytest.raises(InputError, match="takes no option 'connectivity'"):
        render(encoded, view, "toy", connectivity="6")
