"""The big-stack section of ``make benchmark`` (issue 24): encoding a 2048^3 uint16 slice stack (16 GiB) from disk.

    python -m benchmarks.big_stack [--side N] [--repeat 1] [--out benchmark-results]

:func:`write_stack` writes, once, into a cache folder it reuses (``$VOXRENDER_BENCH_CACHE`` or
``~/.cache/voxrender-bench``), a synthetic micro-CT of a piece of bone: a cylindrical cortex around a porous
trabecular solid, grey values smooth across the surface as a scanner's partial volume makes them, and mild noise.
:func:`bench_big_stack` then measures, each in a fresh process after dropping the page cache (so that every one
reads from disk): a cold ``cat`` of the slice files, ``voxrender encode`` of the folder (plain, on a worker for
each core as by default, ``--bin 2``, and ``--jobs 1``: one process), ``voxrender render --method ftb --size 1024``
of the resulting ``.vxs``, then its levels of detail added (``encode --levels``) and pictures of 1024 and 512
pixels drawn from them; wall seconds, peak RSS (``/usr/bin/time -f %M``: of the largest process), the ratio of
each encode to ``cat`` (of the levels, the file's growth), and the issues' targets met or missed.

The stack's grey values (the constants below):

* bone (cortex and trabeculae) ``BONE`` = 3500, pores (marrow) and the background around the specimen ``PORE`` =
  1000, ``THRESHOLD`` = 2250 between them: the surface is where the grey value crosses it;
* across the surface the value follows a logistic of the signed distance to it, of scale ``EDGE`` = 0.4 voxel (10 %
  to 90 % over 1.8 voxels): the partial volume;
* Gaussian noise of standard deviation ``NOISE`` = 40.

The trabecular solid is a gyroid network (``G > level``) whose coordinates are warped by smooth random fields (so
that struts and pores vary in shape and thickness, not a crystal), its period ``side / 32`` voxels (at least 8):
the same specimen whatever the side, as a scanner at a coarser voxel sees it; the trabeculae thicken toward the
cortex. The cortex is a cylinder along z, its outer radius 0.46 side, half a period thick. About 25 % of the
volume is bone.
"""

from __future__ import annotations

import json
import math
import os
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import click
import numpy as np

PORE = 1000.0            # marrow in the pores, and the medium around the specimen
BONE = 3500.0            # cortical and trabecular bone
THRESHOLD = 2250.0       # halfway: the object to encode is value >= THRESHOLD
EDGE = 0.4               # voxels: scale of the logistic across the surface (partial volume)
NOISE = 40.0             # standard deviation of the scanner's noise
SEED = 2024
FULL_SIDE = 2048         # 2048^3 uint16: 16 GiB
SMALLEST_SIDE = 1626     # 1626^3 uint16: 8 GiB, the smallest stack the section accepts
OUTPUT_ROOM = 0.5        # disk kept for the outputs (a .vxs is about 1/4 of the stack at 2048), a fraction of the stack
MARKER = "stack.json"    # written last: the stack beside it is complete
STACK_VERSION = 1        # bump when the generator changes, so that a cached stack is remade

RSS_TARGET_MB = 2000.0   # 2 GB, encode and ftb
ENCODE_TARGET = 3.0      # encode seconds <= 3 x cold cat (moonshot 1.5 x)
ENCODE_MOONSHOT = 1.5
FTB_TARGET_S = 5.0
LEVEL_TARGETS_S = {1024: 5.0, 512: 2.0}   # a picture from the .vxs's levels of detail: seconds, at its size
LEVEL_RSS_MB = 1000.0    # and in 1 GB
LEVEL_GROWTH = 0.15      # the levels make the file at most 15 % larger
DROP_CACHES = Path("/proc/sys/vm/drop_caches")
TIME = "/usr/bin/time"
CAT_METHOD = "find FOLDER -name '*.tif' -print0 | sort -z | xargs -0 cat > /dev/null (one cat process)"


def _no_progress(iterable, length=None, label=None):
    return iterable


def cache_root():
    """The folder the stacks and outputs are kept in: ``$VOXRENDER_BENCH_CACHE`` or ``~/.cache/voxrender-bench``."""
    return Path(os.environ.get("VOXRENDER_BENCH_CACHE") or Path.home() / ".cache" / "voxrender-bench")


