"""Streaming encode (voxrender.object.stream): a stack encoded a slab at a time gives the in-memory encode's file, byte
for byte, in every orientation and with every step of the selection; in worker processes too.
"""

import itertools
from dataclasses import replace

import numpy as np
import pytest

from voxrender.errors import InputError
from voxrender.object import prep, vxs
from voxrender.object.pipeline import PrepOptions, ReadOptions, load_segments
from voxrender.object.stream import encode_stack
from voxrender.space import orient

SHAPE = (13, 11, 15)


def porous(shape=SHAPE, seed=0):
    """A porous solid with smooth grey values and a little noise (int16, CT-like)."""
    z, y, x = np.mgrid[:shape[0], :shape[1], :shape[2]]
    field = np.sin(x / 2.3) * np.cos(y / 1.7) + np.sin(y / 2.1) * np.cos(z / 1.9) + np.sin(z / 2.7) * np.cos(x / 3.1)
    noise = np.random.default_rng(seed).normal(0, 20, shape)
    return (1000 + 800 * np.tanh(field * 2) + noise).astype(np.int16)


def same_file(tmp_path, name, read, prepare, slabs=(1, 3), jobs=1, scheduler=None, levels=False):
    """Encode in memory and streamed (slabs of so many slices); assert the two files are the same bytes."""
    expected = tmp_path / "memory.vxs"
    load_segments(tmp_path / name, read, prepare).save(expected, levels=levels)
    plane = SHAPE[1] * SHAPE[2]
    for slab in slabs:
        streamed = tmp_path / f"streamed-{slab}.vxs"
        encode_stack(tmp_path / name, streamed, read, prepare, slab_voxels=slab * plane,
                     jobs=jobs, scheduler=scheduler, levels=levels)
        assert streamed.read_bytes() == expected.read_bytes(), (name, read, prepare, slab)
    return vxs.load(expected)


CODES = ["".join(letters) for axes in itertools.permutations(["LR", "PA", "SI"])
         for letters in itertools.product(*axes)]


@pytest.mark.parametrize("code", CODES)
def test_every_orientation_gives_the_same_file(tmp_path, code):
    np.save(tmp_path / "v.npy", porous())
    same_file(tmp_path, "v.npy", ReadOptions(orientation=code, spacing=(0.9, 1.0, 1.3)), PrepOptions(threshold=1000))


def test_the_cases_say_how_the_stack_is_read(tmp_path):
    np.save(tmp_path / "v.npy", porous())
    hows = {code: encode_stack(tmp_path / "v.npy", tmp_path / "o.vxs", ReadOptions(orientation=code),
                               PrepOptions(threshold=1000))["how"] for code in ("LPS", "RAS", "LPI", "SLP")}
    assert hows == {"LPS": "stored order", "RAS": "stored order", "LPI": "from the far end",
                    "SLP": "across the stored slices"}
    assert orient.code_of(orient.direction_of("SLP")) == "SLP"


@pytest.mark.parametrize("read, prepare", [
    (ReadOptions(), PrepOptions()),                                                     # Otsu's threshold
    (ReadOptions(orientation="LPI"), PrepOptions(threshold=prep.Interval(800, 1500))),
    (ReadOptions(spacing=(0.7, 0.9, 1.3), orientation="RAI"),
     PrepOptions(threshold=1000, crop=(slice(2, 12), slice(1, 10), slice(3, 14)))),
    (ReadOptions(spacing=(1.0, 1.0, 2.0)), PrepOptions(threshold=1000, bin=2)),
    (ReadOptions(), PrepOptions(threshold=900, bin=3, crop=(slice(1, 12), slice(None), slice(2, 14)))),
    (ReadOptions(spacing=(1, 1, 1.4)), PrepOptions(threshold=None, tissues=(
        ("soft", prep.Interval(600, 1200), (1, 0, 0)), ("bone", prep.Interval(1200), (0, 1, 0))))),
    (ReadOptions(), PrepOptions(threshold=1000, voxel=0.6)),                            # finer than the input
    (ReadOptions(spacing=(1.0, 1.0, 2.0)), PrepOptions(bin=2)),                         # Otsu of binned values
    (ReadOptions(spacing=(1, 1, 1.000001)), PrepOptions(threshold=1000)),               # all but cubic
    (ReadOptions(spacing=(1.000001, 1, 1), orientation="SLP"), PrepOptions(threshold=1000)),
])
def test_every_step_of_the_selection_gives_the_same_file(tmp_path, read, prepare):
    np.save(tmp_path / "v.npy", porous())
    same_file(tmp_path, "v.npy", read, prepare)


