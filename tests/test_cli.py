import json
import shutil
import subprocess
import sys
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
from click.testing import CliRunner
from conftest import ROOT, data_path
from dicom_files import write_series

from voxrender.cli import main
from voxrender.outputs.output import write_slices
from voxrender.samples import SAMPLE_THRESHOLD


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def assert_bad_input(result, *words):
    """Exit 2, one line on stderr naming the problem, no traceback."""
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert "Traceback" not in result.output
    for word in words:
        assert word in lines[0], lines[0]


@pytest.fixture
def cube_folder(tmp_path):
    values = np.full((10, 12, 14), 40, np.uint16)
    values[2:8, 3:9, 4:10] = 1000
    return write_slices(values, tmp_path / "cube")


def test_render_writes_png_depth_and_stats(tmp_path, cube_folder):
    out, depth, stats, depth_png = (tmp_path / n for n in ("c.png", "d.npy", "s.json", "d16.png"))
    result = run("render", cube_folder, "--threshold", 500, "--alpha", 30, "--beta", 20, "--size", "64x48",
                 "--scale", 2, "-o", out, "--depth-out", depth, "--stats-json", stats, "--depth-png", depth_png)
    assert result.exit_code == 0, result.output
    picture = iio.imread(out)
    assert picture.shape == (48, 64) and picture.dtype == np.uint8        # no colour: 8-bit grey
    depths = np.load(depth)
    assert depths.dtype == np.float32 and depths.shape == (48, 64) and np.isinf(depths).any()
    assert np.array_equal(np.isfinite(depths), picture > 0)
    report = json.loads(stats.read_text())
    assert report["method"] == "ftb"  # the default
    assert set(report["seconds"]) == {"load", "prepare", "render", "shade", "write", "total"}
    assert report["stats"]["pixels_lit"] == np.isfinite(depths).sum()
    assert report["stats"]["segments_read"] == 36
    assert iio.imread(depth_png).dtype == np.uint16
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.png", "cube", "d.npy", "d16.png", "s.json"]


def test_methods_agree_and_clip_options_work(tmp_path, cube_folder):
    depths = {}
    for method in ("ftb", "btf"):
        path = tmp_path / f"{method}.npy"
        result = run("render", cube_folder, "--threshold", 500, "--method", method, "--alpha", 25, "--beta", -30,
                     "--size", 48, "--scale", 2, "-o", tmp_path / f"{method}.png", "--depth-out", path)
        assert result.exit_code == 0, result.output
        depths[method] = np.load(path)
    assert np.array_equal(np.isfinite(depths["ftb"]), np.isfinite(depths["btf"]))
    whole = np.isfinite(depths["ftb"]).sum()
    result = run("render", cube_folder, "--threshold", 500, "--alpha", 25, "--beta", -30, "--size", 48, "--scale", 2,
                 "--clip-x", "4:7", "--clip-z", ":5", "--cut-depth", -1, "-o", tmp_path / "c.png", "--depth-out",
                 tmp_path / "c.npy")
    assert result.exit_code == 0, result.output
    clipped = np.load(tmp_path / "c.npy")
    assert 0 < np.isfinite(clipped).sum() < whole
    # The cut keeps voxels whose centre is at Z' >= -1; their cubes reach at most sqrt(3)/2 nearer.
    assert np.nanmin(np.where(np.isfinite(clipped), clipped, np.nan)) >= -1 - 3 ** 0.5 / 2


def test_encode_then_render_the_vxs(tmp_path, cube_folder):
    vxs = tmp_path / "cube.vxs"
    result = run("encode", cube_folder, "--threshold", 500, "-o", vxs)
    assert result.exit_code == 0 and "216 in the object" in result.output
    direct, via = tmp_path / "a.npy", tmp_path / "b.npy"
    assert run("render", cube_folder, "--threshold", 500, "--view", "left", "-o", tmp_path / "a.png",
               "--depth-out", direct).exit_code == 0
    assert run("render", vxs, "--view", "left", "-o", tmp_path / "b.png", "--depth-out", via).exit_code == 0
    assert np.array_equal(np.load(direct), np.load(via))
    assert_bad_input(run("render", vxs, "--threshold", 3, "-o", tmp_path / "c.png"), "already encoded")