def stack_bytes(side):
    """Bytes of the slices of a ``side``^3 uint16 stack (the TIFF headers aside)."""
    return 2 * side ** 3


def stack_parameters(side):
    """Everything the stack's grey values depend on: the marker holds them, and a stack is reused only if they match."""
    return {"version": STACK_VERSION, "side": side, "seed": SEED, "period": _period(side), "pore": PORE,
            "bone": BONE, "edge": EDGE, "noise": NOISE, "dtype": "uint16", "files": "slice_%04d.tif"}


def _period(side):
    return max(8.0, side / 32)


def slice_names(side):
    return [f"slice_{z:04d}.tif" for z in range(side)]


def is_complete(folder, side):
    """Whether ``folder`` holds a whole stack of ``side`` made with today's parameters (its marker says so)."""
    marker = Path(folder) / MARKER
    try:
        return json.loads(marker.read_text()) == stack_parameters(side)
    except (OSError, ValueError):
        return False


def write_stack(folder, side=FULL_SIDE, progress=_no_progress):
    """Write the synthetic micro-CT stack into ``folder`` as ``side`` uncompressed uint16 TIFF slices, once.

    A folder whose marker (``stack.json``) holds today's parameters is kept as it is; anything else there (a stack
    half written, or of other parameters) is removed and the stack written again, slice by slice, the marker last.

    Parameters
    ----------
    folder : path
        Where the slices go (``slice_0000.tif`` ...).
    side : int
        The stack is ``side`` slices of ``side`` x ``side``.
    progress : callable
        ``progress(iterable, length, label)`` wraps the loop over the slices (e.g. a progress bar).

    Returns
    -------
    bool
        True if the stack was written, False if the complete one there was kept.
    """
    import tifffile

    folder = Path(folder)
    if is_complete(folder, side):
        return False
    folder.mkdir(parents=True, exist_ok=True)
    (folder / MARKER).unlink(missing_ok=True)
    for stale in folder.glob("slice_*.tif"):
        stale.unlink()
    field = BoneField(side)
    for z, name in enumerate(progress(slice_names(side), side, f"writing the {side}^3 stack")):
        tifffile.imwrite(folder / name, field.slice(z), photometric="minisblack")
    marker = folder / (MARKER + ".part")
    marker.write_text(json.dumps(stack_parameters(side), indent=1))
    marker.replace(folder / MARKER)
    return True


