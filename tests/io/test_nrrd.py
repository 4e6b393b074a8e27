"""voxrender.io.nrrd: NRRD, attached or detached, and folders of NRRD files."""

import bz2
import gzip

import numpy as np
import pytest
from formats import refused_cuts

from voxrender import io
from voxrender.errors import InputError


def test_nrrd_encodings_and_bad_files(tmp_path):
    import nrrd

    data = np.random.default_rng(1).integers(0, 100, (3, 4, 5)).astype(np.uint16)
    for encoding in ("raw", "gzip", "bzip2"):
        nrrd.write(str(tmp_path / f"{encoding}.nrrd"), data, {"encoding": encoding, "endian": "big"}, index_order="C")
        assert np.array_equal(io.read_volume(tmp_path / f"{encoding}.nrrd").values, data)
    nrrd.write(str(tmp_path / "detached.nhdr"), data, {"encoding": "gzip"}, index_order="C", detached_header=True)
    assert np.array_equal(io.read_volume(tmp_path / "detached.nhdr").values, data)
    next(tmp_path.glob("detached.raw*")).unlink()
    with pytest.raises(InputError, match="missing|cannot read"):
        io.read_volume(tmp_path / "detached.nhdr")
    text = (tmp_path / "raw.nrrd").read_bytes().replace(b"encoding: raw", b"encoding: magic")
    (tmp_path / "magic.nrrd").write_bytes(text)
    with pytest.raises(InputError, match="cannot read"):
        io.read_volume(tmp_path / "magic.nrrd")


@pytest.mark.parametrize("space,outcome", [("posterior-left-superior", "PLS -> LPS: axes yxz -> xyz"),
                                           ("left-right-superior", "names a patient axis twice")])
def test_nrrd_space_names_the_axes(tmp_path, space, outcome):
    data = np.arange(60, dtype=np.uint8).reshape(3, 4, 5)
    header = (f"NRRD0004\ntype: uint8\ndimension: 3\nspace: {space}\nsizes: 5 4 3\n"
              "space directions: (1,0,0) (0,1,0) (0,0,2)\nencoding: raw\n\n")
    (tmp_path / "v.nrrd").write_bytes(header.encode() + data.tobytes())
    if "twice" in outcome:
        with pytest.raises(InputError, match=outcome):
            io.read_volume(tmp_path / "v.nrrd")
        return
    volume = io.read_volume(tmp_path / "v.nrrd")
    assert volume.meta["reoriented"] == outcome
    assert np.array_equal(volume.values, data.transpose(0, 2, 1)) and volume.spacing == (1.0, 1.0, 2.0)


def test_nrrd_4d_takes_a_frame(tmp_path):
    import nrrd

    data = np.arange(2 * 3 * 4 * 5, dtype=np.int16).reshape(2, 3, 4, 5)       # [t, z, y, x]
    nrrd.write(str(tmp_path / "four.nrrd"), data, {"space": "left-posterior-superior", "kinds":
               ["domain", "domain", "domain", "list"], "space directions": [[1, 0, 0], [0, 1, 0], [0, 0, 2],
                                                                             [np.nan] * 3]}, index_order="C")
    with pytest.raises(InputError, match="holds 2 volumes") as info:
        io.read_volume(tmp_path / "four.nrrd")
    assert info.value.parameter == "frame"
    volume = io.read_volume(tmp_path / "four.nrrd", frame=1)
    assert np.array_equal(volume.values, data[1]) and volume.spacing == (1.0, 1.0, 2.0)
    with pytest.raises(InputError, match="is not a volume") as info:
        io.read_volume(tmp_path / "four.nrrd", frame=5)
    assert info.value.parameter == "frame"


def test_a_folder_of_nrrd_files_says_what_it_holds(tmp_path):
    import nrrd

    for name in ("liver", "spleen"):
        nrrd.write(str(tmp_path / f"{name}.seg.nrrd"), np.zeros((3, 4, 5), np.uint8))
    assert io.detect_format(tmp_path) == "masks"
    with pytest.raises(InputError, match=r"holds 2 NRRD volume files \(liver.seg.nrrd, spleen.seg.nrrd\), not slices; "
                                         r"give one of them, or the folder as one label map of masks"):
        io.read_volume(tmp_path, format="nrrd")


