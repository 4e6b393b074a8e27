"""Stacks of NIfTI, NRRD and MetaImage files, raw and compressed: ``open_stack`` read a slab at a time, in any order,
gives ``read_volume``'s values, spacing, direction and meta; damaged streams are bad input when their slab is read."""

import bz2
import gzip
import zlib

import nibabel
import nrrd
import numpy as np
import pytest
from conftest import data_path
from formats import refused_cuts, stored, write_metaimage, write_nifti, write_nrrd

from voxrender import io
from voxrender.errors import InputError
from voxrender.io import _shared

# stored order; z flipped (read from the far end); x and y flipped; permuted (sagittal: slices across the canonical)
ORIENTATIONS = ["LPS", "LPI", "RAS", "PIR"]
# file name, how to write it: (path, stored values, spacing, direction)
KINDS = {
    "nifti raw": ("v.nii", write_nifti),
    "nifti gzip": ("v.nii.gz", write_nifti),
    "nrrd raw": ("v.nrrd", lambda *a: write_nrrd(*a, encoding="raw")),
    "nrrd gzip": ("v.nrrd", lambda *a: write_nrrd(*a, encoding="gzip")),
    "nrrd bzip2": ("v.nrrd", lambda *a: write_nrrd(*a, encoding="bzip2")),
    "nrrd big-endian": ("v.nrrd", lambda *a: write_nrrd(*a, encoding="raw", endian="big")),
    "nhdr raw": ("v.nhdr", lambda *a: write_nrrd(*a, encoding="raw")),
    "nhdr gzip": ("v.nhdr", lambda *a: write_nrrd(*a, encoding="gzip")),
    "nrrd text": ("v.nrrd", lambda *a: write_nrrd(*a, encoding="ascii")),
    "mha raw": ("v.mha", lambda *a: _write_metaimage(*a)),
    "mha zlib": ("v.mha", lambda *a: _write_metaimage(*a, compressed=True)),
    "mhd raw": ("v.mhd", lambda *a: _write_metaimage(*a)),
    "mhd zlib": ("v.mhd", lambda *a: _write_metaimage(*a, compressed=True)),
}


def _write_metaimage(path, values, spacing, direction, compressed=False):
    """tests/formats.py's MetaImage (a .mha, raw), its voxels zlib-compressed or in a data file beside a .mhd."""
    header, _, payload = write_metaimage(path.with_suffix(".mha"), values, spacing, direction).read_bytes().partition(
        b"ElementDataFile = LOCAL\n")
    if compressed:
        payload = zlib.compress(payload)
        header += f"CompressedData = True\nCompressedDataSize = {len(payload)}\n".encode()
    if path.suffix == ".mhd":
        path.with_suffix(".mha").unlink()
        path.with_suffix(".raw").write_bytes(payload)
        path.write_bytes(header + b"ElementDataFile = v.raw\n")
    else:
        path.write_bytes(header + b"ElementDataFile = LOCAL\n" + payload)
    return path


def _canonical(shape=(7, 6, 5), seed=0):
    """Distinct int16 values ``[z, y, x]`` in the canonical frame, so that any slice out of place shows."""
    return np.random.default_rng(seed).permutation(np.prod(shape)).reshape(shape).astype(np.int16) - 100


def _write(tmp_path, kind, code, canonical=None):
    name, write = KINDS[kind]
    values, spacing, direction = stored(_canonical() if canonical is None else canonical, code)
    return write(tmp_path / name, values, spacing, direction)


def _slabs(nz, size):
    return [(z, min(z + size, nz)) for z in range(0, nz, size)]