class BoneField:
    """The grey values of the synthetic bone, a slice at a time (:meth:`slice`), from 1-D and 2-D arrays made once.

    The gyroid ``sin X cos Y + sin Y cos Z + sin Z cos X`` is taken at warped coordinates ``X = k (x + dx(y, z))``,
    ``Y = k (y + dy(x, z))``, ``Z = k (z + dz(x, y))``; ``sin X = sin kx cos k dx + cos kx sin k dx`` makes every
    term a product of arrays of fewer dimensions, so a slice costs a few passes over its pixels.
    """

    def __init__(self, side, seed=SEED):
        rng = np.random.default_rng(seed)
        self.side = side
        self.k = 2 * np.pi / _period(side)
        centre = (side - 1) / 2
        axis = np.arange(side, dtype=np.float64)
        self.axis = axis
        self.kx_sin = np.sin(self.k * axis).astype(np.float32)                     # sin k x (and k y)
        self.kx_cos = np.cos(self.k * axis).astype(np.float32)
        # three warps, each a few random plane waves of 2.5 periods with amplitude a quarter period
        self.waves = [self._waves(rng) for _ in range(3)]
        dz = self._warp(self.waves[2], axis[None, :], axis[:, None])                 # dz(x, y): [y, x]
        self.dz_sin, self.dz_cos = np.sin(self.k * dz).astype(np.float32), np.cos(self.k * dz).astype(np.float32)
        radius = np.hypot(axis[None, :] - centre, axis[:, None] - centre)           # distance to the axis, [y, x]
        thickness = max(3.0, _period(side) / 2)
        outer = 0.46 * side
        self.middle = outer - thickness / 2                                         # the cortex's mid-radius
        self.cortex = (thickness / 2 - np.abs(radius - self.middle)).astype(np.float32)
        self.inside = (self.middle - radius).astype(np.float32)                    # > 0 within the cortex's middle
        # gyroid level: 0.75 at the axis (thin struts) down to 0.25 at the cortex (thick ones)
        self.level = (0.75 - 0.5 * np.clip(radius / self.middle, 0, 1) ** 2).astype(np.float32)

    def _waves(self, rng, count=4):
        angles = rng.uniform(0, 2 * np.pi, count)
        phases = rng.uniform(0, 2 * np.pi, count)
        wavenumber = self.k / 2.5
        return np.cos(angles) * wavenumber, np.sin(angles) * wavenumber, phases

    def _warp(self, waves, u, v):
        """A smooth random displacement at (u, v), in voxels (a quarter period at most, about)."""
        a, b, phases = waves
        amplitude = (2 * np.pi / self.k) / 8                                        # an eighth of a period a wave
        return amplitude * sum(np.cos(a[j] * u + b[j] * v + phases[j]) for j in range(len(phases)))

    def slice(self, z):
        """Slice ``z`` as uint16 ``[y, x]``: bone ``BONE``, pores and background ``PORE``, smooth between, noisy."""
        axis, k = self.axis, self.k
        sin_k, cos_k = self.kx_sin, self.kx_cos
        dx = self._warp(self.waves[0], axis, z)                                     # dx(y, z), along y
        dy = self._warp(self.waves[1], axis, z)                                     # dy(x, z), along x
        sin_dx, cos_dx = np.sin(k * dx).astype(np.float32)[:, None], np.cos(k * dx).astype(np.float32)[:, None]
        sin_dy, cos_dy = np.sin(k * dy).astype(np.float32), np.cos(k * dy).astype(np.float32)
        sin_x = sin_k * cos_dx + cos_k * sin_dx                                     # [y, x]
        cos_x = cos_k * cos_dx - sin_k * sin_dx
        sin_y = sin_k[:, None] * cos_dy + cos_k[:, None] * sin_dy
        cos_y = cos_k[:, None] * cos_dy - sin_k[:, None] * sin_dy
        sin_z = np.float32(math.sin(k * z)) * self.dz_cos + np.float32(math.cos(k * z)) * self.dz_sin
        cos_z = np.float32(math.cos(k * z)) * self.dz_cos - np.float32(math.sin(k * z)) * self.dz_sin
        gyroid = sin_x * cos_y
        gyroid += sin_y * cos_z
        gyroid += sin_z * cos_x
        # signed distance, in voxels, about: the gyroid's gradient is about 1.3 k
        distance = (gyroid - self.level) / np.float32(1.3 * k)
        np.minimum(distance, self.inside, out=distance)
        np.maximum(distance, self.cortex, out=distance)
        grey = np.tanh(distance / np.float32(2 * EDGE))            # logistic(d / EDGE) = (1 + tanh(d / 2 EDGE)) / 2
        grey *= np.float32((BONE - PORE) / 2)
        grey += np.float32((BONE + PORE) / 2)
        grey += np.random.default_rng([SEED, z]).standard_normal(grey.shape, dtype=np.float32) * np.float32(NOISE)
        return np.clip(np.rint(grey), 0, 65535).astype(np.uint16)


def choose_side(root=None, side=None):
    """The side of the stack the disk under ``root`` can hold, and why, or None and why not.

    ``side`` None asks for the full 2048, else the largest side whose stack and outputs fit, at least 1626 (8 GiB);
    a given ``side`` is taken if it fits. The stack already in the cache, and the previous outputs (remade), count
    as room.
    """
    root = Path(root or cache_root())
    existing = root
    while not existing.exists():
        existing = existing.parent
    free = shutil.disk_usage(existing).free

    def room(side):
        kept = _folder_bytes(root / f"stack-{side}") + _folder_bytes(root / f"outputs-{side}")
        return free + kept

    def needed(side):
        return stack_bytes(side) * (1 + OUTPUT_ROOM)

    wanted = side or FULL_SIDE
    if needed(wanted) <= room(wanted):
        return wanted, f"{wanted}^3 stack, {stack_bytes(wanted) / 2 ** 30:.1f} GiB"
    gib = f"{room(wanted) / 2 ** 30:.1f} GiB free under {existing}"
    if side is not None:
        return None, f"the {side}^3 stack and its outputs need {needed(side) / 2 ** 30:.1f} GiB: {gib}"
    fits = int((free / (2 * (1 + OUTPUT_ROOM))) ** (1 / 3))
    if fits < SMALLEST_SIDE:
        return None, (f"the disk cannot hold even an 8 GiB stack ({SMALLEST_SIDE}^3) and its outputs: {gib}; "
                      "the big-stack section is skipped")
    return fits, (f"the disk cannot hold the 16 GiB stack ({FULL_SIDE}^3) and its outputs ({gib}): the largest "
                  f"that fits, {fits}^3 ({stack_bytes(fits) / 2 ** 30:.1f} GiB), is used")


