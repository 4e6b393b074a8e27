"""The benchmark's pieces run on small data (its timings are not asserted: machines are noisy)."""

import numpy as np
import pytest
from conftest import absent

from benchmarks import bench
from voxrender.object import segments, vxs
from voxrender.space.view import View


def test_scaling_section_runs_on_the_phantoms():
    result = bench.bench_scaling(repeat=1, sizes=(12, 16, 20))
    for kind in ("sphere", "gyroid"):
        rows = result[kind]["rows"]
        assert [row["n"] for row in rows] == [12, 16, 20]
        assert [row["voxels"] for row in rows] == [int(bench.phantom(kind, n).sum()) for n in (12, 16, 20)]
        assert set(result[kind]["exponents"]) == set(bench.SCALING_METHODS)


def test_exponents_of_a_power_law():
    rows = [{"n": n, "a": 2.0 * n ** 1.5, "b": 0.1 * n ** 3} for n in (16, 32, 64, 100)]
    fitted = bench.fit_exponents(rows, ["a", "b"])
    for key in ("exponents", "exponents_largest"):
        assert np.allclose([fitted[key]["a"], fitted[key]["b"]], [1.5, 3.0])


def test_phantoms():
    assert bench.phantom("sphere", 20).sum() > bench.phantom("gyroid", 20).sum() > 0


def test_markdown_report(tmp_path):
    small = tmp_path / "small.vxs"
    vxs.save(segments.encode(bench.thin_shell(16, 6.0)), small)
    stage = {"render": 0.1, "shade": 0.02}
    stages = {"load_s": 0.001, "write_s": 0.002, "vtk_s": 0.246, "normals_at_encode_s": 1.0, "gradient": stage,
              "gradient + ao": stage, "depth-gradient": stage, "fresh": bench._fresh_stages(small, 1, 32)}
    results = {"stages": stages, "when": "now", "machine": "here", "repeat": 1, "read_s": 1.0, "vtk_version": None,
               "encode": {"grid_xyz": [4, 4, 4], "voxels": 8, "segments": 4, "threshold_and_encode_s": 0.1},
               "views": [{"alpha": 1.0, "beta": 2.0, "seconds": {m: 1.0 for m in bench.timed_methods()}}],
               "pipeline": {"command": "c", "seconds": 1.0, "method": "ftb"},
               "read": {"DICOM folder": {"seconds": 0.5, "megabytes": 123.0}, ".nii.gz": {"seconds": 0.25,
                                                                                        "megabytes": 17.0}},
               "scaling": bench.bench_scaling(repeat=1, sizes=(8, 10)),
               "projection": bench.bench_projection(np.arange(120, dtype=np.int16).reshape(4, 5, 6), 1, size=8),
               "raycast": bench.bench_raycast(1, {"shell": (segments.encode(bench.thin_shell(24, 9.0)),
                                                             View(30, 10, 0, (32, 32), 1.2))}),
               "agreement": {"grid_xyz": [512, 512, 234], "cases": {"organs": {
                   "structures": 3, "voxrender_s": 0.5, "surface_distance_s": 6.0, "speedup": 12.0,
                   "largest_difference": 0.0}}}}
    text = bench.markdown(results)
    assert "| organs | 3 | 0.50 | 6.00 | 12.0x | 0 |" in text
    assert "| .nii.gz | 17.0 | 0.25 |" in text
    assert "| 1 | 2 |" in text and "fitted exponent" in text and "peers" in text and "| shell | adaptive |" in text
    assert "| gradient | 0.001 | 0.100 | 0.020 | 0.002 | 0.123 | 0.246 | 0.50 |" in text
    assert "| gradient, fresh process |" in text and "In a fresh process" in text
    assert "Maximum intensity projection of the 6 x 5 x 4 volume" in text and "| anterior |" in text
    rows = results["raycast"]["shell"]["rows"]
    assert rows["adaptive"]["leaks"] == 0 and rows["26"]["leaks"] > 0


def test_mask_folder_section_runs_small():
    from benchmarks.masks import bench_mask_folder

    result = bench_mask_folder(1, shape=(12, 16, 20), count=5)
    assert result["masks"] == 5 and result["grid_xyz"] == [20, 16, 12] and result["mask_folder_s"] > 0


