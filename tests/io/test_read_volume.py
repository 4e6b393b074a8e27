"""voxrender.io.read_volume: options, the recipe for a new format, and bugs that stay bugs."""

import json
import types
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from formats import phantom, random_stack, stored, write_dicom, write_metaimage, write_nifti, write_nrrd

from voxrender import io
from voxrender.cli import main
from voxrender.errors import InputError
from voxrender.outputs.output import write_slices


def test_natural_key_orders_numbers():
    names = [f"quarter.{i}" for i in (10, 2, 1, 93, 11)]
    assert sorted(names, key=io.natural_key) == ["quarter.1", "quarter.2", "quarter.10", "quarter.11", "quarter.93"]


def test_a_format_refuses_options_it_does_not_take(tmp_path):
    np.save(tmp_path / "v.npy", random_stack())
    with pytest.raises(InputError, match="npy input takes no series") as info:
        io.read_volume(tmp_path / "v.npy", series="1.2.3")
    assert info.value.parameter == "series"


def test_an_unknown_format(tmp_path):
    with pytest.raises(InputError, match="unknown format 'png'; choose one of auto, seg, zarr, dicom, masks") as info:
        io.read_volume(tmp_path, format="png")
    assert info.value.parameter == "format"


def test_spacing_override(tmp_path):
    np.save(tmp_path / "v.npy", random_stack())
    assert io.read_volume(tmp_path / "v.npy", spacing=(1, 2, 3)).spacing == (1.0, 2.0, 3.0)
    with pytest.raises(InputError):
        io.read_volume(tmp_path / "v.npy", spacing=(1, 0, 3))


# ------------------------------------------------------------------ the recipe "add a format" (docs/design.md)

def read_toy(path, progress):
    """A toy format written by the recipe: JSON with ``"toy": 1``, ``values`` [z][y][x] and ``spacing`` (x, y, z)."""
    data = json.loads(Path(path).read_text())
    values = np.asarray(data["values"], np.int16)
    return io.Volume(values, tuple(data["spacing"]), {"spacing_from": "toy header"})


def is_toy(path):
    """A toy file without its suffix, by its first bytes."""
    if not path.is_file():
        return False
    with open(path, "rb") as f:
        return f.read(9) == b'{"toy": 1'


# The recipe's module: its reading function and its record (here a module object, as voxrender/io/toy.py would be).
toy = types.ModuleType("toy")
toy.read_toy, toy.is_toy = read_toy, is_toy
toy.READER = io.Reader(read_toy, suffixes=(".toy",), sniff=is_toy)


def test_a_toy_format_added_by_the_recipe(tmp_path, monkeypatch):
    from voxrender.object.pipeline import PrepOptions, load_segments

    monkeypatch.setitem(io.READERS, "toy", toy.READER)          # its line in READERS
    values = np.zeros((3, 4, 5), int)
    values[1, 1:3, 1:4] = 100
    text = json.dumps({"toy": 1, "values": values.tolist(), "spacing": [1, 1, 2]})
    (tmp_path / "box.toy").write_text(text)
    volume = io.read_volume(tmp_path / "box.toy")
    assert volume.meta["format"] == "toy" and volume.spacing == (1, 1, 2)
    assert np.array_equal(volume.values, values)
    (tmp_path / "box").write_text(text)                        # no suffix: its sniff knows it
    assert io.detect_format(tmp_path / "box") == "toy"
    encoded = load_segments(tmp_path / "box.toy", prepare=PrepOptions(threshold=50, resample=False))
    assert encoded.segments.voxel_count == 6
    with pytest.raises(InputError, match="toy input takes no series"):
        io.read_volume(tmp_path / "box.toy", series="1.2")


# ------------------------------------------------------------------ bugs stay bugs

def small_input(format, folder):
    """A small valid input of ``format`` in ``folder``, and the command-line options it needs."""
    folder.mkdir()
    values, spacing, direction = stored(phantom(), "LPS")
    if format == "images":
        return write_slices(values.astype(np.uint16), folder / "slices"), []
    if format == "tiff":
        import tifffile

        tifffile.imwrite(folder / "v.tif", values.astype(np.uint16))
        return folder / "v.tif", []
    if format == "raw":
        values.astype("<u2").tofile(folder / "v.raw")
        return folder / "v.raw", ["--raw", f"{values.shape[2]}x{values.shape[1]}:uint16:little"]
    if format == "npy":
        np.save(folder / "v.npy", values)
        return folder / "v.npy", []
    if format == "dicom":
        write_dicom(folder / "series", values, spacing, direction)
        return folder / "series", []
    writer = {"nifti": write_nifti, "nrrd": write_nrrd, "metaimage": write_metaimage}[format]
    return writer(folder / {"nifti": "v.nii", "nrrd": "v.nrrd", "metaimage": "v.mha"}[format], values, spacing,
                  direction), []


