"""Levels of detail (issue 35): the object at 2, 4 and 8 times coarser voxels, made from its runs, kept in the
``.vxs`` and drawn when a picture's pixel is as large as their voxel.

The literal oracle of :func:`voxrender.object.levels.coarser` is the mask itself binned by NumPy: a coarse voxel
is in the object when any of its fine voxels is (the largest label among them); each level is then a volume of
its own, held to the exact reference like any other.
"""

import json

import imageio.v3 as iio
import numpy as np
import pytest
from test_cli import assert_bad_input, run
from test_contract import check, torus

from voxrender._render import render
from voxrender.errors import InputError
from voxrender.object import levels, segments, vxs
from voxrender.object.normals import (
    SurfaceNormals,
    octahedral_decode,
    octahedral_encode,
    surface_band,
    surface_normals,
)
from voxrender.pictures import RenderOptions, level_for
from voxrender.space.view import PRESETS, View


def binned(values, factor):
    """The literal oracle: ``values`` padded to whole coarse voxels and reduced by their largest value."""
    padded = np.pad(values, [(0, -n % factor) for n in values.shape])
    nz, ny, nx = (n // factor for n in padded.shape)
    return padded.reshape(nz, factor, ny, factor, nx, factor).max(axis=(1, 3, 5))


def same_runs(a, b):
    return (a.shape == b.shape and np.array_equal(a.offsets, b.offsets) and np.array_equal(a.starts, b.starts)
            and np.array_equal(a.ends, b.ends)
            and (a.labels is None) == (b.labels is None) and (a.labels is None or np.array_equal(a.labels, b.labels)))


@pytest.mark.parametrize("shape", [(9, 11, 10), (16, 16, 16), (5, 3, 7), (1, 1, 1), (3, 40, 2)])
@pytest.mark.parametrize("factor", [2, 3, 4])
def test_a_coarse_voxel_is_in_the_object_when_any_of_its_voxels_is(shape, factor, monkeypatch):
    rng = np.random.default_rng(sum(shape) * factor)
    for fill in (0.05, 0.3, 0.9):
        mask = rng.random(shape) < fill
        coarse = levels.coarser(segments.encode(mask, (0.5, 0.5, 2.0)), factor)
        assert same_runs(coarse, segments.encode(binned(mask, factor)))
        assert coarse.spacing == (0.5 * factor, 0.5 * factor, 2.0 * factor)
        assert coarse.meta["level_factor"] == factor
    monkeypatch.setattr(levels, "_RUNS_AT_ONCE", 3)       # many groups of slices: the same runs
    assert same_runs(levels.coarser(segments.encode(mask), factor), segments.encode(binned(mask, factor)))


@pytest.mark.parametrize("factor", [2, 3])
def test_a_coarse_voxel_holds_the_largest_label_of_its_voxels(factor, monkeypatch):
    rng = np.random.default_rng(factor)
    labels = (rng.integers(1, 6, (9, 13, 11)) * (rng.random((9, 13, 11)) < 0.5)).astype(np.uint16)
    fine = segments.encode_labels(labels, meta={"label_table": {"1": {"name": "one", "colour": [1, 2, 3]}}})
    coarse = levels.coarser(fine, factor)
    assert same_runs(coarse, segments.encode_labels(binned(labels, factor)))
    # the tables keep the full resolution's counts, which the coarse voxels would overstate
    assert coarse.meta["label_voxels"] == {str(k): v for k, v in fine.label_voxels().items()}
    assert coarse.meta["label_table"] == fine.meta["label_table"]
    monkeypatch.setattr(levels, "_RUNS_AT_ONCE", 5)
    assert same_runs(levels.coarser(fine, factor), coarse)


def test_the_levels_are_each_made_from_the_one_before_and_equal_binning_the_voxels():
    mask = torus()
    made = levels.build_levels(segments.encode(mask))
    assert [level.meta["level_factor"] for level in made] == [2, 4, 8]
    for level in made:
        assert same_runs(level, segments.encode(binned(mask, level.meta["level_factor"])))
    with pytest.raises(ValueError, match="multiple"):
        levels.build_levels(segments.encode(mask), (2, 3))


def test_a_coarse_normal_is_the_unit_sum_of_its_voxels_normals(monkeypatch):
    """Held against the sum written out a voxel at a time, at the coarse surface's voxels, and outward on a ball."""
    zz, yy, xx = np.mgrid[:24, :24, :24]
    ball = (xx - 11.3) ** 2 + (yy - 12.1) ** 2 + (zz - 11.7) ** 2 <= 81
    fine = segments.encode(ball)
    fine.normals = surface_normals(ball, (-(((xx - 11.3) ** 2 + (yy - 12.1) ** 2 + (zz - 11.7) ** 2) ** 0.5)))
    coarse = levels.coarser(fine, 2).normals
    sums = {}
    for voxel, normal in zip(np.asarray(fine.normals.index), octahedral_decode(fine.normals.packed), strict=True):
        z, rest = divmod(int(voxel), 24 * 24)
        y, x = divmod(rest, 24)
        key = ((z // 2) * 12 + y // 2) * 12 + x // 2
        sums[key] = sums.get(key, 0) + normal.astype(float)
    coarse_ball = binned(ball, 2)                   # the coarse surface's object side keeps normals, nothing else
    surface = (surface_band(coarse_ball) & coarse_ball).ravel()
    keys = sorted(k for k, v in sums.items() if np.linalg.norm(v) > 1e-6 and surface[k])
    assert np.asarray(coarse.index).tolist() == keys
    expected = octahedral_encode(np.array([sums[k] / np.linalg.norm(sums[k]) for k in keys]))
    assert np.abs(np.asarray(coarse.packed).astype(int) - expected).max() <= 1
    z, rest = np.divmod(np.asarray(coarse.index), 144)
    y, x = np.divmod(rest, 12)
    outward = np.stack([x * 2 + 0.5 - 11.3, y * 2 + 0.5 - 12.1, z * 2 + 0.5 - 11.7], axis=1)
    outward /= np.linalg.norm(outward, axis=1, keepdims=True)
    assert np.einsum("nk,nk->n", octahedral_decode(coarse.packed), outward).min() > 0.9
    assert "summed over 2x2x2" in coarse.source and isinstance(coarse, SurfaceNormals)
    monkeypatch.setattr(levels, "_RUNS_AT_ONCE", 7)           # groups of one coarse slice, summed a slice at a time
    monkeypatch.setattr(levels, "_CELLS_AT_ONCE", 1)
    again = levels.coarser(fine, 2).normals
    assert np.array_equal(again.index, coarse.index) and np.array_equal(again.packed, coarse.packed)


@pytest.mark.parametrize("method", ["ftb", "btf", "octree-ftb", "octree-sort", "zbuffer"])
def test_every_method_meets_the_contract_at_a_coarse_level(ball, method):
    """A level is a volume of its own: the exact reference of its binned mask holds it."""
    for mask in (ball, torus()):
        level = levels.coarser(segments.encode(mask), 2)
        for angles, scale in (((31, 19, 0), 2.6), ((-45, 15, 10), 3.0)):
            view = View(*angles, (40, 44), scale)
            check(render(level, view, method).depth, binned(mask, 2), method, view)


def test_the_file_keeps_its_levels_and_an_old_file_has_none(tmp_path):
    mask = torus()
    fine = segments.encode_labels(mask.astype(np.uint16) * 3, (1.0, 1.0, 1.0), {"threshold": 1})
    fine.normals = surface_normals(mask)
    fine.levels = levels.build_levels(fine)
    vxs.save(fine, tmp_path / "a.vxs")
    again = vxs.load(tmp_path / "a.vxs")
    assert "levels" not in again.meta and len(again.levels) == 3
    for kept, made in zip(again.levels, fine.levels, strict=True):
        assert same_runs(kept, made) and kept.spacing == made.spacing
        assert kept.meta == {**made.meta, "normals_from": made.normals.source}     # as the object's own, once saved
        assert np.array_equal(kept.normals.index, made.normals.index)
        assert np.array_equal(kept.normals.packed, made.normals.packed)
    vxs.save(again, tmp_path / "b.vxs")                                   # saved again: the same bytes
    assert (tmp_path / "a.vxs").read_bytes() == (tmp_path / "b.vxs").read_bytes()
    fine.levels = ()
    vxs.save(fine, tmp_path / "c.vxs")
    assert vxs.load(tmp_path / "c.vxs").levels == ()
    with pytest.raises(InputError, match="only level 0") as info:
        vxs.load(tmp_path / "c.vxs").at_level(1)
    assert info.value.parameter == "level"


def test_a_damaged_level_is_a_damaged_file(tmp_path):
    fine = segments.encode(torus())
    fine.levels = levels.build_levels(fine)
    vxs.save(fine, tmp_path / "a.vxs")
    header, arrays = vxs.read_sections(tmp_path / "a.vxs")
    header["meta"]["levels"][1]["shape"] = [1, 2]
    with pytest.raises(InputError, match="damaged"):
        vxs.from_sections(header, arrays, tmp_path / "a.vxs")
    header["meta"]["levels"] = "coarse"
    with pytest.raises(InputError, match="levels"):
        vxs.from_sections(header, arrays, tmp_path / "a.vxs")


def test_the_level_for_a_picture_is_the_coarsest_no_larger_than_a_pixel():
    cube = np.zeros((64, 64, 64), bool)
    cube[4:60, 4:60, 4:60] = True
    fine = segments.encode(cube)
    fine.levels = levels.build_levels(fine)
    options = RenderOptions()
    # 56 voxels and a margin of 5 % on each side fill the picture: a pixel is 61.6 / size voxels
    for size, expected in ((512, 0), (40, 0), (30, 1), (15, 2), (7, 3), (2, 3)):
        assert level_for(fine, View(size=(size, size)), options)[0] == expected, size
    assert level_for(fine, View(size=(64, 64), scale=0.25), options) == (2, View(size=(64, 64), scale=1.0))   # 64/4
    assert level_for(fine, View(size=(64, 64), scale=0.25), options, level=1)[1].scale == 0.5
    from voxrender._render import Clip

    clipped = RenderOptions(clip=Clip(x=(0, 30)))
    assert level_for(fine, View(size=(8, 8)), clipped)[0] == 0             # clip limits are in its own voxels
    with pytest.raises(InputError, match="level 0"):
        level_for(fine, View(size=(8, 8)), clipped, level=2)
    assert level_for(segments.encode(cube), View(size=(8, 8)), options)[0] == 0       # no levels kept


def test_encode_levels_and_render_the_one_that_suits_the_picture(tmp_path):
    from test_qc_commands import body_hu

    from voxrender.outputs.output import write_nifti

    ct = write_nifti(tmp_path / "ct.nii.gz", body_hu())
    common = ("--threshold", "-500")
    assert run("encode", ct, *common, "-o", tmp_path / "plain.vxs").exit_code == 0
    result = run("encode", ct, *common, "--levels", "-o", tmp_path / "levels.vxs")
    assert result.exit_code == 0 and "levels 2x, 4x, 8x" in result.output, result.output
    added = run("encode", tmp_path / "plain.vxs", "--levels", "-o", tmp_path / "added.vxs")
    assert added.exit_code == 0, added.output
    assert (tmp_path / "added.vxs").read_bytes() == (tmp_path / "levels.vxs").read_bytes()
    plain, kept = vxs.load(tmp_path / "plain.vxs"), vxs.load(tmp_path / "levels.vxs")
    assert same_runs(plain, kept) and plain.meta == kept.meta
    growth = (tmp_path / "levels.vxs").stat().st_size / (tmp_path / "plain.vxs").stat().st_size
    assert 1 < growth < 1.5
    info = run("info", tmp_path / "levels.vxs")
    assert "levels: 3" in info.output and "  1: voxels 2 times larger" in info.output, info.output
    described = json.loads(run("info", tmp_path / "levels.vxs", "--json").output)
    assert [row["voxel_edge"] for row in described["levels"]] == [2, 4, 8]
    # level 0 is the picture of the file without levels; a small picture is drawn from a level, as asked
    size = ("--view", "anterior", "--size", "6")                   # the ball is 14 voxels across: 2.6 a pixel
    for name, path, level in (("plain", "plain.vxs", ()), ("zero", "levels.vxs", ("--level", "0")),
                              ("auto", "levels.vxs", ()), ("one", "levels.vxs", ("--level", "1"))):
        result = run("render", tmp_path / path, *size, *level, "-o", tmp_path / f"{name}.png")
        assert result.exit_code == 0, result.output
    picture = {name: iio.imread(tmp_path / f"{name}.png") for name in ("plain", "zero", "auto", "one")}
    assert np.array_equal(picture["plain"], picture["zero"])
    assert level_for(kept, View(*PRESETS["anterior"], (6, 6)), RenderOptions())[0] == 1
    assert "drawn from level 1" in result.output
    assert np.array_equal(picture["auto"], picture["one"]) and not np.array_equal(picture["auto"], picture["plain"])
    assert_bad_input(run("render", tmp_path / "levels.vxs", "--level", "4", "-o", tmp_path / "x.png"), "--level",
                     "levels 0 to 3")
    assert_bad_input(run("render", tmp_path / "plain.vxs", "--level", "1", "-o", tmp_path / "x.png"), "--level",
                     "encode --levels")
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("angles", [(31, 19, 0), (-45, 15, 10), (61, 119, 0)])
def test_a_framed_view_gives_the_same_picture_of_a_level(angles):
    """A view with its scale and centre set (a turntable's frames share them) draws a level where the full
    resolution lies: on an object made of whole coarse voxels, on a grid that is not, the same pixels."""
    mask = np.zeros((17, 18, 15), bool)
    mask[4:12, 2:10, 6:14] = True
    mask[12:14, 10:16, 2:4] = True
    fine = segments.encode(mask)
    fine.levels = levels.build_levels(fine, (2,))
    view = View(*angles, (48, 52), 1.7, centre=(1.3, -0.7))
    level, coarse_view = level_for(fine, view, RenderOptions(), level=1)
    assert level == 1 and coarse_view.scale == pytest.approx(3.4)
    full, coarse = render(fine, view, "btf").depth, render(fine.levels[0], coarse_view, "btf").depth
    assert np.isfinite(full).sum() > 300
    assert np.array_equal(np.isfinite(full), np.isfinite(coarse))


def test_a_batch_turns_a_file_with_levels_from_the_level_that_suits_it(tmp_path):
    """A turntable's frames share one framing, so every frame of a small picture comes from the same level, in the
    place the full resolution's picture has; --level 0 gives the pictures of the file without levels."""
    mask = np.zeros((40, 48, 44), bool)                 # of whole voxels of every level, on a grid that is not
    mask[8:32, 8:40, 8:40] = True
    mask[16:24, 0:8, 16:24] = True
    fine = segments.encode(mask, meta={"threshold": 1})
    fine.normals = surface_normals(mask)
    vxs.save(fine, tmp_path / "plain.vxs")
    fine.levels = levels.build_levels(fine)
    vxs.save(fine, tmp_path / "kept.vxs")
    made = {}
    for name, path, level in (("plain", "plain.vxs", ()), ("zero", "kept.vxs", ("--level", "0")),
                              ("auto", "kept.vxs", ())):
        result = run("batch", tmp_path / path, "--turntable", "3", "--size", "12", "--jobs", "1", *level,
                     "--background", "255,0,255", "-o", tmp_path / name)
        assert result.exit_code == 0, result.output
        made[name] = [iio.imread(next((tmp_path / name).glob(f"*/turn00{k}.png"))) for k in range(3)]
    for plain, zero, auto in zip(made["plain"], made["zero"], made["auto"], strict=True):
        assert np.array_equal(plain, zero)
        assert not np.array_equal(plain, auto)
        # the object is made of whole coarse voxels: its level covers the pixels the full resolution covers
        covered, coarse = ((picture[..., :3] != (255, 0, 255)).any(axis=2) for picture in (plain, auto))
        assert covered.sum() > 30 and np.array_equal(coarse, covered)


def test_a_file_without_levels_keeps_the_layout_it_always_had(tmp_path):
    """Runs, the octree's sections, then labels and normals: the .vxs and .vxo bytes of earlier versions."""
    from voxrender.object import octree

    mask = torus()
    fine = segments.encode_labels(mask.astype(np.uint16) * 2)
    fine.normals = surface_normals(mask)
    sections = octree.sections(octree.build_from_segments(fine))
    vxs.save(fine, tmp_path / "a.vxo", sections)
    names = list(vxs.read_sections(tmp_path / "a.vxo")[0]["arrays"])
    assert names == ["offsets", "starts", "ends", *sections, "labels", "normal_index", "normal_packed"]
    fine.levels = levels.build_levels(fine)
    vxs.save(fine, tmp_path / "b.vxo", sections)
    assert list(vxs.read_sections(tmp_path / "b.vxo")[0]["arrays"])[:len(names)] == names     # levels after


def test_a_level_whose_runs_leave_its_grid_is_refused_when_drawn(tmp_path):
    """In a file with levels each object's runs are checked when first drawn (a picture from one level reads no
    other's): a damaged level loads, is one line and exit 2 when drawn, and the others draw."""
    from test_segments import _rewritten

    mask = torus()
    fine = segments.encode(mask, meta={"threshold": 1})
    fine.levels = levels.build_levels(fine)
    vxs.save(fine, tmp_path / "a.vxs")
    ends = np.asarray(fine.levels[0].ends).copy()
    ends[0] = 99
    _rewritten(tmp_path / "a.vxs", lambda header: None, {"level1.ends": ends})
    loaded = vxs.load(tmp_path / "a.vxs")
    assert loaded.unchecked is not None and loaded.levels[0].unchecked is not None
    with pytest.raises(InputError, match="runs leave their grid"):
        render(loaded.levels[0], View(size=(8, 8)))
    assert_bad_input(run("render", tmp_path / "a.vxs", "--level", "1", "-o", tmp_path / "x.png"), "damaged")
    assert not (tmp_path / "x.png").exists()
    for level in ("0", "2"):
        result = run("render", tmp_path / "a.vxs", "--level", level, "-o", tmp_path / f"{level}.png")
        assert result.exit_code == 0, result.output