def _folder_bytes(folder):
    return sum(f.stat().st_size for f in Path(folder).glob("*") if f.is_file()) if Path(folder).is_dir() else 0


def drop_page_cache():
    """``sync; echo 3 > /proc/sys/vm/drop_caches``; returns None when done, else why not (not root, say)."""
    os.sync()
    try:
        DROP_CACHES.write_text("3\n")
    except OSError as exc:
        return f"page cache not dropped ({exc.strerror or exc})"
    return None


def measure(command, drop_caches=True):
    """Run ``command`` in a fresh process (after dropping the page cache) and measure it.

    Parameters
    ----------
    command : list of str, or str
        The program and its arguments, or a shell line (run by ``sh -c``).
    drop_caches : bool
        Drop the page cache first, so that the command reads its files from disk (needs root).

    Returns
    -------
    dict
        ``seconds`` (wall), ``peak_mb`` (peak RSS, ``/usr/bin/time -f %M``, in MB of 10^6 bytes; None without
        ``/usr/bin/time``), ``ok`` (exit status 0), ``error`` (the last line the command wrote to stderr when it
        failed), ``cache`` ("dropped", "not dropped (asked)" or why it could not be dropped).
    """
    argv = ["sh", "-c", command] if isinstance(command, str) else [str(a) for a in command]
    cache = "not dropped (asked)"
    if drop_caches:
        cache = drop_page_cache() or "dropped"
    timed = Path(TIME).is_file()
    with tempfile.NamedTemporaryFile("r", suffix=".rss") as report:
        if timed:
            argv = [TIME, "-f", "%M", "-o", report.name, *argv]
        started = time.perf_counter()
        done = subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, errors="replace")
        seconds = time.perf_counter() - started
        reported = report.read().split() if timed else []
    peak_kib = int(reported[-1]) if reported and reported[-1].isdigit() else None
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    return {"seconds": seconds, "peak_mb": None if peak_kib is None else peak_kib * 1024 / 1e6,
            "ok": done.returncode == 0, "error": None if done.returncode == 0 else
            (lines[-1].strip() if lines else f"exit status {done.returncode}"), "cache": cache}


def _cli(*args):
    return [sys.executable, "-m", "voxrender.cli", *map(str, args)]


def commands(folder, out):
    """The measured commands, name -> (argv or shell line, what the table shows)."""
    folder, out = Path(folder), Path(out)
    threshold = f"{THRESHOLD:g}"
    # by default a streamed encode takes a worker for each core; --jobs 1 is the encode in one process
    encodes = {"encode": [], "encode --bin 2": ["--bin", 2], "encode --jobs 1": ["--jobs", 1]}
    result = {"cat": (f"find {shlex.quote(str(folder))} -name '*.tif' -print0 | sort -z | xargs -0 cat > /dev/null",
                      "cat slice_*.tif > /dev/null")}
    for name, options in encodes.items():
        vxs = out / (name.replace(" --", "-").replace(" ", "") + ".vxs")
        shown = " ".join(["voxrender encode STACK -o", vxs.name, "--threshold", threshold, *map(str, options)])
        result[name] = (_cli("encode", folder, "-o", vxs, "--threshold", threshold, *options), shown)
    result["ftb 1024^2"] = (_cli("render", out / "encode.vxs", "--method", "ftb", "--size", 1024,
                                 "-o", out / "ftb.png"), "voxrender render encode.vxs --method ftb --size 1024")
    # levels of detail (issue 35): made as the stack's slabs pass, or added to the encoded file; then the pictures
    # drawn from the level that suits them
    result["encode STACK --levels"] = (
        _cli("encode", folder, "-o", out / "encode-levels.vxs", "--threshold", threshold, "--levels"),
        f"voxrender encode STACK -o encode-levels.vxs --threshold {threshold} --levels")
    result["encode --levels"] = (_cli("encode", out / "encode.vxs", "--levels", "-o", out / "levels.vxs"),
                                 "voxrender encode encode.vxs --levels -o levels.vxs")
    for size in LEVEL_TARGETS_S:
        result[f"ftb {size}^2, levels"] = (
            _cli("render", out / "levels.vxs", "--method", "ftb", "--size", size, "-o", out / f"levels-{size}.png"),
            f"voxrender render levels.vxs --method ftb --size {size}")
    return result


