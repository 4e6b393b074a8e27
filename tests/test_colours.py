"""Colour tables in four formats, the built-in palette, named colours, the tissue presets."""

import json

import numpy as np
import pytest

from voxrender.errors import InputError
from voxrender.pictures.colours import PRESETS, label_colours, named_colour, palette, preset, read_colour_table

EXPECTED = {1: ("liver", (200, 100, 50)), 7: ("left kidney", (0, 128, 255))}


def test_a_table_reads_the_same_from_every_format(tmp_path):
    files = {
        "t.csv": "label,name,r,g,b\n1,liver,200,100,50\n7,left kidney,0,128,255\n",
        "t.json": json.dumps([{"label": 1, "name": "liver", "colour": [200, 100, 50]},
                              {"label": 7, "name": "left kidney", "r": 0, "g": 128, "b": 255}]),
        "t.ctbl": "# Color table file\n# 2 values\n1 liver 200 100 50 255\n7 left\\ kidney 0 128 255 255\n",
        "itk.txt": '# ITK-SnAP Label Description File\n    0     0    0    0        0  0  0    "Clear Label"\n'
                   '    1   200  100   50        1  1  1    "liver"\n    7     0  128  255        1  1  1    '
                   '"left kidney"\n',
    }
    for name, text in files.items():
        (tmp_path / name).write_text(text)
        assert read_colour_table(tmp_path / name) == EXPECTED, name
    (tmp_path / "d.json").write_text(json.dumps({"1": {"name": "liver", "colour": [200, 100, 50]},
                                                 "7": {"name": "left kidney", "colour": [0, 128, 255]}}))
    assert read_colour_table(tmp_path / "d.json") == EXPECTED


@pytest.mark.parametrize("name,text,where", [
    ("bad.csv", "label,name,r,g,b\n1,liver,200,100,50\n2,spleen,300,0,0\n", "row 3"),
    ("bad.csv", "1,liver,200,100\n", "row 1"),
    ("bad.json", json.dumps([{"label": "x", "name": "a", "colour": [1, 2, 3]}]), "row 1"),
    ("bad.json", "{not json", "not JSON"),
    ("bad.ctbl", "1 liver 200 100 50 255\nseven kidney 1 2 3 255\n", "line 2"),
    ("empty.csv", "label,name,r,g,b\n", "no label"),
])
def test_a_bad_table_names_its_row(tmp_path, name, text, where):
    (tmp_path / name).write_text(text)
    with pytest.raises(InputError, match=where):
        read_colour_table(tmp_path / name)


def test_a_missing_table_is_one_error(tmp_path):
    with pytest.raises(InputError, match="cannot read"):
        read_colour_table(tmp_path / "none.csv")


def test_the_palette_keeps_neighbouring_labels_apart():
    colours = palette(range(1, 118))                         # TotalSegmentator's 117 classes
    for label in range(1, 117):
        a, b = np.array(colours[label], float), np.array(colours[label + 1], float)
        assert np.linalg.norm(a - b) > 60, label
    assert len(set(palette(range(1, 21)).values())) == 20


def test_precedence_given_then_stored_then_palette():
    stored = {"1": {"name": "from seg.nrrd", "colour": [1, 2, 3]}, "2": {"name": "two", "colour": [4, 5, 6]}}
    table = label_colours([1, 2, 3], stored, {1: ("given", (9, 9, 9))})
    assert table == {1: ("given", (9, 9, 9)), 2: ("two", (4, 5, 6)), 3: ("label 3", palette([3])[3])}


def test_named_colours():
    assert named_colour("#FF0080") == (255, 0, 128) and named_colour("Bone") == PRESETS["bone"].colour
    for bad in ("#ff00", "no-such-colour", "1,2,300"):
        with pytest.raises(InputError):
            named_colour(bad)


def test_presets_are_windows_with_colours_and_sources():
    assert set(PRESETS) == {"bone", "skin", "soft-tissue", "contrast-vessels", "lung"}
    for tissue in PRESETS.values():
        assert tissue.source and len(tissue.colour) == 3
    assert preset("lung").window.select(np.array([-1000, -700, 0])).tolist() == [False, True, False]
    with pytest.raises(InputError, match="unknown preset 'liver'"):
        preset("liver")


@pytest.mark.parametrize("name, content, message", [
    ("latin.csv", "1,café,200,100,50\n".encode("latin-1"), r"is not UTF-8 text \(byte 0xe9 at 5\)"),
    ("binary.csv", bytes(range(256)), "is not UTF-8 text"),
    ("huge.csv", b"1,liver,200,100,50\n2," + b"x" * 200_000 + b",1,2,3\n", "is not a CSV table"),
    ("inf.csv", b"1,liver,inf,100,50\n", "row 1"),
    ("inf.ctbl", b"1 liver 1e400 100 50 255\n", "line 1"),
    ("deep.json", b"[" * 100_000 + b"]" * 100_000, "nests its JSON too deep"),
])
def test_a_damaged_table_is_one_error(tmp_path, name, content, message):
    """Each was an internal error (exit 1): a table not in UTF-8 (found by the fuzzing gate), a field beyond csv's
    limit, a colour of inf, JSON nested beyond Python's recursion."""
    (tmp_path / name).write_bytes(content)
    with pytest.raises(InputError, match=message) as info:
        read_colour_table(tmp_path / name)
    assert info.value.parameter == "colours"
