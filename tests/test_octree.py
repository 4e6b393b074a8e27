import numpy as np
import pytest

from voxrender import samples
from voxrender.errors import InputError
from voxrender.object import octree


def staircase_mask():
    """The linear-octree paper's Fig. 2 staircase as a mask."""
    return samples.staircase() > samples.SAMPLE_THRESHOLD


def test_the_papers_staircase():
    tree = octree.build(staircase_mask())
    assert octree.code_strings(octree.linear_octree(tree)) == ["0X", "10", "24", "40"]
    # Table 2's Q column: the codes of single voxels, e.g. (2, 2, 2) is 07 and (3, 1, 2) is 24.
    single = octree.build(np.pad(np.ones((1, 1, 1), bool), ((2, 1), (2, 1), (2, 1))))
    assert octree.code_strings(octree.linear_octree(single)) == ["07"]


def test_labels_follow_table_1():
    # forward-north-east (high z, high y, high x) is 0; backward-south-west (all low) is 7
    assert octree.CHILD_OFFSETS[0].tolist() == [1, 1, 1]
    assert octree.CHILD_OFFSETS[7].tolist() == [0, 0, 0]
    assert octree.CHILD_OFFSETS[1].tolist() == [0, 1, 1]  # forward-north-west: low x


@pytest.mark.parametrize("shape", [(5, 7, 9), (8, 8, 8), (3, 16, 2), (1, 1, 1)])
def test_round_trips(shape):
    mask = np.random.default_rng(sum(shape)).random(shape) < 0.6
    tree = octree.build(mask)
    assert np.array_equal(tree.to_mask(), mask)
    codes = octree.linear_octree(tree)
    assert np.array_equal(tree.linear, codes)     # from the Morton order, against the digits sorted as numbers
    assert np.array_equal(octree.codes_to_mask(codes, tree.n)[:shape[0], :shape[1], :shape[2]], mask)
    if shape == (1, 1, 1):
        assert len(codes) == mask.sum()
    else:   # in code order: as base-9 numbers (digits 0-7 and the marker X = 8), strictly increasing
        assert len(codes) > 1 and (np.diff(codes @ (9 ** np.arange(tree.n)[::-1])) > 0).all()


def test_flat_arrays_are_consistent():
    tree = octree.build(np.random.default_rng(3).random((8, 8, 8)) < 0.3)
    grey = np.flatnonzero(tree.color == octree.GREY)
    for node in grey:
        children = tree.first_child[node] + np.arange(8)
        assert (tree.level[children] == tree.level[node] + 1).all()
        half = tree.size(node) // 2
        assert np.array_equal(tree.origin[children], tree.origin[node] + octree.CHILD_OFFSETS * half)
    assert (tree.first_child[tree.color != octree.GREY] == -1).all()
    counts = tree.counts()
    assert counts["white"] + counts["black"] + counts["grey"] == len(tree.color)
    assert sum(v["grey"] for v in counts["by_level"].values()) == counts["grey"]


def test_a_vxo_keeps_the_octree_and_its_face_adjacency(tmp_path):
    from voxrender._shared.mapped import is_mapped
    from voxrender.object.pipeline import Encoded, load_segments
    from voxrender.object.segments import encode

    mask = np.random.default_rng(5).random((9, 7, 8)) < 0.4
    made = Encoded(encode(mask))
    made.save(tmp_path / "s.vxo", octree=True)
    again = load_segments(tmp_path / "s.vxo")
    assert again.has_octree and np.array_equal(again.octree().to_mask(), mask)
    built = made.octree()
    for name in ("color", "level", "origin", "first_child", "linear"):
        assert np.array_equal(getattr(again.octree(), name), getattr(built, name)), name
    assert is_mapped(again.octree().color)
    for kind in ("white_to_white", "white_to_black"):
        for stored, fresh in zip(getattr(again.octree(), kind), getattr(built, kind), strict=True):
            assert np.array_equal(stored.indptr, fresh.indptr) and np.array_equal(stored.indices, fresh.indices)
    made.save(tmp_path / "plain.vxs")
    assert not load_segments(tmp_path / "plain.vxs").has_octree
    (tmp_path / "old.vxo").write_bytes(b"PK\x03\x04 an npz of an older voxrender")
    with pytest.raises(InputError, match="older voxrender"):
        load_segments(tmp_path / "old.vxo")


def dense_build(mask):
    """The region octree built top-down from a pyramid of full and empty cells of the whole padded cube: the
    straightforward construction, the oracle of the object-sized :func:`octree.build_from_voxels`."""
    n = max(0, int(np.ceil(np.log2(max(mask.shape)))))
    side = 1 << n
    padded = np.zeros((side, side, side), bool)
    padded[:mask.shape[0], :mask.shape[1], :mask.shape[2]] = mask
    full, occupied = [padded], [padded]
    for _ in range(n):
        full.insert(0, _halve(full[0], np.logical_and))
        occupied.insert(0, _halve(occupied[0], np.logical_or))
    colors, levels, origins, firsts = [], [], [], []
    cells, start = np.zeros((1, 3), np.int64), 0
    for k in range(n + 1):
        x, y, z = cells.T
        color = np.where(full[k][z, y, x], octree.BLACK, np.where(~occupied[k][z, y, x], octree.WHITE, octree.GREY))
        grey = np.flatnonzero(color == octree.GREY)
        first = np.full(len(cells), -1, np.int64)
        first[grey] = start + len(cells) + 8 * np.arange(len(grey))
        colors.append(color)
        levels.append(np.full(len(cells), k))
        origins.append(cells << (n - k))
        firsts.append(first)
        start += len(cells)
        cells = (2 * cells[grey][:, None, :] + octree.CHILD_OFFSETS[None]).reshape(-1, 3)
        if not len(cells):
            break
    return [np.concatenate(part) for part in (colors, levels, origins, firsts)]