@pytest.mark.parametrize("read, prepare", [
    (ReadOptions(), PrepOptions(threshold=1000)),
    (ReadOptions(spacing=(1, 1, 1.4)), PrepOptions(threshold=None, tissues=(
        ("soft", prep.Interval(600, 1200), (1, 0, 0)), ("bone", prep.Interval(1200), (0, 1, 0))))),
    (ReadOptions(spacing=(1.0, 1.0, 2.0)), PrepOptions(threshold=1000, bin=2)),
    (ReadOptions(orientation="LPI"), PrepOptions(threshold=1000, crop=(slice(1, 12), slice(1, 10), slice(0, 14)))),
])
@pytest.mark.parametrize("slabs", [(1, 3, 6), (20,)])
def test_levels_made_as_the_slabs_pass_are_those_made_from_the_whole_object(tmp_path, read, prepare, slabs):
    """The 2 x level made from each slab as it passes (slabs of whole coarse slices), and the coarser ones from
    it, give the file that the object in memory saved with its levels gives: odd and even grids, labels,
    binning, a crop; the binary mask's normals too."""
    np.save(tmp_path / "v.npy", porous())
    same_file(tmp_path, "v.npy", read, prepare, slabs=slabs, levels=True)
    if not prepare.tissues:
        np.save(tmp_path / "b.npy", porous() > 1000)
        same_file(tmp_path, "b.npy", read, replace(prepare, threshold=1), slabs=slabs[:1], levels=True)


def test_float_values_with_nan_and_a_binary_mask(tmp_path):
    values = porous().astype(np.float32)
    values[np.random.default_rng(1).random(SHAPE) < 0.02] = np.nan
    np.save(tmp_path / "f.npy", values)
    same_file(tmp_path, "f.npy", ReadOptions(spacing=(1, 1, 1.5)), PrepOptions())
    np.save(tmp_path / "b.npy", (porous() > 1000).astype(np.uint8))
    assert same_file(tmp_path, "b.npy", ReadOptions(orientation="SLA"), PrepOptions(threshold=1)).meta[
        "normals_from"] == "the binary mask"


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_otsu_of_float_values_gives_the_same_file(tmp_path, seed):
    np.save(tmp_path / "f.npy", porous(seed=seed).astype(np.float32) * np.float32(0.37))
    same_file(tmp_path, "f.npy", ReadOptions(), PrepOptions())


def test_a_stack_that_changed_is_read_anew(tmp_path):
    np.save(tmp_path / "v.npy", porous())
    encode_stack(tmp_path / "v.npy", tmp_path / "a.vxs", ReadOptions(), PrepOptions(threshold=1000))
    np.save(tmp_path / "v.npy", porous((20, 30, 40)))
    assert encode_stack(tmp_path / "v.npy", tmp_path / "b.vxs", ReadOptions(),
                        PrepOptions(threshold=1000))["shape"] == (20, 30, 40)


def test_a_crop_of_too_few_axes_is_refused_as_in_memory(tmp_path):
    np.save(tmp_path / "v.npy", porous())
    with pytest.raises(InputError) as error:
        encode_stack(tmp_path / "v.npy", tmp_path / "o.vxs", ReadOptions(),
                     PrepOptions(threshold=1000, crop=(slice(1, 5),)))
    assert error.value.parameter == "crop"


