"""The big-stack benchmark section on a small stack: its synthetic micro-CT, its measurements, its table (timings are
not asserted: machines are noisy)."""

import sys

import numpy as np
import pytest
import tifffile

from benchmarks import big_stack


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("VOXRENDER_BENCH_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


def read_stack(folder):
    return np.stack([tifffile.imread(folder / name) for name in big_stack.slice_names(32)])


def test_the_stack_is_written_once_and_the_same_every_time(cache, tmp_path):
    folder = big_stack.cache_root() / "stack-32"
    assert folder.parent == cache
    assert big_stack.write_stack(folder, 32)
    names = sorted(p.name for p in folder.glob("*.tif"))
    assert names == big_stack.slice_names(32) and names[0] == "slice_0000.tif"
    first = read_stack(folder)
    assert first.dtype == np.uint16 and first.shape == (32, 32, 32)
    assert tifffile.TiffFile(folder / names[0]).pages.first.compression == 1     # uncompressed
    stamps = [p.stat().st_mtime_ns for p in sorted(folder.glob("*.tif"))]
    assert not big_stack.write_stack(folder, 32)                                 # kept: its marker says complete
    assert [p.stat().st_mtime_ns for p in sorted(folder.glob("*.tif"))] == stamps
    other = tmp_path / "again"
    big_stack.write_stack(other, 32)
    assert np.array_equal(read_stack(other), first)                             # seeded: the same bytes


def test_a_half_written_stack_is_written_again(cache):
    folder = cache / "stack-32"
    big_stack.write_stack(folder, 32)
    assert big_stack.is_complete(folder, 32)
    first = read_stack(folder)
    (folder / big_stack.MARKER).unlink()                  # as if stopped before the marker
    (folder / "slice_0031.tif").unlink()
    (folder / "slice_9999.tif").write_bytes(b"left over")
    assert big_stack.write_stack(folder, 32)
    assert big_stack.is_complete(folder, 32) and not (folder / "slice_9999.tif").exists()
    assert np.array_equal(read_stack(folder), first)
    assert not big_stack.is_complete(folder, 64)          # another side's parameters


def test_bone_pores_and_the_partial_volume_between(cache):
    folder = cache / "stack-32"
    big_stack.write_stack(folder, 32)
    values = read_stack(folder).astype(float)
    assert big_stack.PORE < big_stack.THRESHOLD < big_stack.BONE
    assert abs(np.percentile(values, 5) - big_stack.PORE) < 150           # pores and background
    assert abs(np.percentile(values, 95) - big_stack.BONE) < 150          # bone
    bone = values >= big_stack.THRESHOLD
    assert 0.1 < bone.mean() < 0.6
    between = (values > big_stack.PORE + 500) & (values < big_stack.BONE - 500)
    assert between.mean() > 0.05                                           # the surface's partial volume
    corner = values[:, :3, :3]                                             # outside the cortex
    assert abs(corner.mean() - big_stack.PORE) < 30 and 20 < corner.std() < 60   # the noise


def test_the_stack_reads_as_a_volume(cache):
    from voxrender import io

    folder = cache / "stack-32"
    big_stack.write_stack(folder, 32)
    volume = io.read_volume(folder)
    assert volume.values.shape == (32, 32, 32)


def test_measure_a_fresh_process():
    done = big_stack.measure([sys.executable, "-c", "import numpy; numpy.ones(80_000_000, 'u1')"], drop_caches=False)
    assert done["ok"] and done["error"] is None and done["seconds"] > 0
    assert done["cache"] == "not dropped (asked)"
    if done["peak_mb"] is not None:                        # /usr/bin/time is there
        assert done["peak_mb"] > 80
    failed = big_stack.measure("echo first >&2; echo 'the last line' >&2; exit 3", drop_caches=False)
    assert not failed["ok"] and failed["error"] == "the last line"


def test_the_page_cache_dropped_or_why_not(monkeypatch, tmp_path):
    monkeypatch.setattr(big_stack, "DROP_CACHES", tmp_path / "absent" / "drop_caches")
    done = big_stack.measure("true")
    assert done["cache"].startswith("page cache not dropped")


def test_the_side_the_disk_holds(cache, monkeypatch):
    def free(gib):
        monkeypatch.setattr(big_stack.shutil, "disk_usage", lambda path: type("Usage", (), {"free": gib * 2 ** 30}))

    free(100)
    assert big_stack.choose_side()[0] == 2048
    free(18)                                               # 16 GiB fits, its outputs not
    side, why = big_stack.choose_side()
    assert big_stack.SMALLEST_SIDE <= side < 2048 and "largest" in why
    assert big_stack.stack_bytes(side) * (1 + big_stack.OUTPUT_ROOM) <= 18 * 2 ** 30
    free(5)
    side, why = big_stack.choose_side()
    assert side is None and "skipped" in why
    result = big_stack.bench_big_stack(drop_caches=False)
    assert result["rows"] == [] and "skipped" in result["skipped"]
    assert "skipped" in big_stack.markdown(result)
    assert big_stack.choose_side(side=32)[0] == 32


def test_the_section_end_to_end(cache):
    result = big_stack.bench_big_stack(side=32, drop_caches=False)
    rows = {row["name"]: row for row in result["rows"]}
    assert list(rows) == ["cat", "encode", "encode --bin 2", "encode --jobs 1", "ftb 1024^2", "encode STACK --levels",
                          "encode --levels", "ftb 1024^2, levels", "ftb 512^2, levels"]
    assert rows["encode --levels"]["growth"] > 1 and set(rows["ftb 512^2, levels"]["targets"]) == {
        "<= 2 s", "RSS <= 1 GB"}
    # --bin and --jobs may not exist yet: recorded, not asserted
    for name in ("cat", "encode", "ftb 1024^2", "encode STACK --levels", "encode --levels", "ftb 512^2, levels"):
        assert rows[name]["ok"], rows[name]["error"]
        assert rows[name]["seconds"] > 0 and rows[name]["cache"] == "not dropped (asked)"
    assert rows["encode"]["ratio_to_cat"] > 0
    assert set(rows["encode"]["targets"]) == {"RSS <= 2 GB", "<= 3 x cat", "<= 1.5 x cat (moonshot)"}
    assert set(rows["ftb 1024^2"]["targets"]) == {"<= 5 s", "RSS <= 2 GB"}
    for row in rows.values():
        assert row["ok"] or row["error"]
    assert (cache / "outputs-32" / "encode.vxs").is_file() and (cache / "outputs-32" / "ftb.png").is_file()
    assert result["write_s"] is not None
    text = big_stack.markdown(result)
    assert "| command | wall s | peak RSS MB | / cat | targets |" in text
    assert "`voxrender encode STACK -o encode.vxs --threshold 2250`" in text and "not dropped" in text
    kept = big_stack.markdown({**result, "write_s": None, "repeat": 3})
    assert "kept from the cache" in kept and "medians of 3" in kept