def _halve(cells, combine):
    cells = combine(cells[0::2], cells[1::2])
    cells = combine(cells[:, 0::2], cells[:, 1::2])
    return combine(cells[:, :, 0::2], cells[:, :, 1::2])


@pytest.mark.parametrize("seed", range(6))
def test_the_object_sized_build_equals_the_dense_one(seed):
    from voxrender.object.segments import encode

    rng = np.random.default_rng(seed)
    shape = tuple(rng.integers(1, 19, 3))
    mask = rng.random(shape) < [0.0, 0.05, 0.4, 0.8, 0.97, 1.0][seed]
    mask[: shape[0] // 2, : shape[1] // 2, : shape[2] // 2] = seed % 2           # solid blocks merge
    expected = dense_build(mask)
    for tree in (octree.build(mask), octree.build_from_segments(encode(mask))):
        found = [tree.color, tree.level, tree.origin, tree.first_child]
        assert all(np.array_equal(a, b) for a, b in zip(found, expected, strict=True))


def _leaf_labels(tree):
    side = 1 << tree.n
    labels = np.full((side, side, side), -1, np.int64)   # [x, y, z]
    for node in np.flatnonzero(tree.first_child < 0):
        x, y, z = tree.origin[node]
        s = 1 << (tree.n - int(tree.level[node]))
        labels[x:x + s, y:y + s, z:z + s] = node
    return labels


def test_leaf_pairs_are_the_face_adjacent_leaves():
    rng = np.random.default_rng(7)
    for _ in range(5):
        mask = rng.random(tuple(rng.integers(2, 12, 3))) < rng.uniform(0.1, 0.9)
        mask[:3, :3, :3] = rng.random() < 0.5
        tree = octree.build(mask)
        labels = _leaf_labels(tree)
        for axis, (low, high) in enumerate(tree.leaf_pairs):
            a = np.moveaxis(labels, axis, 0)
            expected = {(int(p), int(q)) for p, q in zip(a[:-1].ravel(), a[1:].ravel(), strict=True) if p != q}
            assert set(zip(low.tolist(), high.tolist(), strict=True)) == expected


def test_parents_and_white_adjacency():
    rng = np.random.default_rng(8)
    tree = octree.build(rng.random((9, 7, 8)) < 0.4)
    children = tree.first_child[tree.first_child >= 0][:, None] + np.arange(8)
    assert np.all(tree.parent[children] == np.flatnonzero(tree.first_child >= 0)[:, None])
    assert tree.parent[0] == -1
    white = tree.white_leaves
    assert np.all((tree.color[white] == octree.WHITE) & (tree.first_child[white] < 0))
    for direction in range(6):
        axis, high = divmod(direction, 2)
        low_leaves, high_leaves = tree.leaf_pairs[axis]
        source, target = (low_leaves, high_leaves) if high else (high_leaves, low_leaves)
        for color, matrix, names in ((octree.WHITE, tree.white_to_white[direction], white),
                                     (octree.BLACK, tree.white_to_black[direction], np.arange(len(tree.color)))):
            keep = (tree.color[source] == octree.WHITE) & (tree.color[target] == color)
            rows = np.repeat(np.arange(len(matrix.indptr) - 1), np.diff(matrix.indptr))
            cols = matrix.indices
            assert set(zip(white[rows].tolist(), names[cols].tolist(), strict=True)) == \
                set(zip(source[keep].tolist(), target[keep].tolist(), strict=True))


def test_a_vxo_with_a_missing_or_mismatched_octree_section_is_bad_input(tmp_path):
    """Found by the fuzzing gate: a .vxo whose header lacks an octree section ended in a KeyError (exit 1)."""
    from voxrender.object.pipeline import load_segments
    from voxrender.object.segments import encode
    from voxrender.object.vxs import save

    segments = encode(samples.sphere(12) > samples.SAMPLE_THRESHOLD)
    arrays = octree.sections(octree.build_from_segments(segments))
    save(segments, tmp_path / "whole.vxo", arrays)
    assert load_segments(tmp_path / "whole.vxo").has_octree
    save(segments, tmp_path / "lacking.vxo", {k: v for k, v in arrays.items() if k != "octree_first_child"})
    with pytest.raises(InputError, match="damaged .vxo file: its section octree_first_child is missing"):
        load_segments(tmp_path / "lacking.vxo")
    save(segments, tmp_path / "short.vxo", {**arrays, "octree_level": arrays["octree_level"][:-1]})
    with pytest.raises(InputError, match="do not fit together"):
        load_segments(tmp_path / "short.vxo")


@pytest.mark.parametrize("section", [name for name in octree._SECTIONS if name != "octree_n"])
def test_a_vxo_with_a_value_out_of_range_in_any_section_is_bad_input(tmp_path, section):
    """A .vxo whose octree arrays fit together but hold a damaged value (a colour, a child, an origin, a digit or
    an adjacency row out of range) sent the octree renderers indexing out of their tables (exit 1)."""
    from voxrender.object.pipeline import load_segments
    from voxrender.object.segments import encode
    from voxrender.object.vxs import save

    segments = encode(samples.sphere(12) > samples.SAMPLE_THRESHOLD)
    arrays = octree.sections(octree.build_from_segments(segments))
    damaged = arrays[section].copy()
    damaged[len(damaged) // 2] = np.iinfo(damaged.dtype).max
    save(segments, tmp_path / "damaged.vxo", {**arrays, section: damaged})
    with pytest.raises(InputError, match="damaged .vxo file: its octree holds values out of range"):
        load_segments(tmp_path / "damaged.vxo")
