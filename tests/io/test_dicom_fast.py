"""voxrender.io.dicom reads plainly stored pixels straight from the files: the values are pydicom's, bit for bit."""

import numpy as np
import pydicom
import pytest
from conftest import data_path
from dicom_files import write_series
from pydicom.uid import ExplicitVRLittleEndian, ImplicitVRLittleEndian

from voxrender import io
from voxrender.errors import InputError
from voxrender.io import _dicom_header, _dicom_values, dicom


def recode(paths, syntax=ExplicitVRLittleEndian, allocated=16, stored=None, signed=True, raw=None, **elements):
    """Rewrite slice files (written by ``write_series``) with other pixels: ``raw[z]`` stored as ``allocated``-bit
    integers (``stored`` of them used, ``signed`` or not) in the transfer syntax ``syntax``; other ``elements`` set.
    """
    for z, path in enumerate(paths):
        ds = pydicom.dcmread(path)
        ds.BitsAllocated, ds.BitsStored, ds.HighBit = allocated, stored or allocated, (stored or allocated) - 1
        ds.PixelRepresentation = int(signed)
        if raw is not None:
            kind = f"<{'i' if signed else 'u'}{allocated // 8}"
            ds.PixelData = np.ascontiguousarray(raw[z]).astype(kind).tobytes()
            ds["PixelData"].VR = "OB" if allocated == 8 else "OW"
        for keyword, value in elements.items():
            setattr(ds, keyword, value)
        ds.file_meta.TransferSyntaxUID = syntax
        ds.save_as(path, enforce_file_format=True)
    return paths


def pydicom_read(path, monkeypatch, **options):
    """The volume as pydicom decodes every slice (the plain reading turned off)."""
    with monkeypatch.context() as patch:
        patch.setattr(dicom, "plain_pixels", lambda *args: None)
        return io.read_volume(path, **options).values


def plain_read(path, monkeypatch, **options):
    """The volume read plainly: pydicom decodes no slice."""
    def decoded(path):
        raise AssertionError(f"pydicom decoded {path}")

    with monkeypatch.context() as patch:
        patch.setattr(_dicom_values, "dicom_pixels", decoded)
        return io.read_volume(path, **options).values


def assert_same_values(path, monkeypatch, plain=True):
    """The plain reading gives pydicom's values and type, read whole or slab by slab (``plain``: no slice decoded
    by pydicom)."""
    expected = pydicom_read(path, monkeypatch)
    values = plain_read(path, monkeypatch) if plain else io.read_volume(path).values
    assert values.dtype == expected.dtype
    np.testing.assert_array_equal(values, expected)
    stack = io.open_stack(path)
    with monkeypatch.context() as patch:
        patch.setattr(dicom, "plain_pixels", lambda *args: None)
        slow = io.open_stack(path)
    assert stack.dtype == slow.dtype
    slabs = np.concatenate([stack.read_slices(z, min(z + 2, stack.shape[0])) for z in range(0, stack.shape[0], 2)])
    assert slabs.dtype == stack.dtype
    np.testing.assert_array_equal(slabs, slow.read_slices(0, slow.shape[0]))
    return values


RNG = np.random.default_rng(25)


@pytest.mark.parametrize("syntax", [ExplicitVRLittleEndian, ImplicitVRLittleEndian])
@pytest.mark.parametrize("slope, intercept", [(1, -1024), (1, 0), (3, -7), (0.5, 1.25)])
def test_signed_16_bit(tmp_path, monkeypatch, syntax, slope, intercept):
    raw = RNG.integers(-32768, 32768, (4, 6, 7))
    recode(write_series(tmp_path, np.zeros((4, 6, 7)), slope=slope, intercept=intercept), syntax, raw=raw)
    values = assert_same_values(tmp_path, monkeypatch)
    assert values.dtype == (np.float32 if slope == 0.5 else np.int32 if intercept or slope != 1 else np.int16)


@pytest.mark.parametrize("syntax", [ExplicitVRLittleEndian, ImplicitVRLittleEndian])
@pytest.mark.parametrize("high, intercept", [(65536, 0), (30000, -1024), (4096, 0), (65536, -32768)])
def test_unsigned_16_bit(tmp_path, monkeypatch, syntax, high, intercept):
    raw = RNG.integers(0, high, (3, 5, 8))
    recode(write_series(tmp_path, np.zeros((3, 5, 8)), intercept=intercept), syntax, signed=False, raw=raw)
    assert_same_values(tmp_path, monkeypatch)