def test_fit_object_zooms_in(tmp_path, cube_folder):
    covered = {}
    for fit in ("volume", "object"):
        path = tmp_path / f"{fit}.npy"
        assert run("render", cube_folder, "--threshold", 500, "--fit", fit, "--alpha", 30, "--size", 64, "-o",
                   tmp_path / f"{fit}.png", "--depth-out", path).exit_code == 0
        covered[fit] = np.isfinite(np.load(path)).sum()
    assert covered["object"] > 1.5 * covered["volume"]


def test_encode_octree_then_render_and_describe_it(tmp_path, cube_folder):
    from voxrender.object.pipeline import load_segments

    result = run("encode", cube_folder, "--threshold", 500, "--octree", "-o", tmp_path / "c.vxo")
    assert result.exit_code == 0, result.output
    loaded = load_segments(tmp_path / "c.vxo")
    assert loaded.has_octree and loaded.octree().to_mask().sum() == 216 and "black" in result.output
    assert_bad_input(run("encode", cube_folder, "--octree", "-o", tmp_path / "c.vxs"), ".vxo")
    for method in ("octree-ftb", "ftb"):
        result = run("render", tmp_path / "c.vxo", "--method", method, "--size", 32, "-o", tmp_path / f"{method}.png")
        assert result.exit_code == 0, result.output
    assert np.array_equal(iio.imread(tmp_path / "octree-ftb.png") > 0, iio.imread(tmp_path / "ftb.png") > 0)
    result = run("info", tmp_path / "c.vxo", "--json")
    assert result.exit_code == 0 and json.loads(result.output)["octree"]["black"] >= 1, result.output
    result = run("encode", tmp_path / "c.vxo", "--octree", "-o", tmp_path / "again.vxo")       # .vxs -> .vxo
    assert result.exit_code == 0, result.output


def test_info_reports_threshold_and_counts(cube_folder):
    result = run("info", cube_folder, "--threshold", 500, "--json")
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output)
    assert summary["dimensions_xyz"] == [14, 12, 10]
    assert summary["object_voxels"] == 216 and summary["segments"] == 36
    assert 40 < summary["suggested_threshold_otsu"] < 1000
    assert run("info", cube_folder).exit_code == 0


def test_vpn_and_view_options(tmp_path, cube_folder):
    a, b = tmp_path / "a.npy", tmp_path / "b.npy"
    assert run("render", cube_folder, "--threshold", 500, "--vpn", "0,-1,0", "--size", 40, "-o",
               tmp_path / "a.png", "--depth-out", a).exit_code == 0
    assert run("render", cube_folder, "--threshold", 500, "--view", "anterior", "--size", 40, "-o",
               tmp_path / "b.png", "--depth-out", b).exit_code == 0
    assert np.array_equal(np.load(a), np.load(b))


def test_demo_renders_the_quarter_head(tmp_path):
    result = run("demo", "-o", tmp_path / "demo.png", "--size", 64)  # the quarter head shipped with voxrender
    assert result.exit_code == 0, result.output
    assert iio.imread(tmp_path / "demo.png").shape[:2] == (2 * (64 + 16 + 4) + 4, 4 * (64 + 4) + 4)  # 2 x 4 sheet
    assert_bad_input(run("demo", "-o", tmp_path / "d.png", "--headsq", tmp_path), "--headsq", "quarter head")