def _assert_reads_as_volume(path, **options):
    """``open_stack(path)`` read in slabs of 1, 2 and 3 slices, in order, backwards and shuffled, is
    ``read_volume(path)``: values, type (in native byte order: a stack's slices are), spacing, direction, meta."""
    volume = io.read_volume(path, **options)
    stack = io.open_stack(path, **options)
    assert stack.shape == volume.shape and stack.spacing == volume.spacing and stack.meta == volume.meta
    assert (stack.direction is None and volume.direction is None) or np.array_equal(stack.direction,
                                                                                    volume.direction)
    assert stack.dtype == volume.values.dtype.newbyteorder("=")
    rng = np.random.default_rng(1)
    for size in (1, 2, 3):
        slabs = _slabs(stack.shape[0], size)
        whole = np.concatenate([stack.read_slices(z0, z1) for z0, z1 in slabs])
        assert whole.dtype == stack.dtype and np.array_equal(whole, volume.values)
        for order in (slabs[::-1], [slabs[i] for i in rng.permutation(len(slabs))]):
            got = {z0: stack.read_slices(z0, z1) for z0, z1 in order}
            assert np.array_equal(np.concatenate([got[z0] for z0, _ in slabs]), volume.values)
    return stack


@pytest.mark.parametrize("code", ORIENTATIONS)
@pytest.mark.parametrize("kind", KINDS)
def test_slabs_in_any_order_are_the_volume(tmp_path, kind, code):
    stack = _assert_reads_as_volume(_write(tmp_path, kind, code))
    assert stack.how == {"LPS": "stored order", "LPI": "from the far end", "RAS": "stored order",
                         "PIR": "across the stored slices"}[code]
    assert stack.stack.sequential == any(word in kind for word in ("gzip", "bzip2", "zlib"))


@pytest.mark.parametrize("name", ["v.nii", "v.nii.gz"])
@pytest.mark.parametrize("dtype, slope, inter", [(np.int16, 0.5, -10), (np.uint8, 2, 0), (np.float32, 0.25, 3),
                                                 (np.int32, 1, 0)])
def test_nifti_scaled_as_read_volume_scales_it(tmp_path, name, dtype, slope, inter):
    data = np.random.default_rng(2).integers(0, 100, (5, 4, 6)).astype(dtype)          # [i, j, k]
    image = nibabel.Nifti1Image(data, np.diag([0.5, 0.7, 2.0, 1.0]))
    image.header.set_slope_inter(slope, inter)
    nibabel.save(image, str(tmp_path / name))
    stack = _assert_reads_as_volume(tmp_path / name)
    if slope != 1:
        assert stack.dtype.kind == "f" and stack.meta["scaled"].startswith("scl_slope")


def test_nifti_2(tmp_path):
    values, spacing, direction = stored(_canonical(), "RAS")
    affine = np.eye(4)
    affine[:3, :3] = np.diag(spacing)
    nibabel.save(nibabel.Nifti2Image(np.transpose(values, (2, 1, 0)), affine), str(tmp_path / "v.nii"))
    _assert_reads_as_volume(tmp_path / "v.nii")


@pytest.mark.parametrize("name", ["four.nii", "four.nii.gz"])
def test_a_frame_of_a_4d_nifti(tmp_path, name):
    data = np.random.default_rng(3).integers(-500, 500, (5, 4, 6, 3)).astype(np.int16)    # [i, j, k, t]
    image = nibabel.Nifti1Image(data, np.diag([2.0, 3.0, 4.0, 1.0]))
    image.header.set_slope_inter(0.5, 10)
    nibabel.save(image, str(tmp_path / name))
    for frame in (0, 1, 2):
        _assert_reads_as_volume(tmp_path / name, frame=frame)
    with pytest.raises(InputError, match="holds 3 volumes") as info:
        io.open_stack(tmp_path / name)
    assert info.value.parameter == "frame"


# a 4-D NRRD's frame axis, fastest first (3D Slicer's sequences), in the middle, or slowest (frame after frame)
FRAME_AXES = [0, 2, 3]


@pytest.mark.parametrize("encoding", ["raw", "gzip", "bzip2"])
@pytest.mark.parametrize("axis", FRAME_AXES)
def test_a_frame_of_a_4d_nrrd(tmp_path, encoding, axis):
    spatial = [[1, 0, 0], [0, 1, 0], [0, 0, 2]]
    directions = spatial[:axis] + [[np.nan] * 3] + spatial[axis:]
    kinds = ["domain"] * 3
    kinds.insert(axis, "list")
    shape = [5, 4, 6]                                            # x, y, z: NRRD's order, fastest first
    shape.insert(axis, 3)
    data = np.random.default_rng(4).integers(0, 1000, shape[::-1]).astype(np.uint16)
    nrrd.write(str(tmp_path / "four.nrrd"), data, {"space": "left-posterior-superior", "kinds": kinds,
                                                   "space directions": directions, "encoding": encoding},
               index_order="C")
    for frame in (0, 1, 2):
        stack = _assert_reads_as_volume(tmp_path / "four.nrrd", frame=frame)
        assert stack.shape == (6, 4, 5)