@pytest.mark.parametrize("signed", [True, False])
@pytest.mark.parametrize("syntax", [ExplicitVRLittleEndian, ImplicitVRLittleEndian])
def test_12_bits_stored_with_other_bits_set(tmp_path, monkeypatch, syntax, signed):
    """BitsStored 12 of 16: pydicom sign-extends a signed value from its 12th bit and clears an unsigned one's
    high bits; the files' high bits hold anything (what some scanners write there)."""
    values = RNG.integers(-2048, 2048, (3, 6, 6)) if signed else RNG.integers(0, 4096, (3, 6, 6))
    raw = (values & 0x0FFF) | (RNG.integers(0, 16, values.shape) << 12)
    raw = raw.astype(np.uint16).view(np.int16) if signed else raw
    recode(write_series(tmp_path, np.zeros((3, 6, 6)), intercept=-1024), syntax, stored=12, signed=signed, raw=raw)
    read = assert_same_values(tmp_path, monkeypatch)
    np.testing.assert_array_equal(read, values - 1024)
    assert read.min() < -1024 if signed else read.min() >= -1024


@pytest.mark.parametrize("signed", [True, False])
@pytest.mark.parametrize("syntax", [ExplicitVRLittleEndian, ImplicitVRLittleEndian])
def test_8_bit_of_odd_length(tmp_path, monkeypatch, syntax, signed):
    """5 x 7 bytes a slice: the pixel data is padded to an even length."""
    raw = RNG.integers(-128, 128, (3, 5, 7)) if signed else RNG.integers(0, 256, (3, 5, 7))
    recode(write_series(tmp_path, np.zeros((3, 5, 7)), intercept=0), syntax, allocated=8, signed=signed, raw=raw)
    np.testing.assert_array_equal(assert_same_values(tmp_path, monkeypatch), raw)


@pytest.mark.parametrize("signed", [True, False])
@pytest.mark.parametrize("stored, slope, intercept", [(32, 1, 0), (20, 1, -1024), (32, 2, 1), (32, 0.25, 0)])
def test_32_bit(tmp_path, monkeypatch, signed, stored, slope, intercept):
    low, high = (-(1 << (stored - 1)), 1 << (stored - 1)) if signed else (0, 1 << stored)
    raw = RNG.integers(low, high, (3, 4, 5))
    raw[0] = RNG.integers(-100, 100, (4, 5)) if signed else RNG.integers(0, 100, (4, 5))    # int16, the others not
    recode(write_series(tmp_path, np.zeros((3, 4, 5)), slope=slope, intercept=intercept), allocated=32,
           stored=stored, signed=signed, raw=raw)
    assert_same_values(tmp_path, monkeypatch)


@pytest.mark.parametrize("intercepts, dtype", [((-1024, 10000, -1024), np.int32),
                                               ((-1024, 0.5, -1024), np.float32),
                                               ((0.5, -1024, 10000), np.float64)])     # float32, int32
def test_slices_rescaled_to_other_types_widen_the_volume(tmp_path, monkeypatch, intercepts, dtype):
    raw = RNG.integers(0, 30000, (3, 4, 4))
    paths = write_series(tmp_path, raw, names=["a.dcm", "b.dcm", "c.dcm"])
    for path, values, intercept in zip(paths, raw, intercepts, strict=True):
        recode([path], raw=values[None], RescaleIntercept=intercept)
    assert assert_same_values(tmp_path, monkeypatch).dtype == dtype


def test_slices_stored_in_other_types(tmp_path, monkeypatch):
    """Slices stored as signed and unsigned values are each read plainly, the volume as wide as they need."""
    raw = RNG.integers(0, 30000, (4, 4, 6))
    paths = write_series(tmp_path, raw)
    recode(paths[1:2], signed=False, raw=raw[1:2] + 30000)
    recode(paths[2:3], ImplicitVRLittleEndian, raw=raw[2:3])
    assert assert_same_values(tmp_path, monkeypatch).dtype == np.int32


def test_a_header_longer_than_the_first_read_is_read_from_the_file(tmp_path, monkeypatch):
    raw = RNG.integers(-2000, 2000, (3, 4, 4))
    recode(write_series(tmp_path, np.zeros((3, 4, 4))), raw=raw, ImageComments="x" * 5000)
    monkeypatch.setattr(_dicom_header, "HEADER_BYTES", 1000)
    np.testing.assert_array_equal(assert_same_values(tmp_path, monkeypatch), raw - 1024)


