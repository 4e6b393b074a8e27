"""The picture step: one RenderOptions, the same picture from ``render``, ``batch`` and the library."""

import json
import subprocess
import sys

import imageio.v3 as iio
import numpy as np
import pytest
from click.testing import CliRunner

from voxrender._render import METHODS, Clip
from voxrender.cli import main
from voxrender.errors import InputError
from voxrender.object.pipeline import PrepOptions, load_segments
from voxrender.outputs.picture_outputs import Outputs, write_outputs
from voxrender.pictures._picture import RenderOptions, picture
from voxrender.space.view import View

ANGLES = (30.0, 20.0, 10.0)
# Each method, then clipping, cut, gamma, light and shading: every option both commands declare.
GRID = [[]] + [["--method", m] for m in sorted(METHODS) if m != "ftb"] + [
    ["--connectivity", "6", "--method", "raycast"],
    ["--clip-x", "8:", "--clip-z", ":15"],
    ["--cut-depth", "0.5", "--method", "btf"],
    ["--gamma-only"],
    ["--light", "1,-1,-1", "--background", "20,30,40"],
    ["--shading", "depth", "--supersample", "3"],
    ["--scale", "1.5", "--size", "40x36"],
    ["--fit", "object"],
]


@pytest.fixture
def ball_file(tmp_path):
    zz, yy, xx = np.mgrid[:18, :20, :22]
    values = ((xx - 11) ** 2 + (yy - 9) ** 2 + (zz - 8) ** 2 <= 36) * 1000 + ((xx + yy) % 7 == 0) * (zz < 4) * 900
    np.save(tmp_path / "ball.npy", values.astype(np.int16))
    return tmp_path / "ball.npy"


def run(*args):
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    return result


@pytest.mark.parametrize("options", GRID, ids=lambda o: " ".join(o) or "defaults")
def test_render_and_batch_make_identical_pictures(tmp_path, ball_file, options):
    angles = (0.0, 0.0, 45.0) if options == ["--gamma-only"] else ANGLES
    options = [] if options == ["--gamma-only"] else options
    size = [] if "--size" in options else ["--size", "48"]
    run("render", ball_file, "--threshold", 500, "--alpha", angles[0], "--beta", angles[1], "--gamma", angles[2],
        *size, *options, "-o", tmp_path / "render.png", "--depth-out", tmp_path / "render.npy",
        "--stats-json", tmp_path / "render.json")
    run("batch", ball_file, "--threshold", 500, "--angles", ",".join(map(str, angles)), *size, *options,
        "--jobs", 1, "-o", tmp_path / "out", "--pattern", "batch.png", "--depth-out", "batch.npy",
        "--stats-json", "batch.json")
    assert (tmp_path / "render.png").read_bytes() == (tmp_path / "out" / "batch.png").read_bytes()
    assert np.array_equal(np.load(tmp_path / "render.npy"), np.load(tmp_path / "out" / "batch.npy"))
    rendered, batched = (json.loads(p.read_text()) for p in (tmp_path / "render.json", tmp_path / "out" / "batch.json"))
    timings = {"black_seconds", "reference_seconds"}
    assert {k: v for k, v in rendered["stats"].items() if k not in timings} == \
        {k: v for k, v in batched["stats"].items() if k not in timings}
    assert rendered["view"] == batched["view"] and rendered["object"] == batched["object"]
    assert set(rendered["seconds"]) == {"load", "prepare", "render", "shade", "write", "total"}
    assert set(batched["seconds"]) == {"render", "shade", "write", "total"}   # load and prepare: once per input


def test_picture_is_what_the_commands_write(tmp_path, ball_file):
    run("render", ball_file, "--threshold", 500, "--alpha", 30, "--beta", 20, "--size", 48, "--light", "1,0,-1",
        "-o", tmp_path / "cli.png")
    encoded = load_segments(ball_file, prepare=PrepOptions(threshold=500)).segments     # with grey-level normals
    options = RenderOptions(size=(48, 48), light=(1.0, 0.0, -1.0))
    result = picture(encoded, options.view(30, 20), options)
    assert np.array_equal(result.rgb[..., 0], iio.imread(tmp_path / "cli.png"))     # grey: written as one channel
    seconds = write_outputs(result, Outputs(tmp_path / "lib.png", depth_png=tmp_path / "d.png"))
    assert set(seconds) == {"render", "shade", "write", "total"}
    assert (tmp_path / "lib.png").read_bytes() == (tmp_path / "cli.png").read_bytes()
    assert iio.imread(tmp_path / "d.png").dtype == np.uint16


def test_options_are_checked_when_made():
    for bad, parameter in (({"shading": "phong"}, "shading"), ({"fit": "all"}, "fit"), ({"light": (0, 0, 0)}, "light"),
                           ({"scale": -1.0}, "scale"), ({"size": (0, 4)}, "size"), ({"method": "nope"}, "method"),
                           ({"method_options": {"connectivity": "6"}}, "connectivity")):
        with pytest.raises(InputError) as info:
            RenderOptions(**bad)
        assert info.value.parameter == parameter
    assert RenderOptions("raycast", {"connectivity": "26"}, Clip(x=(1, None))).view(1, 2, 3) == \
        View(1, 2, 3, (512, 512), None)