def test_parts_on_worker_processes_give_the_same_file(tmp_path):
    np.save(tmp_path / "v.npy", porous())
    same_file(tmp_path, "v.npy", ReadOptions(spacing=(1, 1, 1.2)), PrepOptions(threshold=1000), slabs=(2,), jobs=2)


def test_parts_on_a_dask_cluster_give_the_same_file(tmp_path):
    pytest.importorskip("distributed")
    np.save(tmp_path / "v.npy", porous())
    same_file(tmp_path, "v.npy", ReadOptions(), PrepOptions(threshold=1000), slabs=(4,), jobs=2, scheduler="local")


def test_what_needs_the_whole_volume_is_refused_and_nothing_is_left(tmp_path):
    np.save(tmp_path / "v.npy", porous())
    out = tmp_path / "out"
    out.mkdir()
    for prepare, parameter in [(PrepOptions(threshold=1000, min_object=5), "min_object"),
                               (PrepOptions(threshold=lambda v: 3), "threshold"),
                               (PrepOptions(threshold=5000), "threshold"),
                               (PrepOptions(threshold=1000, bin=20), "bin")]:
        with pytest.raises(InputError) as error:
            encode_stack(tmp_path / "v.npy", out / "o.vxs", ReadOptions(), prepare)
        assert error.value.parameter == parameter
        assert list(out.iterdir()) == []


@pytest.mark.parametrize("code", ["LPI", "PIR"])
def test_a_compressed_stack_out_of_stored_order_is_inflated_once(tmp_path, code):
    from formats import stored, write_nifti

    write_nifti(tmp_path / "v.nii.gz", *stored(porous(), code))
    same_file(tmp_path, "v.nii.gz", ReadOptions(), PrepOptions(threshold=1000), slabs=(2,))
    info = encode_stack(tmp_path / "v.nii.gz", tmp_path / "o.vxs", ReadOptions(), PrepOptions(threshold=1000),
                        slab_voxels=2 * SHAPE[1] * SHAPE[2])
    assert info["how"].endswith("(inflated once)")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["memory.vxs", "o.vxs", "streamed-2.vxs", "v.nii.gz"]


@pytest.mark.parametrize("streamed", [["--max-memory", "1K"], []])
def test_a_full_disk_is_one_line_and_leaves_nothing(tmp_path, streamed):
    import subprocess
    import sys

    np.save(tmp_path / "v.npy", porous((40, 64, 64)))
    out = tmp_path / "out"
    out.mkdir()
    # a file size limit stands for the full disk: writes past it fail as they would on one (EFBIG, not ENOSPC)
    script = ("import resource, signal, sys\nsignal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
              "resource.setrlimit(resource.RLIMIT_FSIZE, (20000, 20000))\nfrom voxrender.cli import main\n"
              "main(sys.argv[1:])")
    done = subprocess.run([sys.executable, "-c", script, "encode", str(tmp_path / "v.npy"), "--threshold", "1000",
                           *streamed, "-o", str(out / "v.vxs")], capture_output=True, text=True)
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith("error: no room to write") and len(done.stderr.splitlines()) == 1, done.stderr
    assert list(out.iterdir()) == []


def test_an_octree_build_over_the_memory_allowed_is_refused_before_it_starts(tmp_path):
    from click.testing import CliRunner

    from voxrender.cli import main

    np.save(tmp_path / "v.npy", porous())
    runner = CliRunner()
    for args in (["render", str(tmp_path / "v.npy"), "--method", "octree-ftb", "-o", str(tmp_path / "o.png")],
                 ["encode", str(tmp_path / "v.npy"), "--octree", "-o", str(tmp_path / "o.vxo")]):
        done = runner.invoke(main, [*args, "--threshold", "1000", "--max-memory", "10K"])
        assert done.exit_code == 2 and "--max-memory" in done.output and "binned by 2" in done.output, done.output
        assert done.output.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.npy"]
    done = runner.invoke(main, ["encode", str(tmp_path / "v.npy"), "--octree", "--threshold", "1000",   # streamed
                                "--max-memory", "1K", "-o", str(tmp_path / "o.vxo")])
    assert done.exit_code == 2 and sorted(p.name for p in tmp_path.iterdir()) == ["v.npy"], done.output
    done = runner.invoke(main, ["render", str(tmp_path / "v.npy"), "--method", "ftb", "--threshold", "1000",
                                "--max-memory", "10K", "-o", str(tmp_path / "o.png")])
    assert done.exit_code == 0, done.output