def test_raw_slices_beside_their_nrrd_header_are_not_a_folder_of_volumes(tmp_path):
    """The quarter head's folder: 93 raw slices and the .nhdr that lists them (which pynrrd cannot follow)."""
    for z in range(3):
        np.zeros((4, 4), "<u2").tofile(tmp_path / f"quarter.{z + 1}")
    (tmp_path / "quarter.nhdr").write_text("NRRD0004\ndata file: quarter.%d 1 3 1\n")
    with pytest.raises(InputError, match=r"holds 4 files \(quarter.1, quarter.2, quarter.3, ...\) but no") as info:
        io.read_volume(tmp_path)
    assert info.value.parameter == "raw"


@pytest.mark.parametrize("encoding", ["raw", "gzip", "bzip2"])
def test_cut_nrrd_files_are_bad_input(tmp_path, encoding):
    import nrrd

    data = np.random.default_rng(0).integers(0, 999, (7, 8, 9)).astype(np.int16)
    nrrd.write(str(tmp_path / "v.nrrd"), data, {"encoding": encoding}, index_order="C")
    assert refused_cuts(tmp_path / "v.nrrd", lambda: io.read_volume(tmp_path / "v.nrrd")) >= 30


def _nrrd(path, fields, payload):
    """A NRRD written by hand: a header pynrrd would refuse to write, and the bytes after it."""
    path.write_bytes(("NRRD0004\n" + "".join(f"{key}: {value}\n" for key, value in fields.items()) + "\n").encode()
                     + payload)
    return path


INT16 = {"type": "int16", "endian": "little", "dimension": 3}


@pytest.mark.parametrize("encoding, payload", [("raw", bytes(64)), ("gzip", gzip.compress(bytes(64))),
                                               ("bzip2", bz2.compress(bytes(64)))])
def test_a_header_promising_more_than_the_file_holds_says_both(tmp_path, encoding, payload):
    """30000³ int16 over 64 bytes: the file holds 64 bytes of the 54 TB its header promises (was 'out of memory')."""
    path = _nrrd(tmp_path / "huge.nrrd", {**INT16, "sizes": "30000 30000 30000", "encoding": encoding}, payload)
    with pytest.raises(InputError, match=r"holds 64 bytes of voxels, of the 54 TB its header promises"):
        io.read_volume(path)


@pytest.mark.parametrize("encoding, compress", [("raw", bytes), ("gzip", gzip.compress), ("bzip2", bz2.compress)])
def test_voxels_short_or_long_are_refused_with_both_sizes(tmp_path, encoding, compress):
    fields = {**INT16, "sizes": "4 4 4", "encoding": encoding}
    with pytest.raises(InputError, match=r"holds 100 bytes of voxels, of the 128 bytes its header promises"):
        io.read_volume(_nrrd(tmp_path / "short.nrrd", fields, compress(bytes(100))))
    with pytest.raises(InputError, match=r"holds (200 bytes|more than the 128 bytes) of voxels"):
        io.read_volume(_nrrd(tmp_path / "long.nrrd", fields, compress(bytes(200))))


def test_a_gzip_bomb_is_inflated_no_further_than_promised(tmp_path, monkeypatch):
    from voxrender.io import _shared

    inflated = []
    real = _shared._inflated_chunks

    def counted(*args):
        for chunk in real(*args):
            inflated.append(len(chunk))
            yield chunk

    monkeypatch.setattr(_shared, "_inflated_chunks", counted)
    bomb = gzip.compress(bytes(200_000_000))                  # 200 MB of zeros in 200 kB
    path = _nrrd(tmp_path / "bomb.nrrd", {**INT16, "sizes": "10 10 10", "encoding": "gzip"}, bomb)
    with pytest.raises(InputError, match="holds more than the 2 kB of voxels its header promises"):
        io.read_volume(path)
    assert sum(inflated) <= 2001


def test_a_volume_too_big_for_memory_is_refused_with_its_size(tmp_path, monkeypatch):
    from voxrender.io import _shared

    monkeypatch.setattr(_shared, "free_memory", lambda: 1000)
    for encoding in ("raw", "gzip"):
        payload = bytes(2 * 20 * 20 * 20)
        path = _nrrd(tmp_path / f"{encoding}.nrrd", {**INT16, "sizes": "20 20 20", "encoding": encoding},
                     gzip.compress(payload) if encoding == "gzip" else payload)
        with pytest.raises(InputError, match=r"its 20x20x20 int16 voxels take 16 kB, more than the 1 kB of memory "
                                             "free here") as info:
            io.read_volume(path)
        assert info.value.parameter is None


