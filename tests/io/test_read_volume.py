"""voxrender.io.read_volume: options, and the recipe for a new format."""

import json
import types
from pathlib import Path

import numpy as np
import pytest
from formats import random_stack

from voxrender import io
from voxrender.errors import InputError


def test_natural_key_orders_numbers():
    names = [f"quarter.{i}" for i in (10, 2, 1, 93, 11)]
    assert sorted(names, key=io.natural_key) == ["quarter.1", "quarter.2", "quarter.10", "quarter.11", "quarter.93"]


def test_a_format_refuses_options_it_does_not_take(tmp_path):
    np.save(tmp_path / "v.npy", random_stack())
    with pytest.raises(InputError, match="npy input takes no series") as info:
        io.read_volume(tmp_path / "v.npy", series="1.2.3")
    assert info.value.parameter == "series"


def test_an_unknown_format(tmp_path):
    with pytest.raises(InputError, match="unknown format 'png'; choose one of auto, dicom, images") as info:
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
    from voxrender.pipeline import PrepOptions, load_segments

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