def test_projection_section_runs_small():
    """The MIP section on a tiny volume, beside VTK's when VTK is installed."""
    values = np.random.default_rng(5).integers(-1000, 2000, size=(12, 16, 20)).astype(np.int16)
    try:
        peer = bench.VtkMipPeer(values)
    except ImportError:
        peer = None
    result = bench.bench_projection(values, 1, peer=peer, size=32)
    assert [row["view"] for row in result["rows"]] == list(bench.PROJECTION_VIEWS)
    assert all(row["seconds"] > 0 for row in result["rows"])
    if peer is not None:
        assert all(row["vtk_s"] > 0 and row["ratio"] > 0 for row in result["rows"])
        picture = peer.picture(View(90.0, 0.0, 0.0, (32, 32), 1.0))
        assert picture.shape == (32, 32, 3) and picture.any()
    text = "\n".join(bench._projection_table(result))
    assert "| anterior |" in text and result["grid_xyz"] == [20, 16, 12]
    alone = bench.bench_projection(values, 1, size=16)          # without VTK: no peer columns
    assert not any("vtk_s" in row for row in alone["rows"]) and "vtk" not in "".join(bench._projection_table(alone))


def _tiny_sources():
    """Two small CT-like volumes in place of vhf_head and headsq: a bright ball in air."""
    z, y, x = np.mgrid[:30, :36, :40]
    big = np.where((z - 15) ** 2 + (y - 18) ** 2 + (x - 20) ** 2 < 13 ** 2, 700, -1000).astype(np.int16)
    z, y, x = np.mgrid[:20, :16, :16]
    small = np.where((z - 10) ** 2 + (y - 8) ** 2 + (x - 8) ** 2 < 7 ** 2, 1500, 0).astype(np.int16)
    return {"vhf_head": (big, (1.0, 1.0, 1.0), 300.0), "headsq": (small, (3.2, 3.2, 1.5), 1150.0)}


def test_write_studies_gives_distinct_studies_voxrender_reads(tmp_path):
    from benchmarks import studies
    from voxrender import io

    cut_from = _tiny_sources()
    written = studies.write_studies(tmp_path, count=8, cut_from=cut_from)
    assert [s["format"] for s in written] == ["dicom", "nifti"] * 4
    assert [s["format"] for s in written if s["source"] == "headsq"] == ["nifti", "dicom"]
    assert len({(tuple(s["shape"]), tuple(s["flips"]), tuple(s["origin"])) for s in written}) == 8
    assert len({tuple(s["origin"]) for s in written}) == 8
    for study in written:
        volume = io.read_volume(study["path"])
        expected = studies.cut(cut_from[study["source"]][0], study)
        assert volume.shape == tuple(study["shape"]) == expected.shape
        assert np.array_equal(np.asarray(volume.values), expected)            # LPS axes: read as written
        assert np.allclose(volume.spacing, study["spacing"])
    again = studies.write_studies(tmp_path, count=8, cut_from={})          # the cache: nothing is cut again
    assert again == written


def test_vtk_script_renders_the_studies(tmp_path):
    """The VTK script draws each study's views, framed on the object (skipped without VTK)."""
    from benchmarks import studies

    if not studies.vtk_available():
        pytest.skip("vtk is not installed (pip install -e '.[peers]')")
    written = studies.write_studies(tmp_path / "studies", count=2, cut_from=_tiny_sources())
    wall, seconds = studies.run_vtk(written, tmp_path / "vtk", size=48)
    assert wall > 0 and set(seconds) >= {"import", "read", "render", "write", "total"}
    for study in written:       # framed: the ball fills much of the picture, never all (VTK leaves cut faces black)
        drawn = [studies.drawn_pixels(tmp_path / "vtk" / study["name"] / f"{view}.png") for view in studies.VIEWS]
        assert max(drawn) > 0.2 * 48 * 48 and max(drawn) < 48 * 48