@pytest.mark.parametrize("directions, message", [
    ("(1,0) (0,1) (0,0)", "its space directions are 3 vectors of 2 numbers; a 3-D file in a 3-D space needs 3"),
    ("(1,0,0) (0,1,0) (0,0,0)", r"the space direction of its axis 2 is \[0.0, 0.0, 0.0\], which has no length"),
    ("(1,0,0) (0,1,0) (0,0,nan)", "the space direction of its axis 2 is"),
    ("none (0,1,0) (0,0,1)", "its axis 0 has no space direction"),
    ("(1,0,0) (1,0,0) (0,0,1)", "not orthogonal")])
def test_degenerate_space_directions_are_bad_input(tmp_path, directions, message):
    """Was a matmul shape error (exit 1), or a spacing of nan after a warning."""
    fields = {**INT16, "space": "left-posterior-superior", "sizes": "4 4 4", "space directions": directions,
              "encoding": "raw"}
    with pytest.raises(InputError, match=message):
        io.read_volume(_nrrd(tmp_path / "v.nrrd", fields, bytes(128)))


def test_a_4d_nrrd_of_one_volume_gives_it(tmp_path):
    """Was refused as 'holds 1 volumes (4-D)'."""
    import nrrd

    nrrd.write(str(tmp_path / "one.nrrd"), np.full((1, 1, 1, 1), 7, np.int16),
               {"space": "left-posterior-superior", "kinds": ["domain", "domain", "domain", "list"],
                "space directions": [[1, 0, 0], [0, 1, 0], [0, 0, 1], [np.nan] * 3]}, index_order="C")
    assert io.read_volume(tmp_path / "one.nrrd").values.tolist() == [[[7]]]
    assert io.read_volume(tmp_path / "one.nrrd", frame=0).values.tolist() == [[[7]]]


@pytest.mark.parametrize("fields, message", [
    ({"dimension": 2, "sizes": "8 8", "kinds": "list domain"}, "holds a 2-D array .* not a 3-D spatial volume"),
    ({"dimension": 3, "sizes": "3 4 4", "kinds": "RGB-color domain domain"},
     "its axis 0 is of kind 'RGB-color', so it is not a 3-D spatial volume")])
def test_a_nrrd_that_is_not_a_spatial_volume_is_named(tmp_path, fields, message):
    path = _nrrd(tmp_path / "v.nrrd", {"type": "uint8", "encoding": "raw", **fields},
                 bytes(int(np.prod([int(n) for n in fields["sizes"].split()]))))
    with pytest.raises(InputError, match=message):
        io.read_volume(path)


def test_a_header_without_its_required_fields(tmp_path):
    with pytest.raises(InputError, match="its NRRD header lacks encoding, sizes"):
        io.read_volume(_nrrd(tmp_path / "v.nrrd", {"type": "uint8", "dimension": 3}, bytes(8)))


@pytest.mark.parametrize("origin", ["(1,2)", "(1,2,nan)", "(1,2,3,4)"])
def test_a_space_origin_that_is_not_three_numbers_is_bad_input(tmp_path, origin):
    """A two-number origin was a matmul shape error, exit 1 (the fuzzing gate)."""
    fields = {**INT16, "space": "left-posterior-superior", "sizes": "4 4 4",
              "space directions": "(1,0,0) (0,1,0) (0,0,1)", "space origin": origin, "encoding": "raw"}
    with pytest.raises(InputError, match="its space origin .* is not three numbers"):
        io.read_volume(_nrrd(tmp_path / "v.nrrd", fields, bytes(128)))


def test_an_empty_vector_is_bad_input(tmp_path):
    """pynrrd's parser indexes an empty vector's first character (IndexError, exit 1)."""
    fields = {**INT16, "space": "left-posterior-superior", "sizes": "4 4 4", "space origin": "", "encoding": "raw"}
    with pytest.raises(InputError, match="cannot read .* as NRRD"):
        io.read_volume(_nrrd(tmp_path / "v.nrrd", fields, bytes(128)))