@pytest.mark.parametrize("kind", [kind for kind in KINDS if "text" not in kind])
def test_a_file_cut_short_is_bad_input_when_its_slab_is_read(tmp_path, kind):
    """Raw voxels: the file's size says it when the stack is opened (or, cut after, when the slab is read);
    compressed ones: the stream, as it is read, when it ends before the slab does."""
    path = _write(tmp_path, kind, "LPS", _canonical((12, 30, 40), seed=5))
    data = next((p for p in tmp_path.iterdir() if p.suffix not in (".nhdr", ".mhd")), path)   # the voxels' file
    whole = data.read_bytes()
    if not any(word in kind for word in ("gzip", "bzip2", "zlib")):
        stack = io.open_stack(path)
        data.write_bytes(whole[:len(whole) - 100])
        stack.read_slices(0, 1)
        with pytest.raises(InputError, match=f"{data.name} ends within slice 11; the file is truncated"):
            stack.read_slices(10, 12)
        with pytest.raises(InputError, match=f"{data.name} holds .* of voxels, of the .* its header promises"):
            io.open_stack(path)
        return
    data.write_bytes(whole[:len(whole) * 3 // 4])
    stack = io.open_stack(path)
    streamed = "bzip2" not in kind                               # bzip2 gives nothing of a block cut short
    if streamed:
        assert stack.read_slices(0, 2).shape == (2, 30, 40)
    with pytest.raises(InputError, match=f"stream of .*{data.name} (holds .* of the .* its header promises; the "
                                         "file is cut short|is damaged after)"):
        for z0, z1 in _slabs(12, 2):
            stack.read_slices(z0, z1)
    if streamed:
        assert stack.read_slices(0, 1).shape == (1, 30, 40)      # read again from the start, after the error


@pytest.mark.parametrize("codec", ["gzip", "bzip2"])
def test_a_damaged_stream_is_bad_input_when_its_slab_is_read(tmp_path, codec):
    path = _write(tmp_path, f"nrrd {codec}", "LPS", _canonical((12, 30, 40), seed=6))
    whole = bytearray(path.read_bytes())
    whole[len(whole) * 2 // 3:len(whole) * 2 // 3 + 64] = bytes(range(64))
    path.write_bytes(bytes(whole))
    stack = io.open_stack(path)
    with pytest.raises(InputError, match=f"the {codec} stream of .*v.nrrd"):
        for z0, z1 in _slabs(12, 3):
            stack.read_slices(z0, z1)


def _mha(path, dims, payload, compressed):
    header = (f"NDims = 3\nDimSize = {dims}\nElementType = MET_SHORT\nCompressedData = {compressed}\n"
              "ElementDataFile = LOCAL\n")
    path.write_bytes(header.encode() + payload)
    return path


def test_a_stream_longer_than_promised_is_refused_at_its_last_slab(tmp_path, monkeypatch):
    """A bomb is inflated no further than promised (and one byte)."""
    inflated = []
    real = _shared._inflated_chunks

    def counted(*args):
        for chunk in real(*args):
            inflated.append(len(chunk))
            yield chunk

    monkeypatch.setattr(_shared, "_inflated_chunks", counted)
    stack = io.open_stack(_mha(tmp_path / "bomb.mha", "10 10 10", zlib.compress(bytes(50_000_000)), True))
    assert stack.read_slices(0, 9).shape == (9, 10, 10)
    with pytest.raises(InputError, match="bomb.mha holds more than the 2 kB of voxels its header promises"):
        stack.read_slices(9, 10)
    assert sum(inflated) <= 2001


def test_a_header_promising_more_than_the_file_holds_is_refused_when_opened_or_read(tmp_path):
    with pytest.raises(InputError, match=r"holds 64 bytes of voxels, of the 54 TB its header promises"):
        io.open_stack(_mha(tmp_path / "raw.mha", "30000 30000 30000", bytes(64), False))
    stack = io.open_stack(_mha(tmp_path / "z.mha", "30000 30000 30000", zlib.compress(bytes(64)), True))
    with pytest.raises(InputError, match=r"the zlib stream of .*z.mha holds 64 bytes of voxels, of the 54 TB"):
        stack.read_slices(0, 1)


def test_slabs_in_order_inflate_the_stream_once(tmp_path, monkeypatch):
    starts = []
    real = _shared._inflated_chunks

    def counted(*args):
        starts.append(1)
        yield from real(*args)

    monkeypatch.setattr(_shared, "_inflated_chunks", counted)
    path = _write(tmp_path, "nifti gzip", "LPS", _canonical((12, 30, 40), seed=7))
    volume = io.read_volume(path).values
    stack = io.open_stack(path)
    assert stack.how == "stored order"
    starts.clear()
    whole = np.concatenate([stack.read_slices(z0, z1) for z0, z1 in _slabs(12, 2)])
    assert len(starts) == 1 and np.array_equal(whole, volume)
    stack.read_slices(0, 1)                                        # before the current position: from the start
    assert len(starts) == 2


@pytest.mark.parametrize("kind", ["nifti gzip", "nrrd bzip2", "mhd zlib"])
def test_slabs_across_the_inflated_chunks(tmp_path, monkeypatch, kind):
    """Chunks of 5 bytes: slices begin and end within chunks, and a slab spans many."""
    monkeypatch.setattr(_shared, "CHUNK", 5)
    _assert_reads_as_volume(_write(tmp_path, kind, "LPI"))


def test_opening_does_not_ask_for_the_free_memory(tmp_path, monkeypatch):
    """The point of a stack: it may be larger than memory (the volume is refused, its stack is not)."""
    paths = []
    for kind in ("nifti gzip", "nrrd raw", "mha zlib"):
        (tmp_path / kind).mkdir()
        paths.append(_write(tmp_path / kind, kind, "LPS"))
    monkeypatch.setattr(_shared, "free_memory", lambda: 100)
    for path in paths:
        with pytest.raises(InputError, match="more than the 100 bytes of memory free"):
            io.read_volume(path)
        assert io.open_stack(path).read_slices(0, 7).shape == (7, 6, 5)


def _read_all(path):
    """Open ``path`` and read its slabs, two slices at a time."""
    stack = io.open_stack(path)
    for z0, z1 in _slabs(stack.shape[0], 2):
        stack.read_slices(z0, z1)


@pytest.mark.parametrize("kind", KINDS)
def test_cut_files_are_bad_input(tmp_path, kind):
    """Cut at forty lengths, the header's file and the voxels' (when they are two): nothing but InputError."""
    path = _write(tmp_path, kind, "PIR")
    for cut in tmp_path.iterdir():
        assert refused_cuts(cut, lambda: _read_all(path)) >= (30 if cut == path else 20)
    _read_all(path)


def test_compressed_files_written_by_other_tools(tmp_path):
    """A gzip NRRD whose stream was made apart from pynrrd, and a bzip2 one, with a byte skip and line skip."""
    data = _canonical()
    header = ("NRRD0004\ntype: int16\ndimension: 3\nsizes: 5 6 7\nendian: little\nencoding: {}\n"
              "space: left-posterior-superior\nspace directions: (1,0,0) (0,1,0) (0,0,2)\n"
              "data file: v.raw\nline skip: 1\nbyte skip: 4\n")
    for encoding, compress in (("gzip", gzip.compress), ("bzip2", bz2.compress)):
        (tmp_path / "v.raw").write_bytes(b"a note\n" + compress(bytes(4) + data.tobytes()))
        (tmp_path / "v.nhdr").write_text(header.format(encoding))
        _assert_reads_as_volume(tmp_path / "v.nhdr")


def test_real_metaimage():
    _assert_reads_as_volume(data_path("headmr") / "HeadMRVolume.mhd")