def test_samples_render_at_their_threshold(tmp_path):
    assert run("samples", tmp_path, "--name", "staircase").exit_code == 0
    for written in ("staircase", "staircase.nii.gz", "staircase.nrrd"):      # slices, NIfTI and NRRD alike
        result = run("info", tmp_path / written, "--threshold", SAMPLE_THRESHOLD, "--json")
        assert json.loads(result.output)["object_voxels"] == 11, written


def test_lines_table_reproduces_table_1():
    result = run("lines", "--table", "--trials", 100000, "--seed", 2)
    assert result.exit_code == 0, result.output
    rows = {}
    for line in result.output.splitlines():
        parts = line.split()
        if parts and parts[0] in ("d6/d18", "d6/d26", "d18/d6", "d18/d26", "d26/d6", "d26/d18"):
            rows[parts[0]] = parts
    assert len(rows) == 6
    for parts in rows.values():
        assert abs(float(parts[-1])) <= 0.02  # mean ratio minus Table 1's analytical value


def test_raycast_method_from_the_command_line(tmp_path, cube_folder):
    stats = tmp_path / "s.json"
    result = run("render", cube_folder, "--threshold", 500, "--method", "raycast", "--connectivity", "26",
                 "--size", 40, "-o", tmp_path / "r.png", "--stats-json", stats)
    assert result.exit_code == 0, result.output
    report = json.loads(stats.read_text())["stats"]
    assert report["connectivity"] == "26" and report["steps_6"] == 0 and "leaks" not in report
    result = run("render", cube_folder, "--threshold", 500, "--method", "raycast", "--connectivity", "26",
                 "--compare-rays", "--size", 40, "-o", tmp_path / "r.png", "--stats-json", stats)
    assert result.exit_code == 0 and "leaks" in json.loads(stats.read_text())["stats"], result.output
    assert_bad_input(run("render", cube_folder, "--threshold", 500, "--compare-rays", "-o", tmp_path / "x.png"),
                     "--compare", "ftb")


# ------------------------------------------------------------------ bad input

def test_missing_path(tmp_path):
    assert_bad_input(run("render", tmp_path / "nope", "-o", tmp_path / "o.png"), "no such file")


def test_empty_folder(tmp_path):
    (tmp_path / "empty").mkdir()
    assert_bad_input(run("render", tmp_path / "empty", "-o", tmp_path / "o.png"), "empty folder")


def test_folder_of_non_images(tmp_path):
    folder = tmp_path / "docs"
    folder.mkdir()
    (folder / "notes.txt").write_text("hello")
    assert_bad_input(run("info", folder), "--raw")


def test_slices_of_different_sizes(tmp_path):
    folder = tmp_path / "mixed"
    folder.mkdir()
    iio.imwrite(folder / "1.png", np.zeros((4, 4), np.uint8))
    iio.imwrite(folder / "2.png", np.zeros((5, 4), np.uint8))
    assert_bad_input(run("render", folder, "-o", tmp_path / "o.png"), "same size")


def test_truncated_dicom_and_mixed_series(tmp_path):
    paths = write_series(tmp_path / "cut", np.zeros((3, 8, 8)))
    paths[2].write_bytes(paths[2].read_bytes()[:200])
    assert_bad_input(run("render", tmp_path / "cut", "-o", tmp_path / "o.png"), "DICOM")
    write_series(tmp_path / "two", np.zeros((2, 4, 4)), series_uid="1.2.9.1", names=["a.dcm", "b.dcm"])
    write_series(tmp_path / "two", np.zeros((2, 4, 4)), series_uid="1.2.9.2", names=["c.dcm", "d.dcm"])
    assert_bad_input(run("render", tmp_path / "two", "-o", tmp_path / "o.png"), "--series", "1.2.9.1")
    assert not (tmp_path / "o.png").exists()


def test_raw_dims_that_do_not_match(tmp_path):
    np.zeros(100, np.uint16).tofile(tmp_path / "slice.raw")
    assert_bad_input(run("render", tmp_path / "slice.raw", "--raw", "8x8:uint16:little", "-o",
                         tmp_path / "o.png"), "not a multiple")
    assert_bad_input(run("render", tmp_path / "slice.raw", "--raw", "8by8", "-o", tmp_path / "o.png"), "--raw")