def test_normals_outputs(tmp_path, ball_file):
    run("render", ball_file, "--threshold", 500, "--size", 48, "-o", tmp_path / "p.png",
        "--normals-out", tmp_path / "n.npy", "--normals-png", tmp_path / "n.png", "--depth-out", tmp_path / "d.npy")
    normals, depth = np.load(tmp_path / "n.npy"), np.load(tmp_path / "d.npy")
    assert normals.shape == (48, 48, 3) and iio.imread(tmp_path / "n.png").shape == (48, 48, 3)
    lit = np.isfinite(normals).all(axis=2)
    assert lit.any() and not lit[~np.isfinite(depth)].any()
    assert np.allclose(np.linalg.norm(normals[lit], axis=1), 1, atol=1e-4)
    assert (normals[lit, 2] < 0).mean() > 0.95         # the visible side faces the viewer (negative Z')


@pytest.mark.parametrize("command", ["render", "batch"])
def test_normals_outputs_need_gradient_shading(tmp_path, ball_file, command):
    out = tmp_path / ("p.png" if command == "render" else "out")
    result = CliRunner().invoke(main, [command, str(ball_file), "--threshold", "500", "--shading", "depth",
                                       "-o", str(out), "--normals-out",
                                       str(tmp_path / "n.npy") if command == "render" else "{name}.npy"])
    assert result.exit_code == 2 and result.stderr.count("\n") == 1
    assert "--shading: normals are kept with gradient shading only" in result.stderr
    assert not out.exists() and not (tmp_path / "n.npy").exists()
    with pytest.raises(InputError, match="gradient shading only"):
        Outputs(tmp_path / "p.png", normals=tmp_path / "n.npy").check(RenderOptions(shading="depth-gradient"))


# A fresh interpreter registers one more record before the rest of voxrender is imported, as if it were in
# OUTPUTS' source; nothing else is changed.  It writes the pixels the object covers, white on black.
TOY_OUTPUT = """
import json, sys
import numpy as np
from click.testing import CliRunner
from voxrender.outputs import output, output_kinds

output_kinds.OUTPUTS["coverage_png"] = output_kinds.OutputKind(
    ".png", "Save the pixels the object covers; in a batch, a pattern.",
    lambda path, result, about: output.write_png(path, result.image.coverage.astype(np.uint8) * 255), "coverage-png")

from voxrender.cli import main
from voxrender.outputs.picture_outputs import Outputs, write_outputs
from voxrender.pictures._picture import picture
from voxrender.object.segments import encode
from voxrender.space.view import View

folder, commands = sys.argv[1], json.loads(sys.argv[2])
result = picture(encode(np.ones((4, 4, 4), bool)), View(30, 20, size=(16, 16), scale=2.0))
write_outputs(result, Outputs(f"{folder}/lib.png", coverage_png=f"{folder}/lib-covered.png"))
runs = [CliRunner().invoke(main, command) for command in commands]
print(json.dumps([[run.exit_code, run.stdout, run.stderr] for run in runs]))
"""


def test_an_output_is_one_record(tmp_path, ball_file):
    common = [str(ball_file), "--threshold", "500", "--size", "48"]
    commands = [["render", *common, "-o", f"{tmp_path}/r.png", "--coverage-png", f"{tmp_path}/r-covered.png",
                 "--depth-out", f"{tmp_path}/r.npy"],
                ["batch", *common, "--jobs", "1", "-o", f"{tmp_path}/out", "--coverage-png", "{name}-covered.png"],
                ["batch", *common, "--jobs", "1", "-o", f"{tmp_path}/bad", "--coverage-png", "{name}.npy"],
                ["sheet", *common, "-o", f"{tmp_path}/s.png", "--coverage-png", f"{tmp_path}/s-covered.png"],
                ["render", "--help"]]
    done = subprocess.run([sys.executable, "-c", TOY_OUTPUT, str(tmp_path), json.dumps(commands)],
                          capture_output=True, text=True, check=True)
    (render, made, bad, sheet, render_help) = json.loads(done.stdout)
    lib = iio.imread(tmp_path / "lib-covered.png")                         # the library writes it
    assert lib.shape == (16, 16) and set(np.unique(lib)) == {0, 255}
    assert render[0] == 0, render                                          # the commands take its flag
    covered = np.isfinite(np.load(tmp_path / "r.npy"))
    assert np.array_equal(iio.imread(tmp_path / "r-covered.png"), covered.astype(np.uint8) * 255)
    assert made[0] == 0 and (tmp_path / "out" / "ball-covered.png").is_file(), made
    assert bad[0] == 2 and "--coverage-png: output pattern '{name}.npy' must end in .png" in bad[2], bad
    assert sheet[0] == 2 and "--coverage-png cannot apply" in sheet[2] and not (tmp_path / "s.png").exists()
    assert "--coverage-png FILE.png" in render_help[1] and "Save the pixels the object covers" in render_help[1]