def test_binning_in_memory_is_the_preview_of_the_whole_and_labels_are_not_binned(tmp_path):
    from click.testing import CliRunner

    from voxrender.cli import main

    np.save(tmp_path / "v.npy", porous())
    runner = CliRunner()
    done = runner.invoke(main, ["encode", str(tmp_path / "v.npy"), "--threshold", "1000", "--bin", "2",
                                "-o", str(tmp_path / "b.vxs")])
    assert done.exit_code == 0 and "7x5x6 voxels" in done.output and "binned by 2" in done.output, done.output
    assert vxs.load(tmp_path / "b.vxs").spacing == (2.0, 2.0, 2.0)
    np.save(tmp_path / "l.npy", (porous() > 1000).astype(np.uint8))
    for args in (["render", str(tmp_path / "l.npy"), "--labels"], ["slices", str(tmp_path / "v.npy")]):
        done = runner.invoke(main, [*args, "--bin", "2", "-o", str(tmp_path / "x.png")])
        assert done.exit_code == 2 and "--bin" in done.output, done.output


def test_a_mask_is_told_by_every_7th_slice_as_in_memory(tmp_path):
    values = np.where(porous() > 1000, 100, 0).astype(np.int16)
    between = np.arange(SHAPE[0]) % 7 != 0
    values[between] = np.where(values[between] > 0, 50, 0)      # a third value, only off the sampled slices
    np.save(tmp_path / "m.npy", values)
    assert same_file(tmp_path, "m.npy", ReadOptions(), PrepOptions(threshold=30), slabs=(2, 5)).meta[
        "normals_from"] == "the binary mask"


def test_info_says_how_a_stack_would_be_streamed(tmp_path):
    from click.testing import CliRunner

    from voxrender.cli import main

    np.save(tmp_path / "v.npy", porous())
    runner = CliRunner()
    for code, words in (("LPS", "in stored order"), ("LPI", "from the far end"), ("PIR", "bounded memory, slower")):
        done = runner.invoke(main, ["info", str(tmp_path / "v.npy"), "--orientation", code, "--threshold", "1000"])
        assert done.exit_code == 0, done.output
        assert words in [line for line in done.output.splitlines() if line.startswith("if streamed:")][0]


def test_the_progress_bar_moves_as_each_slab_is_encoded(tmp_path, monkeypatch):
    from voxrender.object import stream

    np.save(tmp_path / "v.npy", porous())
    done, seen = [], []
    encode_part = stream.encode_part
    monkeypatch.setattr(stream, "encode_part", lambda *args: done.append(1) or encode_part(*args))

    def progress(counts, length, label):
        assert isinstance(counts, stream.ByteCounts) and sum(counts) == length == porous().nbytes
        for count in counts:
            seen.append(len(done))              # the parts encoded when the bar is told of the next one
            yield count

    encode_stack(tmp_path / "v.npy", tmp_path / "o.vxs", ReadOptions(), PrepOptions(threshold=1000),
                 progress=progress, slab_voxels=4 * SHAPE[1] * SHAPE[2])
    assert seen == [0, 1, 2, 3] and len(done) == 4


def test_half_floats_and_booleans_stream_as_they_are_read(tmp_path):
    np.save(tmp_path / "h.npy", porous().astype(np.float16))
    same_file(tmp_path, "h.npy", ReadOptions(spacing=(1, 1, 1.5)), PrepOptions(threshold=1000))
    np.save(tmp_path / "b.npy", porous() > 1000)
    same_file(tmp_path, "b.npy", ReadOptions(), PrepOptions(threshold=1))


