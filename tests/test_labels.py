"""Label images: every method gives the contract's label image; labels round-trip through the store."""

import numpy as np
import pytest
from conftest import data_path
from reference import exact_labels

from voxrender._render import METHODS, Clip, render
from voxrender._shared.mapped import is_mapped
from voxrender.object import segments, vxs
from voxrender.object.segments import label_at
from voxrender.pictures.labels import label_image, label_pixels
from voxrender.space.view import View, angles_from_vpn

SIZE = (40, 44)
OPTIONS = {"raycast": {"connectivity": "6"}}       # the discrete rays that keep the contract (test_contract.py)
VIEWS = [(31, 19, 0, 1.3), (0, 0, 0, 1.0), (90, 0, 0, 2.0), (*angles_from_vpn((1, -2, 1)), 1.4), (-45, 15, 10, 2.0),
         (12, -80, 5, 2.5)]


def nested():
    """Three labels: a ball (2) holding a smaller ball (1) that pokes out of it, and a box (3) touching both."""
    z, y, x = np.indices((16, 18, 20))
    labels = np.zeros((16, 18, 20), np.uint16)
    labels[(x - 8) ** 2 + (y - 9) ** 2 + (z - 8) ** 2 <= 36] = 2
    labels[(x - 10) ** 2 + (y - 7) ** 2 + (z - 6) ** 2 <= 9] = 1
    labels[(x >= 12) & (x < 18) & (y >= 3) & (y < 15) & (z >= 5) & (z < 11)] = 3
    return labels


def test_encode_labels_keeps_one_label_per_run_and_the_union():
    labels = nested()
    s = segments.encode_labels(labels)
    assert np.array_equal(s.to_mask(), labels > 0)
    z, y, x = np.nonzero(np.ones(labels.shape, bool))
    assert np.array_equal(label_at(s, x, y, z).reshape(labels.shape), labels)
    assert len(s.labels) == s.segment_count and s.segment_count > segments.encode(labels > 0).segment_count


@pytest.mark.parametrize("alpha,beta,gamma,scale", VIEWS)
@pytest.mark.parametrize("method", sorted(METHODS))
def test_every_method_gives_the_contracts_label_image(method, alpha, beta, gamma, scale):
    labels = nested()
    s = segments.encode_labels(labels)
    view = View(alpha, beta, gamma, SIZE, scale)
    image = render(s, view, method, **OPTIONS.get(method, {}))
    found = label_image(s, image)
    expected = exact_labels(labels, alpha, beta, gamma, SIZE, scale, middle=image.view.centre)
    # where a method's depth keeps the contract (all pixels but its documented exceptions: test_contract.py),
    # the label is the contract's
    same_depth = np.isclose(image.depth, exact_depth := _depth(labels, image.view), atol=1e-5) | \
        (np.isinf(image.depth) & np.isinf(exact_depth))
    assert same_depth.mean() > 0.99
    assert np.array_equal(found[same_depth], expected[same_depth])
    assert set(np.unique(found)) <= {0, 1, 2, 3} and {2, 3} <= set(np.unique(found))


def _depth(labels, view):
    from reference import exact

    return exact(labels > 0, view.alpha, view.beta, view.gamma, view.size, view.scale, middle=view.centre)


@pytest.mark.parametrize("alpha,beta,gamma,scale", VIEWS[:4])
def test_all_methods_give_the_same_label_image(alpha, beta, gamma, scale):
    s = segments.encode_labels(nested())
    view = View(alpha, beta, gamma, SIZE, scale)
    found = {m: label_image(s, render(s, view, m, **OPTIONS.get(m, {}))) for m in METHODS}
    for method, image in found.items():
        assert np.array_equal(image, found["btf"]), method


def test_each_labels_pixels_are_a_render_of_that_label_alone():
    s = segments.encode_labels(nested())
    view = View(31, 19, 0, SIZE, 1.3)
    union = render(s, view)
    labels = label_image(s, union)
    alone = {label: render(s.only(label), union.view).depth for label in (1, 2, 3)}
    for label, depth in alone.items():
        shown = labels == label
        assert shown.any() or label == 1
        assert np.array_equal(union.depth[shown], depth[shown])                     # where it is the nearest
        others = np.min([d for k, d in alone.items() if k != label], axis=0)
        strictly_nearest = np.isfinite(depth) & (depth < others - 1e-6)
        assert (labels[strictly_nearest] == label).all()