def bench_big_stack(side=None, repeat=1, drop_caches=True, progress=_no_progress):
    """The big-stack section: write (once) the stack, then time ``cat``, the encodes and ``ftb`` from disk.

    Parameters
    ----------
    side : int, optional
        The stack's side; None: 2048, or the largest the disk holds (at least 1626).
    repeat : int
        Runs of each command (each after dropping the page cache): median seconds, largest peak.
    drop_caches : bool
        Drop the page cache before each command (needs root; tests pass False).
    progress : callable
        Wraps the loop writing the slices (see :func:`write_stack`).

    Returns
    -------
    dict
        ``side``, ``stack_gib``, ``disk`` (what the disk allowed), ``cat_method``, ``threshold``, ``rows`` (one per
        command: ``name``, ``command``, ``seconds``, ``peak_mb``, ``ok``, ``error``, ``cache``, ``ratio_to_cat``
        for the encodes, and ``targets``: name -> met), ``write_s`` (None when the cached stack was kept); or
        ``skipped`` (why) and no rows.
    """
    root = cache_root()
    chosen, disk = choose_side(root, side)
    if chosen is None:
        return {"side": side, "skipped": disk, "disk": disk, "rows": []}
    folder, out = root / f"stack-{chosen}", root / f"outputs-{chosen}"
    started = time.perf_counter()
    written = write_stack(folder, chosen, progress)
    write_s = time.perf_counter() - started if written else None
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    runs = {name: [] for name in commands(folder, out)}
    for _ in range(repeat):
        for name, (command, _shown) in commands(folder, out).items():
            runs[name].append(measure(command, drop_caches))
            for spare in out.glob("encode-*.vxs"):      # only encode.vxs is rendered: keep the disk for the stack
                spare.unlink()
    rows = [_row(name, shown, runs[name]) for name, (_command, shown) in commands(folder, out).items()]
    sizes = [(out / name).stat().st_size if (out / name).is_file() else None for name in ("encode.vxs", "levels.vxs")]
    for row in rows:
        if row["name"] == "encode --levels" and None not in sizes:
            row["growth"] = sizes[1] / sizes[0]
    cat = rows[0]["seconds"]
    for row in rows:
        row["targets"] = _targets(row, cat)
    return {"side": chosen, "stack_gib": stack_bytes(chosen) / 2 ** 30, "disk": disk, "cat_method": CAT_METHOD,
            "threshold": THRESHOLD, "write_s": write_s, "folder": str(folder), "repeat": repeat, "rows": rows}


def _row(name, shown, runs):
    peaks = [run["peak_mb"] for run in runs if run["peak_mb"] is not None]
    failed = [run for run in runs if not run["ok"]]
    caches = sorted({run["cache"] for run in runs})
    return {"name": name, "command": shown, "seconds": statistics.median(run["seconds"] for run in runs),
            "peak_mb": max(peaks) if peaks else None, "ok": not failed,
            "error": failed[-1]["error"] if failed else None, "cache": "; ".join(caches)}