def test_nrrd_4d_with_its_list_axis_first_takes_a_frame(tmp_path):
    """3D Slicer writes a sequence's frames along the fastest axis, of kind 'list' (its kinds are the header's,
    so the three kept axes are checked by their place in the header, not after the frame is taken)."""
    import nrrd

    data = np.arange(3 * 4 * 5 * 2, dtype=np.int16).reshape(3, 4, 5, 2)       # [z, y, x, t]
    nrrd.write(str(tmp_path / "four.nrrd"), data, {"space": "left-posterior-superior", "kinds":
               ["list", "domain", "domain", "domain"], "space directions": [[np.nan] * 3, [1, 0, 0], [0, 1, 0],
                                                                             [0, 0, 2]]}, index_order="C")
    volume = io.read_volume(tmp_path / "four.nrrd", frame=1)
    assert np.array_equal(volume.values, data[..., 1]) and volume.spacing == (1.0, 1.0, 2.0)


def _early_segmentation(path, segments, extents, common="1 4 2 4 3 4"):
    """An early 3D Slicer .seg.nrrd (before 4.11), written by pynrrd as Slicer wrote them: 4-D in an unnamed
    space of 4 dimensions, one binary volume a segment along the slowest axis, cropped to Segmentation_Extent."""
    import nrrd

    header = {"space dimension": 4, "kinds": ["domain"] * 4, "space origin": [250, 250, -120, 0],
              "space directions": [[-1, 0, 0, 0], [0, -1, 0, 0], [0, 0, 2.5, 0], [0, 0, 0, 1]],
              "Segmentation_Extent": common, "Segmentation_MasterRepresentation": "Binary labelmap"}
    for index, extent in enumerate(extents):
        header |= {f"Segment{index}_Name": f"organ {index}", f"Segment{index}_Extent": extent,
                   f"Segment{index}_DefaultColor": "1 0 0.5"}
    nrrd.write(str(path), segments, header, index_order="C")


def test_an_early_slicer_segmentation_is_read_in_ras_at_its_extent(tmp_path):
    """3D Slicer took the unnamed space as RAS and put the file's first voxel at the corner of Segmentation_Extent;
    each segment keeps its own voxels, within its own extent (the rest of the common block is not its)."""
    segments = np.zeros((2, 2, 3, 4), np.uint8)               # [segment, z, y, x]: x 1..4, y 2..4, z 3..4
    segments[0] = 1                                            # organ 0 fills the block
    segments[1, :, 1:, 2:] = 1                                 # organ 1 inside it...
    segments[1, :, 0, 0] = 1                                   # ...and a voxel outside its own extent
    _early_segmentation(tmp_path / "early.seg.nrrd", segments, ["1 4 2 4 3 4", "3 4 3 4 3 4"])
    volume = io.read_volume(tmp_path / "early.seg.nrrd")
    # RAS (250 - x, 250 - y) is LPS (x - 250, y - 250): the first voxel, x 1, y 2, z 3, is at LPS (-249, -248, -112.5)
    assert volume.meta["origin"] == pytest.approx([-249, -248, -112.5]) and volume.spacing == (1.0, 1.0, 2.5)
    assert "early 3D Slicer" in volume.meta["orientation_from"]
    assert volume.meta["label_table"] == {"1": {"name": "organ 0", "colour": [255, 0, 128]},
                                          "2": {"name": "organ 1", "colour": [255, 0, 128]}}
    from voxrender._shared import label_sets

    own = label_sets.structure_counts(volume.values, volume.meta["label_sets"])
    assert own == {1: 24, 2: 2 * 2 * 2}                       # organ 1: its extent's 8 voxels, not the stray one
    assert volume.meta["overlaps"][0]["inside"]


def test_an_early_slicer_segmentation_of_one_segment_takes_no_frame(tmp_path):
    _early_segmentation(tmp_path / "one.seg.nrrd", np.ones((1, 2, 3, 4), np.uint8), ["1 4 2 4 3 4"])
    assert io.read_volume(tmp_path / "one.seg.nrrd").values.sum() == 24
    with pytest.raises(InputError, match="holds one volume") as info:
        io.read_volume(tmp_path / "one.seg.nrrd", frame=0)
    assert info.value.parameter == "frame"