@pytest.mark.parametrize(("dtype", "threshold"), [
    (np.int16, 1000.0),                         # every 7th slice of two values, for the binary check
    (np.float32, None),                         # Otsu's threshold of floats: two passes over every slice
])
def test_the_survey_before_the_first_slab_holds_no_more_than_a_slab(tmp_path, dtype, threshold):
    """What the survey keeps of each slab (every 7th value of every 7th row of every 7th slice) is a copy: kept
    as views, they held every slab they came from (5 GB of a 16 GiB stack; 31 % and 63 % of this one)."""
    import tracemalloc

    from voxrender.io import open_stack
    from voxrender.object.survey import survey

    values = (np.random.default_rng(1).normal(1000, 300, (560, 32, 32))).astype(dtype)
    if threshold is not None:                   # two values: the binary check reads every 7th slice
        values = np.where(values > 1000, 2000, 0).astype(dtype)
    np.save(tmp_path / "v.npy", values)
    stack = open_stack(tmp_path / "v.npy")
    region = tuple(slice(0, n) for n in stack.shape)
    prepare = PrepOptions() if threshold is None else PrepOptions(threshold=threshold)
    survey(stack, region, 1, prepare, slab_voxels=4 * 32 * 32)       # the modules it imports, imported
    tracemalloc.start()
    try:
        survey(stack, region, 1, prepare, slab_voxels=4 * 32 * 32)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < values.nbytes / 10, (peak, values.nbytes)


def test_a_streamed_stack_takes_a_worker_for_each_core_that_memory_holds(tmp_path, monkeypatch):
    """By default a streamed encode shares its slabs out over the machine's cores, as many as max_memory holds;
    an input read whole is encoded in this process; --jobs decides when given."""
    from voxrender.object import stream

    np.save(tmp_path / "v.npy", porous())
    monkeypatch.setattr(stream.os, "cpu_count", lambda: 4)
    monkeypatch.setattr(stream, "SLAB_VOXELS", 10)            # a worker's share: WORKER_SLABS * 2 * 10 bytes
    taken = []
    monkeypatch.setattr(stream, "_run", lambda plan, parts, folder, jobs, *rest: taken.append(jobs) or
                        [stream.encode_part(plan, *part, str(folder)) for part in parts])
    share = stream.WORKER_SLABS * 2 * 10
    for max_memory, jobs, expected in [(10 * share, None, 4), (3 * share, None, 3), (3 * share, 2, 2)]:
        stream.encode_file(tmp_path / "v.npy", tmp_path / "o.vxs", ReadOptions(), PrepOptions(threshold=1000),
                           jobs=jobs, max_memory=max_memory)
        assert taken.pop() == expected
    stream.encode_file(tmp_path / "v.npy", tmp_path / "o.vxs", ReadOptions(), PrepOptions(threshold=1000),
                       max_memory=1 << 30)
    assert taken == []                                          # read whole: not streamed


def test_the_survey_of_integers_stops_at_a_third_value(tmp_path):
    """With a threshold given, integers are surveyed only for whether they hold two values: once a third is met
    the rest of the stack is not read; a two-valued stack is read to its end (every 7th slice)."""
    from voxrender.io import open_stack
    from voxrender.object.survey import survey

    values = np.zeros((560, 32, 32), np.int16)
    values[:, :16] = 2000
    values[399, 7, 14] = 1000                          # a third value, where the survey samples (every 7th)
    for name, data, last in [("grey", values, 399), ("two", np.where(values == 1000, 0, values), 553)]:
        np.save(tmp_path / f"{name}.npy", data)
        stack = open_stack(tmp_path / f"{name}.npy")
        read, numbers = [], stack.read_numbers
        stack.read_numbers = lambda wanted, read=read, numbers=numbers: read.extend(wanted) or numbers(wanted)
        found = survey(stack, tuple(slice(0, n) for n in stack.shape), 1, PrepOptions(threshold=1000),
                        slab_voxels=4 * 32 * 32)
        assert found["binary"] == (name == "two")
        assert last <= max(read) < last + 4 * 7 and read == sorted(read), (name, max(read))