def test_a_tie_goes_to_the_smaller_label():
    """Pixel column 2's ray runs along the face between voxels x = 1 and x = 2 (View: X' = 0 there)."""
    for left, right in ((5, 2), (2, 5)):
        labels = np.zeros((1, 1, 4), np.uint16)
        labels[0, 0, :2], labels[0, 0, 2:] = left, right
        s = segments.encode_labels(labels)
        image = render(s, View(size=(5, 5), scale=1.0, centre=(0.0, 0.0)))
        assert label_image(s, image)[2].tolist()[1:4] == [left, 2, right]
        assert exact_labels(labels, 0, 0, 0, (5, 5), 1.0)[2].tolist()[1:4] == [left, 2, right]


def test_clipped_voxels_show_no_label():
    labels = nested()
    s = segments.encode_labels(labels)
    view = View(0, 90, 0, SIZE, 1.5)               # looking along x: the box (x >= 12) in front
    clip = Clip(x=(None, 12))
    image = render(s, view, clip=clip)
    found = label_image(s, image, clip)
    assert 3 not in found and 2 in found
    kept = labels * (np.indices(labels.shape)[2] < 12)
    assert np.array_equal(found, exact_labels(kept, 0, 90, 0, SIZE, 1.5, middle=image.view.centre))


def test_label_pixels_count_the_label_image():
    s = segments.encode_labels(nested())
    labels = label_image(s, render(s, View(31, 19, 0, SIZE, 1.3)))
    counts = label_pixels(labels)
    assert sum(counts.values()) == int((labels > 0).sum()) and counts == {
        int(v): int((labels == v).sum()) for v in np.unique(labels) if v}


def test_the_store_round_trips_labels_and_colours(tmp_path):
    table = {"3": {"name": "box", "colour": [200, 50, 50]}}
    s = segments.encode_labels(nested(), meta={"labels": [1, 2, 3], "label_table": table})
    vxs.save(s, tmp_path / "l.vxs")
    loaded = vxs.load(tmp_path / "l.vxs")
    assert np.array_equal(loaded.labels, s.labels) and is_mapped(loaded.labels)
    assert loaded.meta["label_table"] == table
    assert np.array_equal(loaded.starts, s.starts) and np.array_equal(loaded.offsets, s.offsets)
    single = segments.encode(nested() > 0)
    vxs.save(single, tmp_path / "one.vxs")
    assert vxs.load(tmp_path / "one.vxs").labels is None          # single objects stay as they are


def test_a_damaged_label_section_is_refused(tmp_path):
    from voxrender.errors import InputError

    s = segments.encode_labels(nested())
    s.labels = s.labels[:-1]
    vxs.save(s, tmp_path / "bad.vxs")
    with pytest.raises(InputError, match="runs and labels disagree"):
        vxs.load(tmp_path / "bad.vxs")


def test_only_picks_labels_as_one_object():
    labels = nested()
    s = segments.encode_labels(labels)
    for chosen in (1, 3, (1, 3)):
        part = s.only(chosen)
        assert part.labels is None and np.array_equal(part.to_mask(), np.isin(labels, chosen))


def test_head_label_map_renders_three_colours_each_its_single_label_render():
    """vhf_head split by HU (bone, soft tissue, airway), cut open: three labels, each where it is nearest."""
    from voxrender.io import read_volume
    from voxrender.object.prep import label_map
    from voxrender.samples import tissue_labels

    volume = read_volume(data_path("vhf_head"))
    volume.values = tissue_labels(volume.values)
    labels, _ = label_map(volume, voxel=2.0)
    s = segments.encode_labels(labels)
    clip = Clip(x=(None, labels.shape[2] // 2))
    union = render(s, View(*angles_from_vpn((1, -0.4, 0.3)), size=(160, 160)), clip=clip)
    found = label_image(s, union, clip)
    counts = label_pixels(found)
    assert set(counts) == {1, 2, 3} and min(counts.values()) > 20
    for label in (1, 2, 3):
        alone = render(s.only(label), union.view, clip=clip).depth
        shown = found == label
        assert np.array_equal(union.depth[shown], alone[shown])