def info(path, options):
    return CliRunner().invoke(main, ["info", str(path), *options])


# Each reader's call into its library (or, for MetaImage, which has none, its own header parser).
LIBRARY_CALLS = {"images": "imageio.v3.imread", "tiff": "tifffile.TiffPageSeries.asarray", "dicom": "pydicom.dcmread",
                 "nifti": "nibabel.load", "nrrd": "nrrd.read_header", "npy": "numpy.load", "raw": "numpy.fromfile",
                 "metaimage": "voxrender.io.metaimage._metaimage_direction"}


@pytest.mark.parametrize("format", sorted(LIBRARY_CALLS))
def test_a_bug_in_a_reading_call_is_an_internal_error(tmp_path, monkeypatch, format):
    """A reader turns only its library's errors for a damaged file into bad input: any other one, from a bug, ends
    the command with exit status 1, as an internal error."""
    path, options = small_input(format, tmp_path / format)
    assert info(path, options).exit_code == 0

    def bug(*args, **kwargs):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(LIBRARY_CALLS[format], bug)
    result = info(path, options)
    assert result.exit_code == 1, result.output
    assert result.stderr.startswith("internal error: ZeroDivisionError: a bug")


@pytest.mark.parametrize("format, function", [("images", "voxrender.io.images.to_grey"),
                                              ("dicom", "voxrender.io.dicom._slices_placed"),
                                              ("nifti", "voxrender.io.nifti.check_spacing")])
def test_a_bug_in_a_reader_is_an_internal_error(tmp_path, monkeypatch, format, function):
    path, options = small_input(format, tmp_path / format)

    def bug(*args, **kwargs):
        raise TypeError("a bug")

    monkeypatch.setattr(function, bug)
    result = info(path, options)
    assert result.exit_code == 1 and result.stderr.startswith("internal error: TypeError: a bug"), result.output


def test_running_out_of_memory_is_not_a_damaged_file(tmp_path, monkeypatch):
    path, _ = small_input("images", tmp_path / "images")

    def out_of_memory(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr("imageio.v3.imread", out_of_memory)
    with pytest.raises(MemoryError):
        io.read_volume(path)
    result = info(path, [])
    assert result.exit_code == 1 and result.stderr.startswith("internal error: out of memory")


def test_voxels_become_real_numbers_the_renderers_take(tmp_path):
    """A boolean TIFF ended in numpy's 'boolean subtract' (exit 1), found by fuzzing the readers; complex NIfTI
    values in 'a must be an array of real numbers' (exit 1); 16-bit floats become 32-bit ones."""
    import nibabel
    import tifffile

    tifffile.imwrite(tmp_path / "mask.tif", np.ones((3, 4, 5), bool))
    tifffile.imwrite(tmp_path / "half.tif", np.full((3, 4, 5), 0.5, np.float16))
    nibabel.save(nibabel.Nifti1Image(np.ones((5, 4, 3), np.complex64), np.eye(4)), str(tmp_path / "complex.nii"))
    assert io.read_volume(tmp_path / "mask.tif").values.dtype == np.uint8
    half = io.read_volume(tmp_path / "half.tif").values
    assert half.dtype == np.float32 and np.all(half == 0.5)
    with pytest.raises(InputError, match="complex.nii holds complex64 values; voxrender needs real numbers"):
        io.read_volume(tmp_path / "complex.nii")


def test_sizes_that_round_alike_are_given_in_bytes():
    """Found auditing the fuzzing gate's lines: 'holds 15.8 kB of voxels, more than the 15.8 kB its header promises'."""
    from voxrender.io._shared import check_holds

    with pytest.raises(InputError, match="holds 15841 bytes of voxels, more than the 15840 bytes its header promises"):
        check_holds("x.nrrd", 15840, 15841, exact=True)
    with pytest.raises(InputError, match="holds 9.29 kB of voxels, of the 15.8 kB its header promises"):
        check_holds("x.nii", 15840, 9290)


@pytest.mark.parametrize("name", ["x.nii.gz", "x.nrrd", "seg.dcm", "x.npy", "x.tif", "x.mha"])
def test_an_empty_file_says_so_whatever_its_format(tmp_path, name):
    """Each reader said it its own way, and an empty .dcm was told to 'give the folder that holds the series'."""
    (tmp_path / name).write_bytes(b"")
    with pytest.raises(InputError, match=f"{name} is an empty file"):
        io.read_volume(tmp_path / name)