def test_threshold_that_leaves_nothing(tmp_path, cube_folder):
    assert_bad_input(run("render", cube_folder, "--threshold", 5000, "-o", tmp_path / "o.png"),
                     "values range from 40 to 1000")
    assert not (tmp_path / "o.png").exists()


def test_crop_outside_the_volume(tmp_path, cube_folder):
    assert_bad_input(run("render", cube_folder, "--crop", "0:99,:,:", "-o", tmp_path / "o.png"),
                     "outside", "0:14")


def test_unwritable_outputs(tmp_path, cube_folder):
    assert_bad_input(run("render", cube_folder, "-o", tmp_path / "no" / "o.png"), "does not exist")
    assert_bad_input(run("render", cube_folder, "-o", tmp_path), "is a folder")
    assert_bad_input(run("render", cube_folder, "-o", tmp_path / "o.png", "--stats-json",
                         tmp_path / "no" / "s.json"), "does not exist")
    assert not (tmp_path / "o.png").exists()


@pytest.mark.parametrize("args,words", [
    (["--size", "0"], ["--size"]),
    (["--size", "12x"], ["--size"]),
    (["--view", "anterior", "--alpha", "3"], ["--view", "--alpha"]),
    (["--vpn", "0,0,0"], ["--vpn"]),
    (["--vpn", "1,2"], ["--vpn"]),
    (["--light", "up"], ["--light"]),
    (["--light", "0,0,0"], ["--light", "(0.0, 0.0, 0.0) must be a non-zero direction"]),
    (["--background", "puce"], ["--background"]),
    (["--scale", "-1"], ["--scale"]),
    (["--method", "magic"], ["magic"]),
    (["--threshold", "bone"], ["--threshold"]),
    (["--spacing", "1,1"], ["--spacing"]),
    (["--voxel", "0"], ["--voxel"]),
    (["--min-object", "-3"], ["--min-object"]),
    (["--alpha", "abc"], ["--alpha"]),
    (["--clip-x", "5"], ["--clip-x"]),
    (["--clip-y", "9:3"], ["--clip-y"]),
    (["--cut-depth", "inf"], ["--cut-depth"]),
    (["--supersample", "0"], ["--supersample"]),
    (["--connectivity", "6"], ["--connectivity", "'ftb' takes no option"]),
    (["--crop", "1:2,3"], ["--crop"]),
    (["--crop", "a:b,:,:"], ["--crop"]),
    (["--series", "1.2.3"], ["--series", "takes no series"]),
    (["--depth-out", "{name}.npy", "--shading", "flat"], ["--shading"]),
])
def test_bad_options(tmp_path, cube_folder, args, words):
    result = run("render", cube_folder, *args, "-o", tmp_path / "o.png")
    assert_bad_input(result, *words)
    assert not (tmp_path / "o.png").exists()
    if args[0] in ("--view", "--vpn", "--alpha", "--series"):
        return   # render's view options; a series is looked for in each input of a batch
    # batch declares the same options and reports them the same way, before making anything
    result = run("batch", cube_folder, *args, "-o", tmp_path / "out")
    assert_bad_input(result, *words)
    assert not (tmp_path / "out").exists()


def test_input_is_never_modified(tmp_path, cube_folder):
    before = {p.name: p.read_bytes() for p in cube_folder.iterdir()}
    assert run("render", cube_folder, "--threshold", 500, "-o", tmp_path / "o.png").exit_code == 0
    assert {p.name: p.read_bytes() for p in cube_folder.iterdir()} == before


