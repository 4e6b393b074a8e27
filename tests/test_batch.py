import csv
import json
import shutil
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
from click.testing import CliRunner

from voxrender.batch import cache, spec, tasks
from voxrender.batch import run as batch
from voxrender.cli import main
from voxrender.errors import InputError
from voxrender.object import vxs
from voxrender.object.pipeline import PrepOptions, ReadOptions
from voxrender.pictures._picture import RenderOptions
from voxrender.qc.index_page import missing_labels, read_index
from voxrender.space.view import PRESETS, rotation_matrix


@pytest.fixture
def stacks(tmp_path):
    """Two small volumes as .npy files and one broken input."""
    folder = tmp_path / "in"
    folder.mkdir()
    zz, yy, xx = np.mgrid[:20, :22, :24]
    np.save(folder / "ball.npy", ((xx - 12) ** 2 + (yy - 11) ** 2 + (zz - 10) ** 2 <= 49).astype(np.int16) * 1000)
    np.save(folder / "box.npy", np.pad(np.full((6, 8, 10), 1000, np.int16), 5))
    (folder / "broken.npy").write_bytes(b"not an array")
    return folder


def read_summary(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def items(paths, views=None, size=(32, 32)):
    return spec.items_from([str(p) for p in paths], [], ReadOptions(), PrepOptions(threshold=500),
                            RenderOptions(size=size), views or spec.parse_views(["anterior"], [(30, 20, 10)]),
                            spec.Patterns())


def test_turntable_turns_the_object_about_its_axis():
    views = spec.turntable(8, "z")
    base = rotation_matrix(*PRESETS["anterior"])
    for k, view in enumerate(views):
        expected = base @ rotation_matrix(0, 0, 45 * k)
        assert np.allclose(rotation_matrix(view.alpha, view.beta, view.gamma), expected, atol=1e-9)
    assert len({v.label for v in views}) == 8


def test_views_and_names():
    assert [v.label for v in spec.parse_views()] == ["anterior"]
    assert [v.label for v in spec.parse_views(["left"], turntable_count=3)][0] == "turn000"
    with pytest.raises(InputError):
        spec.parse_views(["left", "left"])
    with pytest.raises(InputError):
        spec.parse_views(["sideways"])
    assert spec._unique_names(["x/ct", "y/ct", "z/a.npy"]) == ["ct", "ct-2", "a"]


def test_manifests(tmp_path, stacks):
    (tmp_path / "m.csv").write_text("input,threshold,views,method,output\n"
                                    f"{stacks / 'ball.npy'},500,\"left;30,0,0\",btf,{{name}}-{{view}}.png\n"
                                    "in/box.npy,,,,\n")
    rows = spec.read_manifest(tmp_path / "m.csv")
    made = spec.items_from([], rows, ReadOptions(), PrepOptions(threshold=700), RenderOptions(),
                            spec.parse_views(), spec.Patterns())
    assert [v.label for v in made[0].views] == ["left", "a30_b0_g0"] and made[0].method == "btf"
    assert made[0].prepare.threshold == 500 and made[1].prepare.threshold == 700
    assert made[1].input == str(tmp_path / "in" / "box.npy")
    (tmp_path / "m.toml").write_text('[[input]]\ninput = "in/ball.npy"\nviews = "superior"\n')
    assert spec.read_manifest(tmp_path / "m.toml")[0]["views"] == "superior"
    (tmp_path / "bad.csv").write_text("path\nx\n")
    with pytest.raises(InputError, match="'input' column"):
        spec.read_manifest(tmp_path / "bad.csv")


def test_a_manifest_row_keeps_its_labels_with_its_threshold_and_takes_a_name(tmp_path, stacks):
    """A row with both labels and a threshold lost its labels; the same CT once per model needs a name a row."""
    np.save(tmp_path / "in" / "seg.npy", (np.load(stacks / "ball.npy") > 0).astype(np.uint8))
    (tmp_path / "m.csv").write_text("input,name,labels,threshold\n"
                                    "in/ball.npy,model-a,in/seg.npy,500\n"
                                    "in/ball.npy,model-b,in/seg.npy,\n"
                                    "in/box.npy,,,\n")
    made = spec.items_from([], spec.read_manifest(tmp_path / "m.csv"), ReadOptions(), PrepOptions(threshold=700),
                            RenderOptions(), spec.parse_views(), spec.Patterns())
    assert [item.name for item in made] == ["model-a", "model-b", "box"]
    assert made[0].prepare.labels.source == tmp_path / "in" / "seg.npy" and made[0].prepare.threshold == 500
    assert made[1].prepare.labels is not None and made[1].prepare.threshold == 700
    for names, said in [(("a", "a"), "two studies are named 'a'"), (("../up", "b"), "not a file name of its own"),
                        ((".hidden", "b"), "not a file name of its own")]:
        rows = [{"input": str(stacks / "ball.npy"), "name": n} for n in names]
        with pytest.raises(InputError, match=said):
            spec.items_from([], rows, ReadOptions(), PrepOptions(), RenderOptions(), spec.parse_views(),
                             spec.Patterns())


def test_batch_renders_reports_failures_and_resumes(tmp_path, stacks):
    out = tmp_path / "out"
    work = items([stacks / "ball.npy", stacks / "broken.npy", stacks / "box.npy"], size=(40, 48))
    rows = batch.run_batch(work, out, jobs=1)
    assert [r["status"] for r in rows] == ["ok", "ok", "failed", "failed", "ok", "ok"]
    assert "broken.npy" in rows[2]["error"]
    summary = read_summary(out / "summary.csv")
    assert len(summary) == 6 and summary[0]["view"] == "anterior" and json.loads(summary[0]["stats"])["pixels_lit"] > 0
    picture = iio.imread(out / "ball" / "a30_b20_g10.png")
    assert picture.shape == (40, 48) and picture.any()          # no colour: written as 8-bit grey
    assert len(list((out / ".voxrender-cache").glob("*.vxs"))) == 2

    # A run killed half-way leaves whole pictures only; a truncated or missing one is made again.
    (out / "box" / "anterior.png").unlink()
    (out / "ball" / "anterior.png").write_bytes((out / "ball" / "anterior.png").read_bytes()[:50])
    again = batch.run_batch(work, out, jobs=1)
    assert [r["status"] for r in again] == ["ok", "done earlier", "failed", "failed", "ok", "done earlier"]
    assert {tuple(r)[:10] for r in again} == {tuple(tasks.SUMMARY_COLUMNS[:10])}   # one row, whatever its status
    assert iio.imread(out / "ball" / "anterior.png").shape == (40, 48)


def test_cache_is_keyed_by_content_and_options(tmp_path, stacks):
    read = ReadOptions()
    key = cache.cache_key(stacks / "ball.npy", read, PrepOptions(threshold=500))
    assert key == cache.cache_key(stacks / "ball.npy", read, PrepOptions(threshold=500))
    assert key != cache.cache_key(stacks / "ball.npy", read, PrepOptions(threshold=501))
    np.save(tmp_path / "copy.npy", np.load(stacks / "ball.npy") + 1)
    assert key != cache.cache_key(tmp_path / "copy.npy", read, PrepOptions(threshold=500))


def test_worker_processes_give_the_same_pictures(tmp_path, stacks):
    work = items([stacks / "ball.npy", stacks / "box.npy"])
    batch.run_batch(work, tmp_path / "one", jobs=1)
    batch.run_batch(work, tmp_path / "two", jobs=2)
    for name in ("ball/anterior.png", "box/a30_b20_g10.png"):
        assert np.array_equal(iio.imread(tmp_path / "one" / name), iio.imread(tmp_path / "two" / name))


def test_local_dask_cluster(tmp_path, stacks):
    pytest.importorskip("distributed", reason="Dask is the extra 'distributed'")
    work = items([stacks / "ball.npy", stacks / "broken.npy"])
    rows = batch.run_batch(work, tmp_path / "dask", jobs=2, scheduler="local")
    assert [r["status"] for r in rows] == ["ok", "ok", "failed", "failed"]
    reference = tmp_path / "ref"
    batch.run_batch(work[:1], reference, jobs=1)
    assert np.array_equal(iio.imread(tmp_path / "dask" / "ball" / "anterior.png"),
                          iio.imread(reference / "ball" / "anterior.png"))


def test_turntable_animation(tmp_path, stacks):
    work = items([stacks / "ball.npy"], spec.parse_views(turntable_count=6), size=(24, 24))
    batch.run_batch(work, tmp_path, jobs=1, animations=["gif"])
    frames = iio.imread(tmp_path / "ball.gif")
    assert frames.shape[:3] == (6, 24, 24)


def test_mp4_animation(tmp_path, stacks):
    pytest.importorskip("imageio_ffmpeg", reason="MP4 is the extra 'video'")
    work = items([stacks / "ball.npy"], spec.parse_views(turntable_count=4))
    batch.run_batch(work, tmp_path, jobs=1, animations=["mp4"])
    assert (tmp_path / "ball.mp4").stat().st_size > 0


def test_patterns_are_checked(tmp_path, stacks):
    work = items([stacks / "ball.npy"])
    work[0].patterns = spec.Patterns("{name}.png")
    with pytest.raises(InputError, match="twice"):
        batch.run_batch(work, tmp_path, jobs=1)
    work[0].patterns = spec.Patterns("{nope}/{view}.png")
    with pytest.raises(InputError, match="not valid") as info:
        batch.run_batch(work, tmp_path, jobs=1)
    assert info.value.parameter == "picture"                 # --pattern
    work[0].patterns = spec.Patterns(stats_json="{name}/{nope}.json")
    with pytest.raises(InputError, match="'{name}/{nope}.json' is not valid") as info:
        batch.run_batch(work, tmp_path, jobs=1)
    assert info.value.parameter == "stats_json"              # --stats-json, not --pattern
    work[0].patterns = spec.Patterns(depth="{name}/{view}.png")
    with pytest.raises(InputError, match="must end in .npy") as info:
        batch.run_batch(work, tmp_path, jobs=1)
    assert info.value.parameter == "depth"


def test_batch_command(tmp_path, stacks):
    result = CliRunner().invoke(main, ["batch", str(stacks / "*.npy"), "--threshold", "500", "--view", "left",
                                       "--size", "32", "-o", str(tmp_path / "o"), "--jobs", "1"])
    assert result.exit_code == 2
    assert "2 pictures made" in result.output and "failed: " in result.stderr and "broken.npy" in result.stderr
    assert len(read_summary(tmp_path / "o" / "summary.csv")) == 3
    result = CliRunner().invoke(main, ["batch", str(tmp_path / "nothing*"), "-o", str(tmp_path / "o")])
    assert result.exit_code == 2 and "no input matches" in result.stderr


def test_octree_pictures_of_one_object_share_its_octree(stacks, tmp_path):
    # The cache keeps the object with its octree (a .vxo), and a worker keeps the object it rendered last.
    result = CliRunner().invoke(main, ["batch", str(stacks / "ball.npy"), "--threshold", "500", "--turntable", "3",
                                       "--method", "octree-ftb", "--jobs", "1", "--size", "32", "-o",
                                       str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    rows = read_summary(tmp_path / "out" / "summary.csv")
    assert [row["status"] for row in rows] == ["ok"] * 3
    path = next((tmp_path / "out" / ".voxrender-cache").glob("*.vxo"))
    stamp = (path.stat().st_size, path.stat().st_mtime_ns)
    assert cache.load_encoded(str(path), stamp) is cache.load_encoded(str(path), stamp)
    assert cache.load_encoded(str(path), stamp).has_octree          # read from the file, not built


def test_a_turntable_keeps_one_scale_and_centres_every_frame(tmp_path, stacks):
    work = items([stacks / "box.npy"], spec.parse_views(turntable_count=4), size=(40, 40))
    rows = batch.run_batch(work, tmp_path, jobs=1, animations=[])
    assert [row["status"] for row in rows] == ["ok"] * 4
    pictures = [iio.imread(row["output"]) > 0 for row in rows]
    spans = []
    for covered in pictures:
        rows_, columns = np.nonzero(covered)
        spans.append((rows_.max() - rows_.min() + 1, columns.max() - columns.min() + 1))
        assert abs((columns.max() + columns.min()) / 2 - 19.5) <= 1.5      # each frame centred
    # one scale for all: the box's height (along z, up in the picture) is the same in every frame
    assert len({height for height, _ in spans}) == 1


def test_index_page_and_sheet(tmp_path, stacks):
    work = items([stacks / "ball.npy", stacks / "broken.npy"], spec.parse_views(["anterior", "left"]), size=(24, 24))
    batch.run_batch(work, tmp_path, jobs=1, make_sheet=True)
    ball, broken = sorted(read_index(tmp_path / "index.html"), key=lambda study: study.name)
    assert [path for _, path in ball.pictures] == ["ball/anterior.png", "ball/left.png"]  # a row per study, its views
    assert broken.input.endswith("broken.npy") and broken.error                          # the failure keeps its error
    sheet = iio.imread(tmp_path / "sheet.png")
    assert sheet.shape[:2] == (2 * (24 + 16 + 4) + 4, 2 * (24 + 4) + 4)   # a row per input, a column per view


def test_outputs_stay_inside_the_batch_folder(tmp_path, stacks):
    out = tmp_path / "out"
    work = items([stacks / "ball.npy"])
    refused = [("../../escaped.png", "picture"), (str(tmp_path / "abs" / "{view}.png"), "picture"),
               ("{name}/../../{view}.png", "picture")]
    for pattern, parameter in refused:
        work[0].patterns = spec.Patterns(pattern)
        with pytest.raises(InputError, match="outside the batch's folder") as info:
            batch.run_batch(work, out, jobs=1)
        assert info.value.parameter == parameter
    work[0].patterns = spec.Patterns(depth="../{name}-{view}.npy")
    with pytest.raises(InputError, match="outside") as info:
        batch.run_batch(work, out, jobs=1)
    assert info.value.parameter == "depth"
    assert not out.exists() and not list(tmp_path.rglob("*.png"))      # refused before anything was made

    (tmp_path / "elsewhere").mkdir()
    out.mkdir()
    (out / "link").symlink_to(tmp_path / "elsewhere")                   # a link inside that points out
    work[0].patterns = spec.Patterns("link/{view}.png")
    with pytest.raises(InputError, match=r"outside the batch's folder .* \(a symbolic link leads to .*elsewhere"):
        batch.run_batch(work, out, jobs=1)
    assert not list((tmp_path / "elsewhere").iterdir())
    work[0].patterns = spec.Patterns("a/../{view}.png")                # a '..' that stays inside is fine
    assert [r["status"] for r in batch.run_batch(work, out, jobs=1)] == ["ok", "ok"]


def test_inputs_are_never_written(tmp_path, stacks):
    work = items([stacks / "ball.npy"], spec.parse_views(["left"]))
    work[0].patterns = spec.Patterns(depth="in/{name}.npy")
    before = (stacks / "ball.npy").read_bytes()
    with pytest.raises(InputError, match="over or inside the input .*ball.npy"):
        batch.run_batch(work, tmp_path, jobs=1)
    assert (stacks / "ball.npy").read_bytes() == before
    folder = tmp_path / "slices"               # a folder input: nothing is written inside it, not even the cache
    folder.mkdir()
    work = items([folder], spec.parse_views(["left"]))
    with pytest.raises(InputError, match="over or inside the input"):
        batch.run_batch(work, folder / "out", jobs=1)
    with pytest.raises(InputError, match="the cache .* would be written inside the input"):
        batch.run_batch(work, tmp_path / "out", jobs=1, cache_dir=folder / "cache")
    assert list(folder.iterdir()) == []


def test_a_manifest_output_outside_the_folder_is_refused_in_one_line(tmp_path, stacks):
    (tmp_path / "m.csv").write_text(f"input,output\n{stacks / 'ball.npy'},../../escaped.png\n")
    result = CliRunner().invoke(main, ["batch", "--manifest", str(tmp_path / "m.csv"), "--threshold", "500",
                                       "-o", str(tmp_path / "out" / "deep"), "--jobs", "1"])
    assert result.exit_code == 2 and len(result.stderr.splitlines()) == 1
    assert "the manifest's output pattern '../../escaped.png'" in result.stderr and "--pattern" not in result.stderr
    assert not (tmp_path / "escaped.png").exists() and not (tmp_path / "out").exists()
    result = CliRunner().invoke(main, ["batch", str(stacks / "ball.npy"), "--pattern", "/tmp/{name}.png",
                                       "-o", str(tmp_path / "out"), "--jobs", "1"])
    assert result.exit_code == 2 and result.stderr.startswith("error: --pattern: output pattern '/tmp/{name}.png'")
    (tmp_path / "m.csv").write_text(f"input,output\n{stacks / 'ball.npy'},{{nope}}.png\n")
    result = CliRunner().invoke(main, ["batch", "--manifest", str(tmp_path / "m.csv"), "-o", str(tmp_path / "out")])
    assert result.exit_code == 2 and "the manifest's output pattern '{nope}.png' is not valid" in result.stderr
    assert "--pattern" not in result.stderr


def test_a_manifest_row_naming_no_file_fails_its_row_as_bad_input(tmp_path, stacks):
    (tmp_path / "m.csv").write_text(f"input\n{stacks / 'ball.npy'}\nmissing.npy\n*.npy\n")
    result = CliRunner().invoke(main, ["batch", "--manifest", str(tmp_path / "m.csv"), "--threshold", "500",
                                       "--size", "24", "-o", str(tmp_path / "out"), "--jobs", "1"])
    rows = {Path(row["input"]).name: row for row in read_summary(tmp_path / "out" / "summary.csv")}
    assert result.exit_code == 2 and "internal error" not in result.output + result.stderr
    assert rows["ball.npy"]["status"] == "ok"
    for name in ("missing.npy", "*.npy"):
        assert rows[name]["status"] == "failed" and "no such file or folder" in rows[name]["error"]


def test_qc_sheets_are_made_of_slice_stacks_and_an_encoded_object_still_renders(tmp_path, stacks):
    from voxrender.object import segments
    from voxrender.qc.qc import SliceOptions

    encoded = tmp_path / "ball.vxs"
    vxs.save(segments.encode(np.load(stacks / "ball.npy") > 500), encoded)
    work = spec.items_from([str(stacks / "box.npy"), str(encoded)], [], ReadOptions(), PrepOptions(threshold=500),
                            RenderOptions(size=(24, 24)), spec.parse_views(["anterior"]), spec.Patterns(),
                            qc_sheet=True, slices=SliceOptions(("axial",)))
    rows = batch.run_batch(work, tmp_path / "out", jobs=1, make_sheet=True)
    assert [row["status"] for row in rows] == ["ok", "ok"]
    assert sorted(p.name for p in (tmp_path / "out" / "sheets").iterdir()) == ["box.png"]   # no grey values, no sheet
    sheets = {study.name: study.sheet for study in read_index(tmp_path / "out" / "index.html")}
    assert sheets == {"box": "sheets/box.png", "ball": None}


def test_a_rerun_keeps_each_pictures_labels_in_the_summary_and_the_page(tmp_path, stacks):
    from voxrender.object.prep import LabelSelection

    labels = np.zeros((12, 12, 12), np.uint8)
    labels[2:6, 2:6, 2:6], labels[7:10, 7:10, 7:10] = 1, 2
    np.save(tmp_path / "map.npy", labels)
    work = spec.items_from([str(tmp_path / "map.npy"), str(stacks / "box.npy")], [], ReadOptions(),
                            PrepOptions(threshold=None, labels=LabelSelection()), RenderOptions(size=(24, 24)),
                            spec.parse_views(["anterior"]), spec.Patterns())
    work[1].prepare = PrepOptions(threshold=500)                # a CT alone: no labels, so none missing
    pages = []
    for _ in range(2):
        rows = batch.run_batch(work, tmp_path / "out", jobs=1)
        pages.append(read_index(tmp_path / "out" / "index.html"))
        summary = read_summary(tmp_path / "out" / "summary.csv")
        assert json.loads(summary[0]["label_volumes"])[1]["voxels"] == 27
    assert [row["status"] for row in rows] == ["done earlier", "done earlier"]
    tables = [[study.labels for study in page] for page in pages]
    assert tables[0] == tables[1] and [label["voxels"] for label in tables[1][0]] == [64, 27]   # the map's, kept
    assert tables[1][1] == [] and missing_labels(pages[1]) == {}    # the CT alone lacks no label: it has none


def test_summary_cells_that_begin_like_a_formula_are_quoted_and_a_rerun_reads_them_back(tmp_path, stacks):
    """OWASP's CSV injection: a spreadsheet runs a cell that begins with =, +, - or @ as a formula."""
    shutil.copy(stacks / "box.npy", stacks / "=1+2.npy")
    shutil.copy(stacks / "box.npy", stacks / "@SUM(A1).npy")
    work = items([stacks / "=1+2.npy", stacks / "@SUM(A1).npy"])
    for _ in range(2):
        batch.run_batch(work, tmp_path / "out", jobs=1)
        rows = read_summary(tmp_path / "out" / "summary.csv")
        cells = [cell for row in rows for cell in row.values()]
        formulas = [cell for cell in cells if cell[:1] in ("=", "+", "@") or cell[:1] == "-" and not _number(cell)]
        assert not formulas, formulas
        assert {row["name"] for row in rows} == {"'=1+2", "'@SUM(A1)"}
    assert {row["status"] for row in rows} == {"done earlier"}              # the quoted outputs read back


def _number(text):
    try:
        float(text)
        return True
    except ValueError:
        return False