def _targets(row, cat_seconds):
    """The issue's targets for a row: name -> met (None for a failed command)."""
    if not row["name"].startswith(("encode", "ftb")):
        return {}
    small = row["peak_mb"] is not None and row["peak_mb"] <= RSS_TARGET_MB
    rss = f"RSS <= {RSS_TARGET_MB / 1000:g} GB"
    if row["name"] == "encode STACK --levels":        # the encode's targets are the plain encode's
        row["ratio_to_cat"] = row["seconds"] / cat_seconds if cat_seconds else None
        return {rss: (small if row["ok"] else None)}
    if row["name"] == "encode --levels":
        growth = row.get("growth")
        return {f"file <= {1 + LEVEL_GROWTH:g} x": (growth is not None and growth <= 1 + LEVEL_GROWTH)
                if row["ok"] else None}
    if row["name"].endswith("levels"):
        target = LEVEL_TARGETS_S[int(row["name"].split()[1].split("^")[0])]
        light = row["peak_mb"] is not None and row["peak_mb"] <= LEVEL_RSS_MB
        return {goal: (met if row["ok"] else None) for goal, met in
                {f"<= {target:g} s": row["seconds"] <= target, f"RSS <= {LEVEL_RSS_MB / 1000:g} GB": light}.items()}
    if row["name"].startswith("encode"):
        ratio = row["ratio_to_cat"] = row["seconds"] / cat_seconds if cat_seconds else None
        goals = {rss: small, f"<= {ENCODE_TARGET:g} x cat": ratio is not None and ratio <= ENCODE_TARGET,
                 f"<= {ENCODE_MOONSHOT:g} x cat (moonshot)": ratio is not None and ratio <= ENCODE_MOONSHOT}
    else:
        goals = {f"<= {FTB_TARGET_S:g} s": row["seconds"] <= FTB_TARGET_S, rss: small}
    return {goal: (met if row["ok"] else None) for goal, met in goals.items()}


def markdown_lines(result):
    """The section's lines for ``results.md``: what was measured, and a table of the commands."""
    if result.get("skipped"):
        return ["", f"Big stack: {result['skipped']}."]
    side = result["side"]
    cached = ("kept from the cache" if result["write_s"] is None else f"written in {result['write_s']:.0f} s")
    lines = ["", f"Big stack: {side} x {side} x {side} uint16 TIFF slices ({result['stack_gib']:.1f} GiB, a synthetic "
             f"micro-CT of trabecular bone in a cortex, {cached}; {result['disk']}), encoded at "
             f"{result['threshold']:g}; each command a fresh process, page cache dropped before each, so that all "
             f"read from disk (wall seconds, peak RSS of /usr/bin/time, MB = 10^6 bytes" +
             (f", medians of {result['repeat']}" if result["repeat"] > 1 else "") +
             f"). cat: {result['cat_method']}.",
             "", "| command | wall s | peak RSS MB | / cat | targets |", "|---|---|---|---|---|"]
    for row in result["rows"]:
        peak = "-" if row["peak_mb"] is None else f"{row['peak_mb']:,.0f}"
        ratio = f"{row['ratio_to_cat']:.2f}" if row.get("ratio_to_cat") is not None else \
            f"file {row['growth']:.3f} x" if row.get("growth") is not None else "-"
        if not row["ok"]:
            targets = f"failed: {row['error']}"
        else:
            targets = ", ".join(f"{goal} {'met' if met else 'missed'}" for goal, met in row["targets"].items()) or "-"
        lines.append(f"| `{row['command']}` | {row['seconds']:.1f} | {peak} | {ratio} | {targets} |")
    caches = sorted({row["cache"] for row in result["rows"]} - {"dropped"})
    if caches:
        lines += ["", f"Page cache: {'; '.join(caches)}: the commands may have read from memory, not disk."]
    return lines


def markdown(result):
    return "\n".join(markdown_lines(result)).strip()


def _bar(iterable, length=None, label=None):
    with click.progressbar(iterable, length=length, label=label, file=sys.stderr) as bar:
        yield from bar


@click.command()
@click.option("--side", type=click.IntRange(8, 4096), default=None,
              help="The stack's side (default: 2048, or the largest the disk holds, at least 1626).")
@click.option("--repeat", default=1, show_default=True, type=click.IntRange(1, 20))
@click.option("--drop-caches/--keep-caches", default=True, show_default=True,
              help="Drop the page cache before each command (needs root).")
@click.option("--out", default="benchmark-results", show_default=True, type=click.Path())
def main(side, repeat, drop_caches, out):
    """Write (once) the big synthetic stack and time encode and ftb on it from disk, beside a cold cat."""
    result = bench_big_stack(side, repeat, drop_caches, progress=_bar)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "big_stack.json").write_text(json.dumps(result, indent=2))
    (out / "big_stack.md").write_text(markdown(result) + "\n")
    click.echo(markdown(result))


if __name__ == "__main__":
    main()