@pytest.mark.filterwarnings("ignore:The pixel data is 34 bytes long")
def test_only_plain_pixels_are_read_plainly(tmp_path, monkeypatch):
    """Compressed, big endian and colour slices, and those whose pixel data is not as long as their pixels, are
    pydicom's to decode."""
    from pydicom.uid import RLELossless

    paths = write_series(tmp_path, RNG.integers(0, 2000, (4, 4, 4)), names=[f"{k}.dcm" for k in range(4)])
    ds = pydicom.dcmread(paths[0])
    ds.compress(RLELossless, ds.pixel_array)
    ds.save_as(paths[0])
    recode(paths[1:2], PhotometricInterpretation="PALETTE COLOR")
    ds = pydicom.dcmread(paths[2])
    ds.PixelData += b"\0\0"
    ds.save_as(paths[2])
    headers = {path: _dicom_header.read_header(path) for path in paths}
    plain = {path.name: _dicom_header.plain_pixels(*headers[path]) for path in paths}
    assert plain == {"0.dcm": None, "1.dcm": None, "2.dcm": None, "3.dcm": plain["3.dcm"]}
    assert plain["3.dcm"].dtype == np.int16 and plain["3.dcm"].shift == 0
    assert_same_values(tmp_path, monkeypatch, plain=False)


@pytest.mark.parametrize("cut", [2, 30, 31])
def test_a_file_cut_within_its_pixels_is_one_line(tmp_path, cut):
    paths = write_series(tmp_path, np.zeros((3, 8, 8)))
    stack = io.open_stack(tmp_path)
    paths[1].write_bytes(paths[1].read_bytes()[:-cut])
    message = (f"cannot read the pixels of DICOM file {paths[1]}: it holds {128 - cut} of the 128 bytes of its pixel "
               "data; the file is truncated")
    with pytest.raises(InputError) as info:
        io.read_volume(tmp_path)
    assert str(info.value) == message
    with pytest.raises(InputError) as info:
        stack.read_slices(0, 3)
    assert str(info.value) == message


def test_vhf_head(monkeypatch):
    path = data_path("vhf_head")
    expected = pydicom_read(path, monkeypatch)
    values = plain_read(path, monkeypatch)
    assert values.dtype == expected.dtype == np.int16 and values.shape == (234, 512, 512)
    np.testing.assert_array_equal(values, expected)



def test_header_values_stored_alike_are_decoded_once():
    """The header pass decodes a value stored as an earlier file's only when it is asked; one stored otherwise
    (here damaged: three bytes of an unsigned short) is decoded, and fails, at once."""
    from pydicom.dataelem import RawDataElement
    from pydicom.dataset import Dataset
    from pydicom.errors import BytesLengthException

    def header(rows):
        return Dataset({0x00280010: RawDataElement(pydicom.tag.BaseTag(0x00280010), "US", len(rows), rows, 0, False,
                                                   True)})

    first, alike, damaged, decoded = header(b"\x03\x00"), header(b"\x03\x00"), header(b"\x03\x00\x00"), {}
    _dicom_header.decode_header(first, decoded)
    _dicom_header.decode_header(alike, decoded)
    assert not isinstance(first.get_item(0x00280010), RawDataElement)
    assert isinstance(alike.get_item(0x00280010), RawDataElement) and alike.Rows == first.Rows == 3
    with pytest.raises(BytesLengthException):
        _dicom_header.decode_header(damaged, decoded)


def test_a_file_cut_in_its_header_is_one_line(tmp_path):
    """Cut within its image pixel elements (0028,xxxx), a header ends in a value too short for its VR: the plain
    reading does not take it, and pydicom's (or the header checks) say what is wrong in one line, for the whole
    volume and slab by slab."""
    paths = write_series(tmp_path, np.zeros((3, 8, 8)))
    whole = paths[1].read_bytes()
    start = whole.index(b"\x28\x00\x02\x00")                        # SamplesPerPixel, the module's first
    for cut in range(start, whole.index(b"\xe0\x7f\x10\x00")):     # to the pixel data element
        paths[1].write_bytes(whole[:cut])
        for read in (io.read_volume, lambda path: io.open_stack(path).read_slices(0, 3)):
            with pytest.raises(InputError) as info:
                read(tmp_path)
            assert "\n" not in str(info.value)