def test_studies_section_runs_small(tmp_path):
    """The batch beside the VTK script (when installed) on two tiny studies, and its lines."""
    from benchmarks import studies

    written = studies.write_studies(tmp_path / "studies", count=2, cut_from=_tiny_sources())
    result = studies.bench_studies(written, 1, size=32)
    assert set(result["rows"]) >= {"jobs 1", "jobs 2"} and result["studies"] == 2
    assert set(result["batch_stages"]["jobs 1"]) == {"load", "prepare", "render", "shade", "write"}
    assert len(result["pixels"]["voxrender"]) == len(studies.VIEWS)
    text = "\n".join(studies.markdown_lines({"studies": result}))
    assert "| `voxrender batch --jobs 2` |" in text


def test_compare_table_on_fake_timings():
    from benchmarks import compare

    seconds = {"whole command": {"working": [1.0, 3.0, 2.0], "ref": [4.0, 4.0, 5.0]},
               "encode --octree head x4": {"working": [2.0], "ref": []},
               "  ftb render (its --stats-json)": {"working": [0.5], "ref": [0.25]}}
    failed = {"encode --octree head x4": {"ref": "exit 2: error: no such option: --octree"}}
    lines = compare.table(seconds, failed, ("working (abc)", "ref (def)"))
    assert lines[0] == "| figure | working (abc) s | ref (def) s | working/ref |"
    assert "| whole command | 2.000 | 4.000 | 0.50 |" in lines
    assert "| encode --octree head x4 | 2.000 | failed (exit 2: error: no such option: --octree) | - |" in lines
    assert "|   ftb render (its --stats-json) | 0.500 | 0.250 | 2.00 |" in lines


def test_studies_markdown_on_fake_results():
    from benchmarks import studies

    rows = {"jobs 1": {"seconds": 20.0, "per_minute": 72.0}, "jobs 2": {"seconds": 10.0, "per_minute": 144.0},
            "vtk": {"seconds": 40.0, "per_minute": 36.0}}
    results = {"commit": "abc", "load": 1.0,
               "studies": {"studies": 24, "views": 4, "size": 512, "repeat": 3, "rows": rows,
                           "formats": {"dicom": 12, "nifti": 12}, "sources": {"vhf_head": 18, "headsq": 6},
                           "pixels": {"voxrender": [10, 20], "vtk": [11, 19]},
                           "batch_stages": {"jobs 1": {"load": 0.4, "prepare": 0.8, "render": 0.08, "shade": 0.07,
                                                       "write": 0.01}}},
               "whole_command": {"command": "voxrender render vhf_head", "repeat": 3, "wall": 0.8,
                                 "stages": {"load": 0.3, "prepare": 0.2}, "vtk_wall": 2.0,
                                 "vtk_stages": {"import": 0.6, "total": 1.9}, "pixels": {"voxrender": 5, "vtk": 6}}}
    text = "\n".join(studies.markdown_lines(results))
    assert "voxrender `--jobs 2` / VTK: 4.00x (target >= 3x: met)" in text
    assert "144 studies per minute (target >= 120: met)" in text
    assert "0.80 s wall (target <= 0.5 s: missed)" in text and "voxrender / VTK wall 0.40" in text
    assert "- inside `voxrender batch --jobs 1` (its summary.csv, mean seconds): per study load 0.400" in text


def test_batch_stages_from_a_summary(tmp_path):
    from benchmarks import studies

    summary = tmp_path / "summary.csv"
    summary.write_text("input,view,status,load_s,prepare_s,render_s,shade_s,write_s\n"
                       "a,v1,ok,1.0,2.0,0.1,0.2,0.3\na,v2,ok,1.0,2.0,0.3,0.2,0.1\nb,v1,ok,3.0,4.0,0.2,0.2,0.2\n"
                       "c,v1,failed,,,,,\n")
    stages = studies.batch_stages(summary)
    assert stages == pytest.approx({"load": 2.0, "prepare": 3.0, "render": 0.2, "shade": 0.2, "write": 0.2})


