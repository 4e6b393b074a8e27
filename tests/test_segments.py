import numpy as np
import pytest

from voxrender import segments
from voxrender.errors import InputError


@pytest.mark.parametrize("seed", range(5))
def test_round_trip_random_masks(seed):
    rng = np.random.default_rng(seed)
    mask = rng.random((7, 9, 13)) < rng.uniform(0.1, 0.9)
    encoded = segments.encode(mask)
    assert np.array_equal(encoded.to_mask(), mask)
    assert encoded.voxel_count == mask.sum()


def test_runs_are_sorted_inclusive_and_separated():
    rng = np.random.default_rng(9)
    mask = rng.random((4, 5, 40)) < 0.5
    encoded = segments.encode(mask)
    for z in range(4):
        for y in range(5):
            starts, ends = encoded.row(z, y)
            assert np.all(starts <= ends)
            assert np.all(starts[1:] > ends[:-1] + 1)  # runs never touch
            line = np.zeros(40, bool)
            for s, e in zip(starts, ends, strict=True):
                line[s:e + 1] = True
            assert np.array_equal(line, mask[z, y])


def test_full_rows_and_edges():
    mask = np.zeros((2, 3, 5), bool)
    mask[0, 0] = True
    mask[1, 2, 0] = mask[1, 2, 4] = True
    encoded = segments.encode(mask)
    assert [a.tolist() for a in encoded.row(0, 0)] == [[0], [4]]
    assert [a.tolist() for a in encoded.row(1, 2)] == [[0, 4], [0, 4]]
    assert encoded.segment_count == 3
    assert encoded.bounding_box() == ((0, 1), (0, 2), (0, 4))


def test_empty_mask():
    encoded = segments.encode(np.zeros((3, 4, 5), bool))
    assert encoded.segment_count == 0 and encoded.bounding_box() is None
    assert not encoded.to_mask().any()


def test_slice_index_reads_one_slice():
    rng = np.random.default_rng(1)
    mask = rng.random((6, 4, 8)) < 0.4
    encoded = segments.encode(mask)
    for z in range(6):
        assert np.array_equal(encoded.slice_mask(z), mask[z])


def test_file_round_trip_is_memory_mapped(tmp_path):
    rng = np.random.default_rng(4)
    mask = rng.random((5, 6, 7)) < 0.3
    path = tmp_path / "obj.vxs"
    segments.save(segments.encode(mask, (0.5, 0.5, 0.5), {"threshold": 300.0}), path)
    loaded = segments.load(path)
    assert segments.is_mapped(loaded.starts)
    assert np.array_equal(loaded.to_mask(), mask)
    assert loaded.spacing == (0.5, 0.5, 0.5) and loaded.meta["threshold"] == 300.0
    assert [p.name for p in tmp_path.iterdir()] == ["obj.vxs"]  # no temporary left behind


def test_load_rejects_other_and_truncated_files(tmp_path):
    other = tmp_path / "not.vxs"
    other.write_bytes(b"hello")
    with pytest.raises(InputError, match="not a voxrender"):
        segments.load(other)
    good = tmp_path / "good.vxs"
    segments.save(segments.encode(np.ones((4, 4, 4), bool)), good)
    cut = tmp_path / "cut.vxs"
    cut.write_bytes(good.read_bytes()[:-100])
    with pytest.raises(InputError, match="damaged"):
        segments.load(cut)


def test_encode_rejects_2d():
    with pytest.raises(InputError):
        segments.encode(np.zeros((3, 3), bool))


@pytest.mark.parametrize("block", [1, 7, 30, 1 << 24])
def test_encoding_in_blocks_of_rows_gives_the_same_runs(monkeypatch, block):
    mask = np.random.default_rng(9).random((4, 5, 8)) < 0.5
    mask[0, 0, :] = True                      # runs that touch both ends of a row
    monkeypatch.setattr(segments, "_BLOCK_VOXELS", block)
    encoded = segments.encode(mask)
    assert np.array_equal(encoded.to_mask(), mask)
    assert encoded.segment_count == sum(len(np.flatnonzero(np.diff(np.r_[0, row, 0]) == 1))
                                        for row in mask.reshape(-1, 8).astype(int))


@pytest.mark.parametrize("block", [1, 7, 1 << 24])
def test_labels_encoded_in_blocks_of_rows_give_the_same_runs(monkeypatch, block):
    values = np.random.default_rng(10).integers(0, 3, (3, 4, 6))
    values[0, 0, :] = 2                       # a stretch that touches both ends of a row
    monkeypatch.setattr(segments, "_BLOCK_VOXELS", block)
    encoded = segments.encode_labels(values)
    again = np.zeros(values.size, int)
    for row, start, end, label in zip(encoded.run_rows(), encoded.starts, encoded.ends, encoded.labels, strict=True):
        again[row * 6 + start:row * 6 + end + 1] = label
    assert np.array_equal(again.reshape(values.shape), values)
