"""The benchmark's pieces run on small data (its timings are not asserted: machines are noisy)."""

import numpy as np

from benchmarks import bench
from voxrender import segments
from voxrender.view import View


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
    segments.save(segments.encode(bench.thin_shell(16, 6.0)), small)
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
                                                             View(30, 10, 0, (32, 32), 1.2))})}
    text = bench.markdown(results)
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