@pytest.mark.parametrize("kernel_copy", ["refused", "partial"])
def test_the_parts_are_joined_the_same_where_the_kernel_cannot_copy_them(tmp_path, monkeypatch, kernel_copy):
    """The parts are copied into the .vxs within the kernel (copy_file_range); where it refuses (another file
    system, not Linux) or stops short, the rest goes through a buffer, and the file is the same."""
    import os

    np.save(tmp_path / "v.npy", porous())
    prepare = PrepOptions(threshold=1000)
    encode_stack(tmp_path / "v.npy", tmp_path / "kernel.vxs", ReadOptions(), prepare, slab_voxels=3 * 11 * 15)
    copy = os.copy_file_range

    def limited(source, out, count, *offsets):
        if kernel_copy == "refused":
            raise OSError(18, "Invalid cross-device link")
        return copy(source, out, min(count, 7), *offsets) if offsets[0] == 0 else 0

    monkeypatch.setattr(os, "copy_file_range", limited)
    encode_stack(tmp_path / "v.npy", tmp_path / "buffered.vxs", ReadOptions(), prepare, slab_voxels=3 * 11 * 15)
    assert (tmp_path / "buffered.vxs").read_bytes() == (tmp_path / "kernel.vxs").read_bytes()


def test_encode_with_levels_streams_them_once_on_workers_too(tmp_path, monkeypatch):
    """encode_file of a streamed stack with levels writes the file once, its levels made as the slabs pass (no
    hidden first file to read again), on worker processes as in this one: the in-memory encode's file."""
    from voxrender.object import stream

    np.save(tmp_path / "v.npy", porous())
    prepare = PrepOptions(threshold=1000)
    memory, _ = stream.encode_file(tmp_path / "v.npy", tmp_path / "memory.vxs", ReadOptions(), prepare, levels=True,
                                   max_memory=1 << 30)
    asked, real = [], stream.encode_stack
    monkeypatch.setattr(stream, "encode_stack", lambda *args, **kw: asked.append(kw["levels"]) or real(*args, **kw))
    for jobs in (1, 2):
        streamed, how = stream.encode_file(tmp_path / "v.npy", tmp_path / f"streamed-{jobs}.vxs", ReadOptions(),
                                           prepare, levels=True, jobs=jobs, max_memory=1000)
        assert how and asked.pop() is True and len(streamed.segments.levels) == 3
        assert (tmp_path / f"streamed-{jobs}.vxs").read_bytes() == (tmp_path / "memory.vxs").read_bytes()
    assert len(memory.segments.levels) == 3 and not list(tmp_path.glob(".*"))


def test_only_the_encodes_own_workers_keep_the_memory_their_slabs_free(tmp_path, monkeypatch):
    """Worker processes of the encode's own pool keep freed memory for their next slab; a Dask cluster's workers,
    which go on to serve other work, are not changed."""
    from voxrender._shared import executors
    from voxrender.object import stream

    np.save(tmp_path / "v.npy", porous())
    kept = []

    class Recording(executors._Inline):
        def submit(self, fn, *args):
            kept.append(args[-1])
            return super().submit(fn, *args)

    monkeypatch.setattr(executors, "executor", lambda jobs, scheduler: Recording())
    monkeypatch.setattr(stream, "keep_freed_memory", lambda: None)          # this test's own process is left alone
    for scheduler, expected in [(None, True), ("tcp://cluster:8786", False)]:
        encode_stack(tmp_path / "v.npy", tmp_path / "o.vxs", ReadOptions(), PrepOptions(threshold=1000), jobs=2,
                     scheduler=scheduler, slab_voxels=4 * SHAPE[1] * SHAPE[2])
        assert kept and set(kept) == {expected}
        kept.clear()
