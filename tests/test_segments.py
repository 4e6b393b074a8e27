import numpy as np
import pytest

from voxrender._shared.mapped import is_mapped
from voxrender.errors import InputError
from voxrender.object import segments, vxs


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
    vxs.save(segments.encode(mask, (0.5, 0.5, 0.5), {"threshold": 300.0}), path)
    loaded = vxs.load(path)
    assert is_mapped(loaded.starts)
    assert np.array_equal(loaded.to_mask(), mask)
    assert loaded.spacing == (0.5, 0.5, 0.5) and loaded.meta["threshold"] == 300.0
    assert [p.name for p in tmp_path.iterdir()] == ["obj.vxs"]  # no temporary left behind


def test_load_rejects_other_and_truncated_files(tmp_path):
    other = tmp_path / "not.vxs"
    other.write_bytes(b"hello")
    with pytest.raises(InputError, match="not a voxrender"):
        vxs.load(other)
    good = tmp_path / "good.vxs"
    vxs.save(segments.encode(np.ones((4, 4, 4), bool)), good)
    cut = tmp_path / "cut.vxs"
    cut.write_bytes(good.read_bytes()[:-100])
    with pytest.raises(InputError, match="damaged"):
        vxs.load(cut)


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


def _rewritten(path, change, arrays=None):
    """``path`` (a .vxs file) with its JSON header changed by ``change(header)`` and its arrays by ``arrays``
    (name: new values of the same size and type), written back with the header's new length."""
    import json

    header, mapped = vxs.read_sections(path)
    data = {name: np.array(array) for name, array in mapped.items()}
    for name, values in (arrays or {}).items():
        data[name][...] = values
    change(header)
    text = json.dumps(header).encode()
    start = -(-(len(vxs.MAGIC) + 8 + len(text)) // 64) * 64
    body = bytearray(max(start + spec["offset"] + data[name].nbytes for name, spec in header["arrays"].items()
                         if name in data))
    for name, spec in header["arrays"].items():
        if name in data:
            body[start + spec["offset"]:start + spec["offset"] + data[name].nbytes] = data[name].tobytes()
    head = vxs.MAGIC + np.uint64(len(text)).tobytes() + text
    path.write_bytes(head + bytes(body[len(head):]))
    return path


def _set(key, value, inside=None):
    def change(header):
        (header[inside] if inside else header)[key] = value
    return change


@pytest.mark.parametrize("change, arrays, message", [
    (_set("meta", "x"), None, "its meta is not a table of names"),
    (_set("label_table", [1, 2], "meta"), None, "its meta is not a table of names"),
    (_set("shape", [4, 4]), None, "its shape .* is not three positive sizes"),
    (_set("shape", [4, 4, -4]), None, "its shape .* is not three positive sizes"),
    (_set("spacing", [1, "a", 1]), None, "its spacing .* is not three positive numbers"),
    (_set("spacing", [1, 0, 1]), None, "its spacing .* is not three positive numbers"),
    (lambda header: header["arrays"]["starts"].update(count=10**9), None, "its array starts .* is not within"),
    (lambda header: header["arrays"]["starts"].update(offset=-64), None, "its array starts .* is not within"),
    (lambda header: header["arrays"]["starts"].update(dtype="|O"), None, "its array starts .* is not within"),
    (lambda header: header["arrays"]["ends"].update(dtype="<f4"), None, "an array is not of integers"),
    (lambda header: header["arrays"].pop("ends"), None, "it lacks ends"),
    (lambda header: None, {"ends": 9}, "runs leave their grid"),
    (lambda header: None, {"starts": -1}, "runs leave their grid"),
    (lambda header: None, {"offsets": 0}, "index and runs disagree"),
])
def test_a_damaged_vxs_file_is_bad_input(tmp_path, change, arrays, message):
    """Each was an internal error (exit 1) when loaded or rendered: a meta that is no table (found by the fuzzing
    gate), a shape or spacing of the wrong kind, arrays outside the file or runs outside the grid."""
    path = tmp_path / "v.vxs"
    vxs.save(segments.encode(np.ones((4, 4, 4), bool)), path)
    _rewritten(path, change, arrays)
    with pytest.raises(InputError, match=f"v.vxs is a damaged .vxs file \\({message}"):
        vxs.load(path)


def test_a_header_length_beyond_the_file_is_bad_input(tmp_path):
    path = tmp_path / "v.vxs"
    vxs.save(segments.encode(np.ones((4, 4, 4), bool)), path)
    whole = bytearray(path.read_bytes())
    whole[len(vxs.MAGIC):len(vxs.MAGIC) + 8] = np.uint64(2**63).tobytes()
    path.write_bytes(bytes(whole))
    with pytest.raises(InputError, match="its header of 9223372036854775808 bytes is longer than the file"):
        vxs.load(path)


def test_normals_out_of_order_are_found_when_first_used(tmp_path):
    """The normals' index is checked when they are first used (reading it whole is most of loading a big file, and
    a picture from a coarser level needs it not): loaded, then refused as a damaged file, one line, exit 2."""
    from test_cli import assert_bad_input, run

    from voxrender.object.normals import surface_normals

    mask = np.zeros((6, 6, 6), bool)
    mask[1:5, 1:5, 1:5] = True
    encoded = segments.encode(mask)
    encoded.normals = surface_normals(mask)
    path = tmp_path / "v.vxs"
    vxs.save(encoded, path)
    index = np.asarray(encoded.normals.index).copy()
    index[[3, 4]] = index[[4, 3]]
    _rewritten(path, lambda header: None, {"normal_index": index})
    loaded = vxs.load(path)
    with pytest.raises(InputError, match="damaged .vxs file \\(surface normals and their voxels disagree"):
        loaded.normals.at(np.array([[2.5, 2.5, 0.9]]))
    assert_bad_input(run("render", path, "-o", tmp_path / "v.png"), "damaged")
    assert not (tmp_path / "v.png").exists()