@pytest.mark.parametrize("damage", ["cut", "garbled"])
def test_a_damaged_deflated_file_is_one_line(tmp_path, monkeypatch, damage):
    """A deflated data set (never read plainly) that is cut or garbled is a damaged file, not zlib's traceback."""
    from pydicom.uid import DeflatedExplicitVRLittleEndian

    raw = RNG.integers(-2000, 2000, (3, 6, 7))
    paths = recode(write_series(tmp_path, np.zeros((3, 6, 7))), DeflatedExplicitVRLittleEndian, raw=raw)
    assert all(_dicom_header.plain_pixels(*_dicom_header.read_header(path)) is None for path in paths)
    np.testing.assert_array_equal(assert_same_values(tmp_path, monkeypatch, plain=False), raw - 1024)
    whole = paths[1].read_bytes()
    middle = len(whole) // 2
    paths[1].write_bytes(whole[:-20] if damage == "cut" else whole[:middle] + b"\x55" * 40 + whole[middle + 40:])
    with pytest.raises(InputError, match=f"cannot read DICOM file {paths[1]}: Error -"):
        io.read_volume(tmp_path)


def test_monochrome1_and_bytes_after_the_pixels_are_read_plainly(tmp_path, monkeypatch):
    """MONOCHROME1 is not inverted (pydicom's pixel_array does not invert it); a trailing padding element and stray
    bytes after the pixel data are not read."""
    raw = RNG.integers(0, 4096, (3, 5, 6))
    paths = recode(write_series(tmp_path, np.zeros((3, 5, 6))), raw=raw, signed=False, stored=12,
                   PhotometricInterpretation="MONOCHROME1", DataSetTrailingPadding=b"\xff" * 64)
    for path in paths:
        path.write_bytes(path.read_bytes() + b"\x01\x02" * 33)
    np.testing.assert_array_equal(assert_same_values(tmp_path, monkeypatch), raw - 1024)


def _write_encoded(path, ds, implicit, little):
    """``ds`` written with its file meta as it is but its data set in the encoding given, whatever the meta says."""
    from pydicom.filebase import DicomBytesIO
    from pydicom.filewriter import write_dataset, write_file_meta_info

    out = DicomBytesIO()
    out.write(b"\0" * 128 + b"DICM")
    write_file_meta_info(out, ds.file_meta, enforce_standard=True)
    out.is_implicit_VR, out.is_little_endian = implicit, little
    write_dataset(out, ds)
    path.write_bytes(out.getvalue())


@pytest.mark.filterwarnings("ignore:Expected explicit VR", "ignore:Expected implicit VR")
@pytest.mark.parametrize("case", ["big endian", "meta says explicit", "meta says implicit", "float pixel data"])
def test_files_pydicom_reads_otherwise_are_left_to_it(tmp_path, monkeypatch, case):
    """Big endian, a data set encoded otherwise than its file meta says (pydicom reads it as it finds it), and
    Float Pixel Data before the Pixel Data (pydicom refuses both) are not read plainly."""
    from pydicom.uid import ExplicitVRBigEndian

    raw = RNG.integers(-2000, 2000, (3, 5, 6))
    paths = write_series(tmp_path, raw)
    for path in paths:
        ds = pydicom.dcmread(path)
        if case == "big endian":
            ds.PixelData = ds.pixel_array.astype(">i2").tobytes()
            ds.file_meta.TransferSyntaxUID = ExplicitVRBigEndian
            _write_encoded(path, ds, False, False)
        elif case == "float pixel data":
            ds.FloatPixelData = np.ones(30, "<f4").tobytes()
            ds.save_as(path)
        else:
            ds.file_meta.TransferSyntaxUID = ExplicitVRLittleEndian if case.endswith("explicit") else \
                ImplicitVRLittleEndian
            _write_encoded(path, ds, case.endswith("explicit"), True)
    assert all(_dicom_header.plain_pixels(*_dicom_header.read_header(path)) is None for path in paths)
    if case == "float pixel data":
        with pytest.raises(InputError, match="One and only one of 'Pixel Data', 'Float Pixel Data'"):
            io.read_volume(tmp_path)
    else:
        np.testing.assert_array_equal(assert_same_values(tmp_path, monkeypatch, plain=False), raw - 1024)


@pytest.mark.filterwarnings("ignore:Invalid value for VR UI")
def test_a_damaged_series_uid_is_listed_on_one_line(tmp_path):
    """A byte of a slice's SeriesInstanceUID garbled into a newline makes a second series: the message that lists
    them stays one line."""
    paths = write_series(tmp_path, np.zeros((3, 4, 4)), series_uid="1.2.3.4")
    paths[1].write_bytes(paths[1].read_bytes().replace(b"1.2.3.4", b"1.2\n3.4"))
    with pytest.raises(InputError, match="holds 2 DICOM series") as info:
        io.read_volume(tmp_path)
    assert "\n" not in str(info.value) and "1.2\\n3.4 (1 slices, test)" in str(info.value)