def test_console_script_errors_are_one_line(tmp_path):
    """The real entry point, in a subprocess: one line on stderr, status 2, nothing on stdout."""
    done = subprocess.run([sys.executable, str(ROOT / "cli.py"), "render", str(tmp_path / "nope"), "-o",
                           str(tmp_path / "o.png")], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.count("\n") == 1 and done.stderr.startswith("error: no such file")
    done = subprocess.run([sys.executable, str(ROOT / "cli.py"), "render"], capture_output=True, text=True)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "INPUT" in done.stderr


# ------------------------------------------------------------------ the issue's commands on real data

def test_issue_commands_on_real_data(tmp_path):
    vhf, headsq = data_path("vhf_head"), data_path("headsq")
    for args in (["render", vhf, "--threshold", 300, "--size", 128, "-o", tmp_path / "skull.png"],
                 ["render", vhf, "--threshold", -300, "--view", "anterior", "--size", 128, "-o", tmp_path / "f.png"],
                 ["render", headsq, "--raw", "64x64:uint16:little", "--spacing", "3.2,3.2,1.5", "--threshold",
                  1150, "--size", 128, "-o", tmp_path / "head.png"],
                 ["info", vhf],
                 ["encode", vhf, "--threshold", 300, "-o", tmp_path / "skull.vxs"],
                 ["render", tmp_path / "skull.vxs", "--size", 128, "-o", tmp_path / "skull2.png"]):
        result = run(*args)
        assert result.exit_code == 0, (args, result.output)
        if args[0] == "info":
            assert "dimensions xyz: [512, 512, 234]" in result.output and "units: HU" in result.output
        if args[0] == "encode":
            assert "592293 in the object" in result.output and "threshold 300" in result.output
    skull, face, head = (iio.imread(tmp_path / name) for name in ("skull.png", "f.png", "head.png"))
    assert np.array_equal(skull, iio.imread(tmp_path / "skull2.png"))     # the .vxs renders the same picture
    for picture in (skull, face, head):
        covered = picture > 0
        rows, columns = np.nonzero(covered)
        assert picture.shape == (128, 128) and covered.sum() > 400
        # framed as the view sees it: the object's extent is centred and fills the picture across one side
        extent = (rows.max() - rows.min() + 1, columns.max() - columns.min() + 1)
        assert max(extent) >= 0.85 * 128
        assert abs((rows.max() + rows.min()) / 2 - 63.5) <= 0.1 * 128
        assert abs((columns.max() + columns.min()) / 2 - 63.5) <= 0.1 * 128
        # and shaded: many grey levels, not a silhouette
        assert len(np.unique(picture[covered])) > 50


# ------------------------------------------------------------------ research formats and a corpus no one here wrote

def test_pydicom_corpus_renders_or_ends_in_one_clean_line(tmp_path):
    """pydicom's own test files, each in a folder of its own, as a new user would try them: every one renders, or
    ends with exit 2 and one error line (warnings may come before it); none is an internal error."""
    import pydicom.data

    files = sorted((Path(pydicom.data.__file__).parent / "test_files").glob("*.dcm"))   # those pydicom installs
    assert len(files) > 70
    outcomes = {}
    for path in files:
        folder = tmp_path / Path(path).stem
        folder.mkdir()
        shutil.copy(path, folder)
        result = run("render", folder, "--size", 24, "-o", tmp_path / f"{folder.name}.png")
        errors = [line for line in result.stderr.splitlines() if not line.startswith("warning: ")]
        assert result.exit_code in (0, 2), (path, result.stderr)
        if result.exit_code == 2:
            assert len(errors) == 1 and errors[0].startswith("error: "), (path, result.stderr)
            assert not (tmp_path / f"{folder.name}.png").exists()
        outcomes[Path(path).stem] = result.exit_code
    # what used to fail and now reads: RGB secondary captures, multi-frame dose grids, files without meta headers
    assert outcomes["SC_rgb_rle"] == outcomes["rtdose"] == outcomes["ExplVR_BigEnd"] == 0
    assert outcomes["badVR"] == 2 and outcomes["rtplan"] == 2
    assert sum(code == 0 for code in outcomes.values()) >= 50


def test_research_formats_through_the_commands(tmp_path):
    import nibabel

    data = np.zeros((12, 10, 8), np.int16)                       # [i, j, k]
    data[3:9, 2:8, 2:6] = 1000
    nibabel.save(nibabel.Nifti1Image(np.stack([data, data], axis=-1), np.eye(4)), str(tmp_path / "t.nii.gz"))
    assert_bad_input(run("render", tmp_path / "t.nii.gz", "-o", tmp_path / "o.png"), "--frame", "2 volumes")
    assert_bad_input(run("render", tmp_path / "t.nii.gz", "--frame", 5, "-o", tmp_path / "o.png"), "--frame")
    assert_bad_input(run("render", tmp_path / "t.nii.gz", "--frame", 1, "--orientation", "XYZ", "-o",
                         tmp_path / "o.png"), "--orientation")
    assert not (tmp_path / "o.png").exists()
    result = run("render", tmp_path / "t.nii.gz", "--frame", 1, "--threshold", 500, "--view", "anterior", "-o",
                 tmp_path / "o.png")
    assert result.exit_code == 0 and iio.imread(tmp_path / "o.png").any()
    info = run("info", tmp_path / "t.nii.gz", "--frame", 0, "--threshold", 500)
    assert "orientation: RAS" in info.output and "orientation from: NIfTI sform" in info.output
    assert "reoriented: RAS -> LPS: flipped x, y" in info.output and "affine:" in info.output
    encoded = run("encode", tmp_path / "t.nii.gz", "--frame", 0, "--threshold", 500, "-o", tmp_path / "t.vxs")
    assert encoded.exit_code == 0
    result = run("batch", tmp_path / "t.nii.gz", "--frame", 0, "--threshold", 500, "--size", 24, "-o", tmp_path / "b",
                 "--jobs", 1)
    assert result.exit_code == 0 and (tmp_path / "b" / "t" / "anterior.png").exists()


def test_bad_research_files_end_in_one_line(tmp_path):
    import nibabel
    import nrrd

    nibabel.save(nibabel.Nifti1Image(np.random.default_rng(0).random((20, 20, 20)), np.eye(4)),
                 str(tmp_path / "whole.nii.gz"))
    (tmp_path / "cut.nii.gz").write_bytes((tmp_path / "whole.nii.gz").read_bytes()[:3000])
    nrrd.write(str(tmp_path / "v.nrrd"), np.zeros((3, 4, 5), np.uint8), index_order="C")
    (tmp_path / "magic.nrrd").write_bytes((tmp_path / "v.nrrd").read_bytes().replace(b"encoding: gzip",
                                                                                       b"encoding: magic"))
    nrrd.write(str(tmp_path / "gone.nhdr"), np.zeros((3, 4, 5), np.uint8), index_order="C", detached_header=True)
    for data in tmp_path.glob("gone.raw*"):
        data.unlink()
    for name, words in (("cut.nii.gz", ["cut.nii.gz"]), ("magic.nrrd", ["cannot read"]), ("gone.nhdr", ["gone"])):
        assert_bad_input(run("render", tmp_path / name, "-o", tmp_path / "o.png"), *words)
        assert not (tmp_path / "o.png").exists()


def test_compare_command(tmp_path):
    golden = ROOT / "tests" / "golden" / "shell-ftb.png"
    picture = iio.imread(golden).copy()
    iio.imwrite(tmp_path / "same.png", picture)
    result = run("compare", tmp_path / "same.png", golden)
    assert result.exit_code == 0 and "same" in result.output
    picture[:5, :5] = 255
    iio.imwrite(tmp_path / "off.png", picture)
    result = run("compare", tmp_path / "off.png", golden)
    assert result.exit_code == 1 and "DIFFERENT" in result.output
    assert run("compare", tmp_path / "off.png", golden, "--tolerance", 255).exit_code == 0
    assert_bad_input(run("compare", tmp_path / "nope.png", golden), "cannot read")
    iio.imwrite(tmp_path / "small.png", picture[:10])
    assert_bad_input(run("compare", tmp_path / "small.png", golden), "differ in size")


def test_sheet_command(tmp_path, cube_folder):
    result = run("sheet", cube_folder, "--threshold", 500, "--view", "anterior", "--view", "left", "--methods",
                 "ftb,btf,octree-ftb", "--size", 32, "-o", tmp_path / "s.png")
    assert result.exit_code == 0, result.output
    assert iio.imread(tmp_path / "s.png").shape[:2] == (3 * (32 + 16 + 4) + 4, 2 * (32 + 4) + 4)
    assert_bad_input(run("sheet", cube_folder, cube_folder, "--methods", "ftb", "-o", tmp_path / "t.png"),
                     "one input")
    assert_bad_input(run("sheet", cube_folder, "--depth-out", tmp_path / "d.npy", "-o", tmp_path / "t.png"),
                     "--depth-out")
    assert not (tmp_path / "t.png").exists()


def test_info_leaves_out_nan_and_inf_and_counts_them(tmp_path):
    """Was: the value range [nan, nan], and '--threshold: nan must be a finite number' with no --threshold given."""
    import nibabel as nib

    values = np.zeros((16, 16, 16), np.float32)
    values[4:12, 4:12, 4:12] = 100
    values[0, 0, :3], values[1, 1, 1] = np.nan, np.inf
    nib.save(nib.Nifti1Image(values, np.eye(4)), tmp_path / "nan.nii")
    result = run("info", tmp_path / "nan.nii", "--json")
    assert result.exit_code == 0 and not result.stderr, result.output
    summary = json.loads(result.stdout)
    assert summary["value_range"] == [0.0, 100.0] and summary["nan_voxels"] == 3 and summary["inf_voxels"] == 1
    assert 0 < summary["suggested_threshold_otsu"] < 100 and summary["object_voxels"] == 8 ** 3
    assert all(np.isfinite(summary["percentiles_1_5_25_50_75_95_99"]))
    assert "nan voxels: 3" in run("info", tmp_path / "nan.nii").stdout
    nib.save(nib.Nifti1Image(np.full((4, 4, 4), np.nan, np.float32), np.eye(4)), tmp_path / "all-nan.nii")
    assert_bad_input(run("info", tmp_path / "all-nan.nii"), "every voxel is NaN or infinite")


def test_info_on_a_ct_padded_outside_its_scan_circle(tmp_path):
    """The padding (-3024 HU outside the circle) is left out of the suggestions, and the CT presets suggested."""
    yy, xx = np.mgrid[:64, :64] - 31.5
    radius = np.hypot(yy, xx)
    plane = np.where(radius < 32, -1000, -3024)
    plane = np.where(radius < 16, 40, plane)
    ct = np.stack([plane] * 6).astype(np.int16)
    write_series(tmp_path / "ct", ct + 1024, spacing=(1.0, 1.0, 1.0), intercept=-1024)
    summary = json.loads(run("info", tmp_path / "ct", "--json").stdout)
    assert summary["units"] == "HU" and summary["value_range"] == [-3024.0, 40.0]
    assert summary["padding_value"] == -3024 and summary["padding_voxels"] == int((ct == -3024).sum())
    assert -1000 < summary["suggested_threshold_otsu"] < 40 and summary["object_voxels"] == int((ct == 40).sum())
    assert summary["suggested_presets"] == {"skin": "-300:", "bone": "300:"}
    plain = json.loads(run("info", tmp_path / "ct", "--json", "--format", "dicom").stdout)
    assert plain == summary
    write_slices(np.full((4, 8, 8), 40, np.uint16), tmp_path / "pngs")
    assert "suggested_presets" not in json.loads(run("info", tmp_path / "pngs", "--json").stdout)