def test_agreement_section_runs_small_and_agrees_with_surface_distance(tmp_path):
    pytest.importorskip("surface_distance", reason="surface-distance is a test dependency")
    from benchmarks.agreement import bench_agreement

    zz, yy, xx = np.mgrid[:24, :28, :32]
    radius = np.sqrt((xx - 16) ** 2 + (yy - 14) ** 2 + (zz - 12) ** 2)
    ct = np.select([radius < 5, radius < 8, radius < 11], [-900, 500, 40], -1000).astype(np.int16)   # air in bone
    np.save(tmp_path / "head.npy", ct)
    result = bench_agreement(tmp_path / "head.npy", 1)
    for case in result["cases"].values():
        assert case["structures"] > 0 and case["largest_difference"] < 1e-6 and case["speedup"] > 0
    assert result["cases"]["3 tissues filling the head"]["structures"] == 3


def test_index_page_section_runs_small():
    from benchmarks.index_page import bench_index_page

    result = bench_index_page(studies=60, repeat=1)
    assert result["studies"] == 60 and result["seconds"] > 0 and result["bytes_per_study"] > 100


def test_index_browser_section_runs_small():
    from benchmarks.bench import _index_browser_lines
    from benchmarks.index_page import bench_index_browser, chromium_absent

    if chromium_absent():
        absent(f"browser benchmark: {chromium_absent()}")
    result = bench_index_browser(studies=150, batch=3, repeat=1)
    assert result["studies"] == 150 and result["rows_s"] > 0 and result["batch"]["turns"] == 6
    assert "| j pressed 200 times through Playwright |" in "\n".join(_index_browser_lines(result))


def test_issue_35_targets_table_from_fake_results():
    from benchmarks import targets

    big = [{"name": "ftb 1024^2, levels", "command": "render 1024", "seconds": 4.2, "peak_mb": 950.0, "ok": True},
           {"name": "ftb 512^2, levels", "command": "render 512", "seconds": 2.1, "peak_mb": 450.0, "ok": True},
           {"name": "encode", "command": "encode STACK", "seconds": 90.0, "peak_mb": 700.0, "ok": True,
            "ratio_to_cat": 3.6}]
    commands = {"repeat": 1, "seconds": {"surface": 1.5, "mip": 1.6, "encode": 3.0, "encode --octree": 5.5,
                                         "import voxrender.cli": 0.2},
                "commands": {name: name for name in ("surface", "mip", "encode", "encode --octree",
                                                     "import voxrender.cli")}}
    views = [{"alpha": 30.0, "beta": 10.0, "seconds": {"ftb": 0.05, "vtk": 0.2}},
             {"alpha": 60.0, "beta": 120.0, "seconds": {"ftb": 0.09, "vtk": 0.15}}]
    results = {"big_stack": {"rows": big}, "commands": commands, "views": views,
               "projection": {"rows": [{"view": "anterior", "ratio": 0.3}, {"view": "(30, 10)", "ratio": 1.2}]},
               "studies": {"studies": {"rows": {"jobs 2": {"per_minute": 150.0}, "vtk": {"per_minute": 50.0}}}},
               "raycast": {"vhf_head 300 HU": {"rows": {"adaptive": {"seconds": 0.7}}}}}
    met = {(item, target): ok for item, _, _, target, ok in targets.target_rows(results)}
    assert met == {("1: a picture from the levels", "<= 5 s in <= 1 GB"): True,
                   ("1: a picture from the levels", "<= 2 s in <= 1 GB"): False,
                   ("2: the big encode", "<= 3 x cat"): False,
                   ("3: the projection command", "<= 1.1 x"): True,          # 1.6 / 1.5
                   ("3: the MIP render against VTK's MIP", "<= 1 x at every view"): False,
                   ("4: `encode --octree`", "<= 2 s over"): False,            # 2.5 s over
                   ("5: ftb against VTK", "<= 0.5 x"): False,                 # 0.6 at (60, 120)
                   ("5: the batch against VTK", ">= 3 x"): True,
                   ("5: ray casting against VTK", "<= 4 x"): True,            # 0.7 / 0.2
                   ("5: the start", "no slower (0.22 s on 2026-12-03)"): None}
    table = "\n".join(targets.markdown_lines(results))
    assert "| 4: `encode --octree` | `encode --octree` against `encode` (the head stacked four times) | " \
           "5.50 - 3.00 = +2.50 s | <= 2 s over | missed | the leaves' face adjacency" in table
    assert "| 1.60 / 1.50 s = 1.07 x | <= 1.1 x | met |  |" in table
