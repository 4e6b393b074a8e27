"""voxrender.io.metaimage: MetaImage .mhd and .mha."""

import zlib

import numpy as np
import pytest
from conftest import data_path
from formats import refused_cuts

from voxrender import io
from voxrender.errors import InputError


def _write_mhd(path, values, compressed=False, local=False, msb=False):
    dtype = values.dtype.newbyteorder(">" if msb else "<")
    payload = values.astype(dtype).tobytes()
    if compressed:
        payload = zlib.compress(payload)
    nz, ny, nx = values.shape
    header = (f"ObjectType = Image\nNDims = 3\nDimSize = {nx} {ny} {nz}\nElementSpacing = 0.5 0.7 2\n"
              f"ElementType = MET_SHORT\nElementByteOrderMSB = {msb}\nCompressedData = {compressed}\n")
    if compressed:
        header += f"CompressedDataSize = {len(payload)}\n"
    if local:
        path.write_bytes((header + "ElementDataFile = LOCAL\n").encode() + payload)
    else:
        path.with_suffix(".raw").write_bytes(payload)
        path.write_text(header + f"ElementDataFile = {path.with_suffix('.raw').name}\n")


@pytest.mark.parametrize("compressed,local,msb", [(False, False, False), (True, False, False),
                                                  (False, True, True), (True, True, False)])
def test_metaimage(tmp_path, compressed, local, msb):
    values = np.random.default_rng(5).integers(-1000, 1000, size=(3, 4, 5)).astype(np.int16)
    path = tmp_path / ("v.mha" if local else "v.mhd")
    _write_mhd(path, values, compressed, local, msb)
    volume = io.read_volume(path)
    assert np.array_equal(volume.values, values) and volume.spacing == (0.5, 0.7, 2.0)


def test_truncated_metaimage(tmp_path):
    values = np.zeros((3, 4, 5), np.int16)
    _write_mhd(tmp_path / "v.mhd", values)
    (tmp_path / "v.raw").write_bytes(b"\0" * 10)
    with pytest.raises(InputError, match="truncated"):
        io.read_volume(tmp_path / "v.mhd")


def test_headmr_metaimage():
    volume = io.read_volume(data_path("headmr") / "HeadMRVolume.mhd")
    assert volume.shape == (42, 62, 48) and volume.spacing == (4.0, 4.0, 4.0)
    assert volume.values.dtype == np.uint8


def test_a_folder_with_one_metaimage_reads_it_and_with_two_lists_them(tmp_path):
    values = np.arange(60, dtype=np.int16).reshape(3, 4, 5)
    _write_mhd(tmp_path / "a.mhd", values)
    assert io.detect_format(tmp_path) == "metaimage"
    volume = io.read_volume(tmp_path)
    assert np.array_equal(volume.values, values) and volume.meta["source"] == str(tmp_path / "a.mhd")
    _write_mhd(tmp_path / "b.mha", values, local=True)
    with pytest.raises(InputError, match=r"holds 2 MetaImage volume files \(a.mhd, b.mha\), not slices; give one"):
        io.read_volume(tmp_path)


@pytest.mark.parametrize("line", ["DimSize = 5 4 x", "DimSize = 5 -4 3", "ElementNumberOfChannels = one",
                                  "HeaderSize = -", "ElementDataFile ="])
def test_header_values_that_are_not_numbers(tmp_path, line):
    key = line.split()[0]
    _write_mhd(tmp_path / "v.mha", np.zeros((3, 4, 5), np.int16), local=True)
    header, _, payload = (tmp_path / "v.mha").read_bytes().partition(b"ElementDataFile = LOCAL\n")
    lines = [text for text in header.decode().splitlines() if not text.startswith(key)]
    data = "ElementDataFile = LOCAL\n" if key != "ElementDataFile" else line + "\n"
    (tmp_path / "v.mha").write_bytes(("\n".join(lines + [line]) + "\n" + data).encode() + payload)
    with pytest.raises(InputError, match="v.mha"):
        io.read_volume(tmp_path / "v.mha")


@pytest.mark.parametrize("compressed", [False, True])
def test_cut_metaimages_are_bad_input(tmp_path, compressed):
    _write_mhd(tmp_path / "v.mha", np.random.default_rng(0).integers(0, 999, (3, 8, 9)).astype(np.int16), compressed,
               local=True)
    assert refused_cuts(tmp_path / "v.mha", lambda: io.read_volume(tmp_path / "v.mha")) >= 30


def _mha(path, dims, payload, compressed=False):
    header = (f"NDims = 3\nDimSize = {dims}\nElementType = MET_SHORT\nCompressedData = {compressed}\n"
              "ElementDataFile = LOCAL\n")
    path.write_bytes(header.encode() + payload)
    return path


@pytest.mark.parametrize("compressed", [False, True])
def test_a_header_promising_more_than_the_file_holds_says_both(tmp_path, compressed):
    payload = zlib.compress(bytes(64)) if compressed else bytes(64)
    path = _mha(tmp_path / "huge.mha", "30000 30000 30000", payload, compressed)
    with pytest.raises(InputError, match=r"holds 64 bytes of voxels, of the 54 TB its header promises"):
        io.read_volume(path)


def test_dimensions_whose_product_overflows_int64_are_bad_input(tmp_path):
    """np.prod of the DimSize wrapped around: a wrong count, then 'cannot reshape array' (exit 1)."""
    with pytest.raises(InputError, match="of voxels, of the .* its header promises"):
        io.read_volume(_mha(tmp_path / "v.mha", "4294967296 4294967296 2", bytes(64)))


def test_a_compressed_stream_longer_than_promised_is_refused(tmp_path):
    path = _mha(tmp_path / "bomb.mha", "10 10 10", zlib.compress(bytes(50_000_000)), compressed=True)
    with pytest.raises(InputError, match="holds more than the 2 kB of voxels its header promises"):
        io.read_volume(path)


@pytest.mark.parametrize("compressed", [False, True])
def test_a_volume_too_big_for_memory_is_refused_with_its_size(tmp_path, monkeypatch, compressed):
    from voxrender.io import _shared

    monkeypatch.setattr(_shared, "free_memory", lambda: 1000)
    payload = bytes(2 * 8000)
    path = _mha(tmp_path / "v.mha", "20 20 20", zlib.compress(payload) if compressed else payload, compressed)
    with pytest.raises(InputError, match=r"its 20x20x20 int16 voxels take 16 kB, more than the 1 kB of memory free"):
        io.read_volume(path)


@pytest.mark.parametrize("offset", ["1 2", "1 2 nan", "a b c"])
def test_an_offset_that_is_not_three_numbers_is_left_out(tmp_path, offset):
    """Two numbers did not fit the affine's three (a broadcast error, exit 1)."""
    header = ("NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nTransformMatrix = 1 0 0 0 1 0 0 0 1\n"
              f"Offset = {offset}\nElementDataFile = LOCAL\n")
    (tmp_path / "v.mha").write_bytes(header.encode() + bytes(8))
    volume = io.read_volume(tmp_path / "v.mha")
    assert "origin" not in volume.meta and volume.meta["affine"][0][3] == 0
