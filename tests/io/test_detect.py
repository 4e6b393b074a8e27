"""voxrender.io.detect_format: the readers' records, asked in the order of READERS."""

import imageio.v3 as iio
import nibabel
import numpy as np
import pytest
from dicom_files import write_series

from voxrender import io
from voxrender.errors import InputError


def test_missing_and_empty_and_unknown(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        io.read_volume(tmp_path / "nope")
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError, match="empty folder"):
        io.read_volume(empty)
    notes = tmp_path / "notes"
    notes.mkdir()
    (notes / "a.txt").write_text("hello")
    with pytest.raises(InputError, match="headerless slices give their layout") as info:
        io.read_volume(notes)
    assert info.value.parameter == "raw"
    (tmp_path / "thing.xyz").write_text("?")
    with pytest.raises(InputError, match="cannot tell the format"):
        io.read_volume(tmp_path / "thing.xyz")


def test_an_unknown_folder_says_what_it_holds(tmp_path):
    for name in ("b.dat", "a.dat", "c.dat", "d.dat"):
        (tmp_path / name).write_bytes(b"\0" * 8)
    with pytest.raises(InputError, match=r"holds 4 files \(a.dat, b.dat, c.dat, ...\) but no DICOM files, images"):
        io.detect_format(tmp_path)
    nested = tmp_path / "outer"
    (nested / "inner").mkdir(parents=True)                     # folders only, and no DICOM files below
    with pytest.raises(InputError, match="empty folder"):
        io.detect_format(nested)


def test_suffixes_first_then_sniffing_in_the_order_of_readers(tmp_path):
    assert list(io.READERS)[:5] == ["seg", "zarr", "dicom", "masks", "images"] and io.FORMATS[0] == "auto"
    np.save(tmp_path / "v.npy", np.zeros((2, 3, 4)))
    assert io.detect_format(tmp_path / "v.npy") == "npy"
    assert io.detect_format(tmp_path / "v.npy", raw=io.RawLayout(4, 3, np.dtype("u1"))) == "raw"
    folder = tmp_path / "both"
    write_series(folder / "series", np.zeros((2, 4, 4)))       # DICOM files below, an image beside them
    iio.imwrite(folder / "preview.png", np.zeros((4, 4), np.uint8))
    assert io.detect_format(folder) == "dicom"
    masks = tmp_path / "segmentations"                         # masks with a preview picture: masks, not slices
    masks.mkdir()
    for name in ("liver.nii.gz", "spleen.nii.gz"):
        nibabel.save(nibabel.Nifti1Image(np.ones((2, 2, 2), np.uint8), np.eye(4)), masks / name)
    iio.imwrite(masks / "preview_total.png", np.zeros((4, 4), np.uint8))
    assert io.detect_format(masks) == "masks"
    for k in range(3):                                         # more pictures than volume files: a stack of slices
        iio.imwrite(masks / f"slice{k}.png", np.zeros((4, 4), np.uint8))
    assert io.detect_format(masks) == "images"


def test_every_reader_that_sniffs_answers_without_raising(tmp_path):
    (tmp_path / "a.txt").write_text("hello")
    for reader in io.READERS.values():
        if reader.sniff is not None:
            assert reader.sniff(tmp_path) is False and reader.sniff(tmp_path / "a.txt") is False


def test_a_device_is_neither_a_file_nor_a_folder():
    """Found by the fuzzing gate: a manifest row of /dev/null ended in NotADirectoryError (exit 1)."""
    with pytest.raises(InputError, match="/dev/null is neither a file nor a folder"):
        io.detect_format("/dev/null")
