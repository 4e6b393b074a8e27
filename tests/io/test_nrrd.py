"""voxrender.io.nrrd: NRRD, attached or detached, and folders of NRRD files."""

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
    assert io.detect_format(tmp_path) == "nrrd"
    with pytest.raises(InputError, match=r"holds 2 NRRD volume files \(liver.seg.nrrd, spleen.seg.nrrd\), not slices"):
        io.read_volume(tmp_path)


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
