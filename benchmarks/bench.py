"""The benchmark behind ``make benchmark``: medians of repeated runs, ratios measured in the same run.

    python -m benchmarks.bench [--repeat 5] [--data ../shared/data] [--out benchmark-results]

It measures, on ``vhf_head`` at 300 HU (512 x 512 pictures at scale 1):

* reading the DICOM folder, and threshold + run-length encoding;
* every method of the registry at the dynamic-screen paper's Fig. 10 orientations and a few
  random ones, with the ratio of each method to ``ftb`` per view; then the same at -300 HU
  (the skin: the whole head is the object) at the paper's orientations;
* VTK's CPU ray caster (``vtkFixedPointVolumeRayCastMapper``) on the same volume and views,
  when ``vtk`` is installed (``pip install -e '.[peers]'``);
* the maximum intensity projection (``voxrender.pictures._project``) of the grey volume at the anterior view and
  two oblique ones, beside VTK's (the same caster, maximum-intensity blend), with their ratio;
* the whole command, DICOM folder to PNG, in a fresh process;
* the paper's section 6 analysis: render time against N for a sphere and for a
  convoluted object (a gyroid), with fitted exponents;
* discrete ray casting with 6-, 26- and adaptive rays on a one-voxel-thick shell and on
  vhf_head: steps, time, leaks and misses (the line-voxelization paper's trade-off);
* a 36-view turntable of vhf_head at 512 x 512 as one batch (1 and 2 workers) against 36
  separate ``voxrender render`` commands;
* the octree papers' tables: every octree method and the dynamic screen at Zhao and Davis's
  VPNs with their Table II and III statistics, on vhf_head and on their artificial object (a
  checkerboard with 32 white, 32 black and 9 grey octants); and the sorted linear octree
  against the z-buffer over a range of voxel counts (the linear-octree paper's Table 4);
* the big stack (``benchmarks/big_stack.py``): a 2048^3 uint16 TIFF stack written once into a cache, encoded
  (plain, ``--bin 2``, ``--jobs 1``) and rendered by ftb at 1024^2 from disk, beside a cold ``cat`` of the same
  files, with peak RSS (run as root, so that the page cache can be dropped before each); about 20 minutes of
  the run, left out by ``--no-big-stack``.

Results go to ``benchmark-results/results.md`` and ``results.json``.
"""

from __future__ import annotations

import json
import math
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import click
import numpy as np

from benchmarks import big_stack, compile_bytecode, median_seconds, studies, targets
from benchmarks.agreement import bench_agreement
from benchmarks.index_page import bench_index_browser, bench_index_page
from benchmarks.masks import bench_mask_folder
from benchmarks.studies import HERE
from voxrender import io
from voxrender._render import DEFAULT_METHOD, METHODS, octree_for, render
from voxrender.object import prep, segments, vxs
from voxrender.object.pipeline import Encoded
from voxrender.space.view import View

THRESHOLD = 300.0        # bone: a thin, convoluted object (the issue's case)
SKIN_THRESHOLD = -300.0  # skin: the whole head, a solid, nearly convex object (the paper's kind of case)
PAPER_VIEWS = [(-45.0, 15.0), (60.0, 120.0), (30.0, 10.0)]  # Fig. 10 (alpha, beta)
RANDOM_VIEWS = [tuple(float(round(a, 1)) for a in pair)
                for pair in np.random.default_rng(2026).uniform(-180, 180, size=(3, 2))]
SCALING_SIZES = (64, 96, 128, 192, 256)
# Discrete ray casting steps every ray voxel by voxel (seconds per picture, not tenths): it has its own
# section, at 256 x 256, instead of the 512 x 512 view table and the scaling runs.
OWN_SECTION = {"raycast"}


def timed_methods():
    return [m for m in METHODS if m not in OWN_SECTION]


def rendered(obj, view, method, **options):
    """``render`` of an :class:`Encoded` object; octree methods get the octree kept with it (built once, as
    the papers start from the octree).  A view without a scale fits the whole volume (as the papers' tables do)."""
    return render(obj.segments, view, method, fit="volume", tree=octree_for(method, obj), **options)


def bench_read(path, volume, repeat):
    """Seconds to read the same volume as the DICOM folder, as .nii.gz and as a gzip-encoded .nrrd."""
    from voxrender.outputs import output

    with tempfile.TemporaryDirectory() as folder:
        nifti = output.write_nifti(Path(folder) / "head.nii.gz", volume.values, volume.spacing)
        nrrd_file = output.write_nrrd(Path(folder) / "head.nrrd", volume.values, volume.spacing)
        seconds = {name: median_seconds(lambda: io.read_volume(source), repeat)[0]
                   for name, source in (("DICOM folder", path), (".nii.gz", nifti), (".nrrd (gzip)", nrrd_file))}
        sizes = {".nii.gz": nifti.stat().st_size, ".nrrd (gzip)": nrrd_file.stat().st_size,
                 "DICOM folder": sum(f.stat().st_size for f in Path(path).iterdir())}
    return {name: {"seconds": seconds[name], "megabytes": sizes[name] / 1e6} for name in seconds}


def bench_encode(volume, repeat):
    seconds, encoded = median_seconds(lambda: segments.encode(prep.binarize(volume, THRESHOLD)[0]), repeat)
    return {"threshold_and_encode_s": seconds, "voxels": encoded.voxel_count, "segments": encoded.segment_count,
            "grid_xyz": list(encoded.shape[::-1])}, Encoded(encoded)


def bench_views(encoded, repeat, size=512, scale=1.0, peer=None, views=PAPER_VIEWS + RANDOM_VIEWS):
    """Median seconds of every method (and the peer) at every view; same run, same volume."""
    rows = []
    for alpha, beta in views:
        view = View(alpha, beta, 0.0, (size, size), scale)
        row = {"alpha": alpha, "beta": beta, "seconds": {}, "stats": {}}
        for method in timed_methods():
            options = {"count_writes": False} if method == "zbuffer" else {}  # time its work, not our counting
            seconds, image = median_seconds(lambda: rendered(encoded, view, method, **options), repeat)
            row["seconds"][method] = seconds
            row["stats"][method] = image.stats
        if peer is not None:
            row["seconds"]["vtk"] = peer.time(view, repeat)
        rows.append(row)
    return rows


class VtkPeer:
    """VTK's CPU fixed-point ray caster on the same volume: step opacity at the threshold, nearest
    interpolation, parallel projection, the same picture size and view direction."""

    def __init__(self, values, threshold):
        vtk = self._start(np.ascontiguousarray(values, dtype=np.float32))
        opacity = vtk.vtkPiecewiseFunction()
        low = float(np.min(values)) - 1
        opacity.AddPoint(low, 0.0)
        opacity.AddPoint(threshold - 1e-3, 0.0)
        opacity.AddPoint(threshold, 1.0)
        opacity.AddPoint(max(float(np.max(values)), threshold) + 1, 1.0)
        prop = vtk.vtkVolumeProperty()
        prop.SetScalarOpacity(opacity)
        prop.SetInterpolationTypeToNearest()
        prop.ShadeOn()
        self._finish(prop)

    def _start(self, values):
        """The volume as VTK image data and the mapper (sample distance 1 voxel, not adjusted); returns ``vtk``."""
        import vtk
        from vtk.util import numpy_support

        vtk.vtkObject.GlobalWarningDisplayOff()
        self.vtk = vtk
        nz, ny, nx = values.shape
        image = vtk.vtkImageData()
        image.SetDimensions(nx, ny, nz)
        image.GetPointData().SetScalars(numpy_support.numpy_to_vtk(values.ravel(), deep=True))
        self.mapper = vtk.vtkFixedPointVolumeRayCastMapper()
        self.mapper.SetInputData(image)
        self.mapper.AutoAdjustSampleDistancesOff()
        self.mapper.SetSampleDistance(1.0)
        self.centre = (np.array([nx, ny, nz]) - 1) / 2
        return vtk

    def _finish(self, prop):
        """The scene: the volume with ``prop`` in an off-screen window."""
        vtk = self.vtk
        volume = vtk.vtkVolume()
        volume.SetMapper(self.mapper)
        volume.SetProperty(prop)
        self.renderer = vtk.vtkRenderer()
        self.renderer.AddVolume(volume)
        self.window = vtk.vtkRenderWindow()
        self.window.SetOffScreenRendering(1)
        self.window.AddRenderer(self.renderer)

    def aim(self, view):
        """The camera of ``view``: parallel projection, the same picture size, direction, up and scale."""
        height, width = view.size
        self.window.SetSize(width, height)
        camera = self.renderer.GetActiveCamera()
        camera.ParallelProjectionOn()
        r = view.matrix
        camera.SetFocalPoint(*self.centre)
        camera.SetPosition(*(self.centre - 2000 * r[2]))  # the viewer looks along +Z' = r[2]
        camera.SetViewUp(*(-r[1]))                          # picture up is -Y'
        camera.SetParallelScale(height / (2 * view.scale))
        self.renderer.ResetCameraClippingRange()
        return camera

    def time(self, view, repeat):
        camera = self.aim(view)
        self.window.Render()  # warm-up

        def once():
            camera.Modified()
            self.window.Render()

        return median_seconds(once, repeat)[0]

    def picture(self, view):
        """The rendered picture of ``view``, (H, W, 3) uint8, top row first (to look at beside ours)."""
        from vtk.util import numpy_support

        self.aim(view)
        self.window.Render()
        grab = self.vtk.vtkWindowToImageFilter()
        grab.SetInput(self.window)
        grab.ReadFrontBufferOff()
        grab.Update()
        height, width = view.size
        rgb = numpy_support.vtk_to_numpy(grab.GetOutput().GetPointData().GetScalars()).reshape(height, width, -1)
        return rgb[::-1, :, :3]


class VtkMipPeer(VtkPeer):
    """VTK's maximum intensity projection: the same caster and camera with ``SetBlendModeToMaximumIntensity``, on
    the volume's own values, opacity 1 and a grey ramp over all of them (every sample counts), nearest
    interpolation, no shading."""

    def __init__(self, values):
        vtk = self._start(np.ascontiguousarray(values))
        self.mapper.SetBlendModeToMaximumIntensity()
        low, high = float(np.min(values)), float(np.max(values))
        high = max(high, low + 1)
        opacity = vtk.vtkPiecewiseFunction()
        opacity.AddPoint(low, 1.0)
        opacity.AddPoint(high, 1.0)
        grey = vtk.vtkColorTransferFunction()
        grey.AddRGBPoint(low, 0.0, 0.0, 0.0)
        grey.AddRGBPoint(high, 1.0, 1.0, 1.0)
        prop = vtk.vtkVolumeProperty()
        prop.SetScalarOpacity(opacity)
        prop.SetColor(grey)
        prop.SetInterpolationTypeToNearest()
        prop.ShadeOff()
        self._finish(prop)


# the axis, and the six views of the render table (issue 35: the MIP at most VTK's at all six)
PROJECTION_VIEWS = {"anterior": (90.0, 0.0, 0.0),
                    **{f"({alpha:g}, {beta:g})": (alpha, beta, 0.0) for alpha, beta in PAPER_VIEWS + RANDOM_VIEWS}}


def bench_projection(values, repeat, peer=None, size=512, scale=1.0, views=PROJECTION_VIEWS):
    """Median seconds of ``project`` (MIP) at each view, beside VTK's MIP of the same view (``peer``, a
    :class:`VtkMipPeer`), and their ratio; same run, same volume."""
    from voxrender.pictures._project import project

    rows = []
    for name, angles in views.items():
        view = View(*angles, (size, size), scale)
        project(values, view, "mip")                        # warm-up, as VTK gets one
        row = {"view": name, "angles": list(angles), "seconds": median_seconds(lambda: project(values, view, "mip"),
                                                                                repeat)[0]}
        if peer is not None:
            row["vtk_s"] = peer.time(view, repeat)
            row["ratio"] = row["seconds"] / row["vtk_s"]
        rows.append(row)
    return {"size": size, "scale": scale, "grid_xyz": list(values.shape[::-1]), "rows": rows}


def _projection_table(result):
    vtk = any("vtk_s" in row for row in result["rows"])
    grid = " x ".join(map(str, result["grid_xyz"]))
    lines = [f"Maximum intensity projection of the {grid} volume, {result['size']} x {result['size']} at scale "
             f"{result['scale']:g} (`voxrender.project`, exact under cube semantics; median seconds" +
             ("; VTK's MIP of the same view: vtkFixedPointVolumeRayCastMapper, maximum-intensity blend, nearest "
              "interpolation, sample distance 1 voxel, its own threads):" if vtk else "):"), "",
             "| view | voxrender s |" + (" vtk s | voxrender/vtk |" if vtk else ""),
             "|---|---|" + ("---|---|" if vtk else "")]
    for row in result["rows"]:
        lines.append(f"| {row['view']} | {row['seconds']:.3f} |" +
                     (f" {row['vtk_s']:.3f} | {row['ratio']:.2f} |" if "vtk_s" in row else ""))
    return lines


def bench_stages(path, repeat, size=512, peer=None):
    """The picture step by stage on vhf_head at 300 HU (ftb, 512 x 512, scale 1, alpha 30, beta 10), in this
    process: loading the encoded object (a memory-mapped ``.vxs``), render, grey-level shading (normals at the hit
    points and lighting), the same with ambient occlusion, the paper's depth-gradient shading, and the PNG write;
    the whole picture beside VTK's render of the same view (``peer``); medians of ``repeat``."""
    from voxrender.object.pipeline import PrepOptions, load_segments
    from voxrender.outputs import output
    from voxrender.pictures._picture import RenderOptions, picture

    loaded = load_segments(path, prepare=PrepOptions(threshold=THRESHOLD))
    result = {}
    with tempfile.TemporaryDirectory() as folder:
        stored = Path(folder) / "object.vxs"
        loaded.save(stored)
        result["load_s"] = median_seconds(lambda: load_segments(stored), repeat)[0]
        for name, options in (("gradient", RenderOptions(size=(size, size), scale=1.0)),
                              ("gradient + ao", RenderOptions(size=(size, size), scale=1.0, ao=True)),
                              ("depth-gradient", RenderOptions(size=(size, size), scale=1.0,
                                                               shading="depth-gradient"))):
            view = options.view(30.0, 10.0)
            seconds = [picture(loaded.segments, view, options).seconds for _ in range(repeat)]
            result[name] = {stage: statistics.median(s[stage] for s in seconds) for stage in ("render", "shade")}
        rgb = picture(loaded.segments, view, RenderOptions(size=(size, size), scale=1.0)).rgb
        result["write_s"] = median_seconds(lambda: output.write_png(Path(folder) / "p.png", rgb), repeat)[0]
        result["fresh"] = _fresh_stages(stored, max(repeat, 5), size)
    if peer is not None:
        result["vtk_s"] = peer.time(View(30.0, 10.0, 0.0, (size, size), 1.0), repeat)
    result["normals_at_encode_s"] = loaded.seconds["prepare"]
    return result


def _fresh_stages(stored, repeat, size):
    """``voxrender render object.vxs`` (gradient shading) in a fresh process each time, as a user's script runs
    it: the medians of the stage seconds it reports, and of its wall time, imports and start-up included."""
    stages, walls = [], []
    with tempfile.TemporaryDirectory() as folder:
        report = Path(folder) / "stats.json"
        for _ in range(repeat):
            started = time.perf_counter()
            subprocess.run(_cli("render", stored, "--alpha", 30, "--beta", 10, "--scale", 1, "--size", size,
                                "--stats-json", report, "-o", Path(folder) / "p.png"), check=True, capture_output=True)
            walls.append(time.perf_counter() - started)
            stages.append(json.loads(report.read_text())["seconds"])
    result = {stage: statistics.median(s[stage] for s in stages) for stage in ("load", "render", "shade", "write")}
    result["shade_and_write"] = statistics.median(s["shade"] + s["write"] for s in stages)
    result["wall"] = statistics.median(walls)
    return result


def bench_pipeline(path, repeat):
    """The whole command, DICOM folder to PNG, as a user runs it (a fresh process each time)."""
    with tempfile.TemporaryDirectory() as folder:
        command = [sys.executable, "-m", "voxrender.cli", "render", str(path), "--threshold", str(THRESHOLD),
                   "--alpha", "30", "--beta", "10", "--size", "512", "--scale", "1", "-o", f"{folder}/out.png"]
        seconds, _ = median_seconds(lambda: subprocess.run(command, check=True, capture_output=True), repeat)
    return {"command": f"voxrender render vhf_head --threshold {THRESHOLD:g} --alpha 30 --beta 10 --size 512 "
                       "--scale 1", "method": DEFAULT_METHOD, "seconds": seconds}


def phantom(kind, n):
    """A ball (convex: C = 1) or a gyroid inside a ball (convoluted: C grows with the volume)."""
    z, y, x = (np.mgrid[:n, :n, :n] - (n - 1) / 2).astype(np.float32)
    ball = x * x + y * y + z * z <= (0.4 * n) ** 2
    if kind == "sphere":
        return ball
    k = 2 * np.pi / 12  # a period of 12 voxels, whatever N
    gyroid = np.sin(k * x) * np.cos(k * y) + np.sin(k * y) * np.cos(k * z) + np.sin(k * z) * np.cos(k * x)
    return ball & (gyroid > 0.4)


SCALING_METHODS = ("ftb", "btf")  # the dynamic-screen paper's analysis


def bench_scaling(repeat, sizes=SCALING_SIZES, methods=SCALING_METHODS):
    """Time against N (N^3 volume, N x N picture at scale 1, view (30, 10)) and the fitted exponents."""
    result = {}
    for kind in ("sphere", "gyroid"):
        rows = []
        for n in sizes:
            encoded = Encoded(segments.encode(phantom(kind, n)))
            view = View(30.0, 10.0, 0.0, (n, n), 1.0)
            row = {"n": n, "voxels": encoded.segments.voxel_count}
            for method in methods:
                row[method] = median_seconds(lambda: rendered(encoded, view, method), repeat)[0]
            rows.append(row)
        result[kind] = {"rows": rows, **fit_exponents(rows, methods)}
    return result


def fit_exponents(rows, methods):
    """The exponent of N in each method's time: a least-squares fit over all rows (``exponents``) and the
    slope between the two largest N, where fixed per-slice costs matter least (``exponents_largest``)."""
    sizes = [row["n"] for row in rows]
    exponents = {method: float(np.polyfit(np.log(sizes), np.log([r[method] for r in rows]), 1)[0])
                 for method in methods}
    last = {method: float(np.log(rows[-1][method] / rows[-2][method]) / np.log(sizes[-1] / sizes[-2]))
            for method in methods}
    return {"exponents": exponents, "exponents_largest": last}


def _views_table(rows, names):
    lines = ["| alpha | beta | " + " | ".join(names) + " | " +
             " | ".join(f"{m}/ftb" for m in names if m != "ftb") + " |",
             "|---|---|" + "---|" * (2 * len(names) - 1)]
    for row in rows:
        seconds = row["seconds"]
        lines.append(f"| {row['alpha']:g} | {row['beta']:g} | " +
                     " | ".join(f"{seconds[m]:.3f}" for m in names) + " | " +
                     " | ".join(f"{seconds[m] / seconds['ftb']:.2f}" for m in names if m != "ftb") + " |")
    return lines


def thin_shell(n=128, radius=50.0):
    """A sphere one voxel thick: 26-connected rays slip through it."""
    z, y, x = (np.mgrid[:n, :n, :n] - (n - 1) / 2).astype(np.float32)
    return np.abs(np.sqrt(x * x + y * y + z * z) - radius) <= 0.5


def bench_raycast(repeat, cases):
    """Steps, time, leaks and misses of 6-, 26- and adaptive rays (Cohen-Or and Kaufman's trade-off)."""
    from voxrender._render.raycast import render_raycast

    result = {}
    for name, (encoded, view) in cases.items():
        rows = {}
        for connectivity in ("6", "26", "adaptive"):
            seconds, _ = median_seconds(lambda: render_raycast(encoded, view, connectivity=connectivity,
                                                               compare=False), repeat)
            _, stats = render_raycast(encoded, view, connectivity=connectivity, compare=True)
            rows[connectivity] = {"seconds": seconds, "steps_26": stats["steps_26"], "steps_6": stats["steps_6"],
                                  "iterations": stats["iterations"], "rays_hit": stats["rays_hit"],
                                  **{k: stats.get(k, 0) for k in ("late_hits", "leaks", "misses")}}   # 6: the contract
        result[name] = {"view": [view.alpha, view.beta, view.gamma, list(view.size), view.scale],
                        "voxels": encoded.voxel_count, "rows": rows}
    return result


def bench_batch(path, views=36, size=512, separate=True):
    """A turntable of ``views`` pictures: one batch with 1 and 2 workers against separate render commands."""
    from voxrender.batch.run import run_batch
    from voxrender.batch.spec import Patterns, items_from, parse_views
    from voxrender.object.pipeline import PrepOptions, ReadOptions
    from voxrender.pictures._picture import RenderOptions

    result = {"views": views, "size": size}
    turn = parse_views(turntable_count=views)
    with tempfile.TemporaryDirectory() as folder:
        for jobs in (1, 2):
            items = items_from([str(path)], [], ReadOptions(), PrepOptions(threshold=THRESHOLD),
                               RenderOptions(size=(size, size)), turn, Patterns())
            started = time.perf_counter()
            rows = run_batch(items, f"{folder}/jobs{jobs}", jobs=jobs, cache_dir=f"{folder}/cache{jobs}")
            seconds = time.perf_counter() - started
            assert all(r["status"] == "ok" for r in rows)
            result[f"batch_{jobs}_s"] = seconds
            result[f"batch_{jobs}_images_per_s"] = views / seconds
        if separate:
            started = time.perf_counter()
            for k, view in enumerate(turn):
                subprocess.run([sys.executable, "-m", "voxrender.cli", "render", str(path), "--threshold",
                                str(THRESHOLD), "--alpha", str(view.alpha), "--beta", str(view.beta), "--gamma",
                                str(view.gamma), "--size", str(size), "-o", f"{folder}/single{k}.png"],
                               check=True, capture_output=True)
            result["separate_s"] = time.perf_counter() - started
            result["separate_images_per_s"] = views / result["separate_s"]
    return result


def bench_sorted_octree(repeat, sides=(16, 29, 32, 42)):
    """The linear-octree paper's Table 4: sorted linear octree against the back-face-culled z-buffer,
    solid cubes of ``side``^3 voxels (4 k to 74 k voxels, the paper's range), at its three VPNs."""
    from voxrender.space.view import angles_from_vpn

    rows = []
    for side in sides:
        encoded = Encoded(segments.encode(np.pad(np.ones((side, side, side), bool), 2)))
        encoded.octree()  # built once, as the paper starts from the linear octree
        row = {"voxels": side ** 3}
        for vpn in ((1, 0, 0), (1, 1, 0), (1, 1, 1)):
            view = View(*angles_from_vpn(vpn), (256, 256), None)
            for method, options in (("zbuffer", {"count_writes": False}), ("octree-sort", {})):
                row[f"{method} {vpn}"] = median_seconds(lambda: rendered(encoded, view, method, **options),
                                                        repeat)[0]
        rows.append(row)
    return rows


OCTREE_VPNS = [(1, -2, 1), (-1, -2, 1), (1, -1, 0), (0, -1, 0)]  # Zhao and Davis's Tables II and III
OCTREE_METHODS = ("octree-btf", "octree-ftb", "octree-sort", "zbuffer", "ftb")  # ftb: the dynamic screen


def checkerboard(n=7, blocks=4):
    """Zhao and Davis's artificial object: an octree of resolution ``n`` with 32 white, 32 black and 9 grey
    octants, here a ``blocks``^3 checkerboard of cubes."""
    side = 1 << n
    z, y, x = np.indices((side, side, side)) // (side // blocks)
    return (x + y + z) % 2 == 0


def bench_octree(objects, repeat, size=512):
    """Tables II and III: every octree method and the dynamic screen at the papers' VPNs, statistics of the
    traversals, and the one-off cost of the octree and its face adjacency.  ``objects``: name -> (segments,
    scale), ``scale`` None to fit the volume."""
    from voxrender.object import octree
    from voxrender.space.view import angles_from_vpn

    result, one_off = {}, {}
    for name, (encoded, scale) in objects.items():
        if id(encoded) not in one_off:        # timed on a fresh tree; the renders use the one kept with the object
            started = time.perf_counter()
            fresh = octree.build_from_segments(encoded.segments)
            built = time.perf_counter()
            _ = fresh.white_to_white, fresh.white_to_black, fresh.parent   # built on first use: time it here
            one_off[id(encoded)] = {"octree_s": built - started, "adjacency_s": time.perf_counter() - built}
            tree = encoded.octree()
            _ = tree.white_to_white, tree.white_to_black, tree.parent
        counts = encoded.octree().counts()
        rows = []
        for vpn in OCTREE_VPNS:
            view = View(*angles_from_vpn(vpn), (size, size), scale)
            row = {"vpn": list(vpn), "seconds": {}, "stats": {}}
            for method in OCTREE_METHODS:
                options = {"count_writes": False} if method == "zbuffer" else {}
                seconds, image = median_seconds(lambda: rendered(encoded, view, method, **options), repeat)
                row["seconds"][method] = seconds
                row["stats"][method] = image.stats
                row["scale"] = image.view.scale
            rows.append(row)
        result[name] = {**one_off[id(encoded)], "n": encoded.octree().n, "white": counts["white"],
                        "black": counts["black"], "grey": counts["grey"], "rows": rows}
    return result


def _octree_tables(octree_results):
    lines = ["", "Octree methods at Zhao and Davis's VPNs (512 x 512; median seconds, one run). "
             "Table II: black faces scan-converted, octants visited (and of them blocked) by colour, time in black "
             "octants, total time; Table III: scanlines and pixels accumulated. octree-sort and zbuffer break the "
             "black octants into voxels: their faces, voxels and fragments (pixel-cube hits) are in those columns:", ""]
    for name, data in octree_results.items():
        lines += [f"{name} (scale {data['rows'][0]['scale']:.2f}): octree n = {data['n']}, {data['white']:,} white, "
                  f"{data['black']:,} black, {data['grey']:,} grey octants; built in {data['octree_s']:.2f} s, face "
                  f"adjacency of its leaves {data['adjacency_s']:.2f} s (both once per object, kept with it)", "",
                  "| VPN | method | black faces | black visited (blocked) | white visited (blocked) | "
                  "grey visited (blocked) | scanlines | pixels | s in black | total s |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
        for row in data["rows"]:
            vpn = "(" + ", ".join(str(v) for v in row["vpn"]) + ")"
            for method in ("octree-btf", "octree-ftb"):
                st = row["stats"][method]
                blocked = {c: f" ({st[c + '_blocked']:,})" if c + "_blocked" in st else ""
                           for c in ("black", "white", "grey")}
                lines.append(f"| {vpn} | {method} | {st['black_faces']:,} | "
                             f"{st['black_visited']:,}{blocked['black']} | "
                             f"{st['white_visited']:,}{blocked['white']} | {st['grey_visited']:,}{blocked['grey']} | "
                             f"{st['scanlines_accumulated']:,} | {st['pixels_accumulated']:,} | "
                             f"{st['black_seconds']:.3f} | {row['seconds'][method]:.3f} |")
            for method in ("octree-sort", "zbuffer"):   # black octants broken into voxels; no W or G octants
                st = row["stats"][method]
                lines.append(f"| {vpn} | {method} | {st['faces']:,} | {st['voxels']:,} (voxels) | - | - | - | "
                             f"{st['fragments']:,} | {row['seconds'][method]:.3f} | {row['seconds'][method]:.3f} |")
        lines += ["", "| VPN | " + " | ".join(OCTREE_METHODS) + " | % reduction ftb over btf (octree) | "
                  "octree-btf/octree-ftb |", "|---|" + "---|" * (len(OCTREE_METHODS) + 2)]
        for row in data["rows"]:
            seconds = row["seconds"]
            vpn = "(" + ", ".join(str(v) for v in row["vpn"]) + ")"
            lines.append(f"| {vpn} | " + " | ".join(f"{seconds[m]:.3f}" for m in OCTREE_METHODS) +
                         f" | {100 * (1 - seconds['octree-ftb'] / seconds['octree-btf']):.0f} % | "
                         f"{seconds['octree-btf'] / seconds['octree-ftb']:.2f} |")
        lines.append("")
    return lines


def _index_browser_lines(b):
    """The index page in headless Chromium (``benchmarks/index_page.py``), against issue 36's targets."""
    if "skipped" in b:
        return [f"The index page in Chromium: skipped ({b['skipped']})", ""]
    real = b["batch"]
    return [f"The index page of {b['studies']:,} synthetic studies in headless Chromium (`python -m "
            "benchmarks.index_page`; medians of fresh openings):", "", "| measure | value | target |", "|---|---|---|",
            f"| rows built (the first screen) | {b['rows_s']:.2f} s | <= 1 s |",
            f"| load event | {b['load_s']:.2f} s | |",
            f"| pictures asked for at load | {b['pictures']:.0f} | < 100 |",
            f"| j pressed 200 times through Playwright | {b['j200_s']:.1f} s | <= 10 s |",
            f"| j, and a verdict, handled in the page | {b['j_ms']:.1f} ms, {b['verdict_ms']:.1f} ms | < 50 ms |",
            f"| showing the flagged | {b['flagged_s']:.2f} s | |",
            f"| a real batch of {real['studies']} studies with 6-frame turntables: load | {real['load_s']:.2f} s, "
            f"{real['pictures']:.0f} pictures, its first turntable {real['turns']} frames under the mouse | <= 1 s |",
            "", f"(The batch itself took {real['batch_s']:.0f} s; its page {real['bytes_per_study']:.0f} bytes a "
            "study.)", ""]


def markdown(results):
    methods = timed_methods()
    peers = ["vtk"] if results.get("vtk_version") else []
    lines = [f"voxrender benchmark, {results['when']}, {results['machine']}", "",
             f"vhf_head at {THRESHOLD:g} HU: grid {results['encode']['grid_xyz']} (x, y, z), "
             f"{results['encode']['voxels']:,} object voxels, {results['encode']['segments']:,} segments; "
             f"read DICOM {results['read_s']:.2f} s; threshold + encode "
             f"{results['encode']['threshold_and_encode_s']:.3f} s (medians of {results['repeat']})", "",
             "Render, 512 x 512 at scale 1 (median seconds; ratios to ftb in the same run):", ""]
    if results.get("read"):
        lines[2:2] = ["Reading vhf_head (median seconds):", "", "| stored as | MB | read s |", "|---|---|---|",
                      *(f"| {name} | {row['megabytes']:.1f} | {row['seconds']:.2f} |"
                        for name, row in results["read"].items()), ""]
    if results.get("mask_folder"):
        m = results["mask_folder"]
        grid = " x ".join(map(str, m["grid_xyz"]))
        lines[2:2] = [f"Reading {m['masks']} masks of a {grid} grid as a folder of `.nii.gz` ({m['folder_mb']:.0f} "
                      f"MB), as TotalSegmentator writes them: {m['mask_folder_s']:.1f} s; "
                      f"the same labels as one `.nii.gz` ({m['one_file_mb']:.0f} MB): {m['one_file_s']:.2f} s "
                      f"({m['ratio']:.0f}x; medians, same run)", ""]
    if results.get("index_page"):
        i = results["index_page"]
        lines[2:2] = [f"Writing the index page of {i['studies']:,} studies from their rows: {i['seconds']:.2f} s, "
                      f"{i['megabytes']:.1f} MB ({i['bytes_per_study']:.0f} bytes a study; median, same run)", ""]
    if results.get("index_browser"):
        lines[2:2] = _index_browser_lines(results["index_browser"])
    if results.get("agreement"):
        a = results["agreement"]
        if "skipped" in a:
            lines[2:2] = [f"Agreement with a reference: skipped ({a['skipped']})", ""]
        else:
            grid = " x ".join(map(str, a["grid_xyz"]))
            lines[2:2] = [f"Agreement with a reference on vhf_head's grid ({grid}; Dice, HD95, surface Dice at 2 mm; "
                          "medians, same run):", "", "| case | structures | voxrender s | surface-distance s | ratio | "
                          "largest difference |", "|---|---|---|---|---|---|",
                          *(f"| {name} | {c['structures']} | {c['voxrender_s']:.2f} | {c['surface_distance_s']:.2f} | "
                            f"{c['speedup']:.1f}x | {c['largest_difference']:.2g} |" for name, c in a["cases"].items()),
                          ""]
    lines += _views_table(results["views"], methods + peers)
    if results.get("stages"):
        stages = results["stages"]
        vtk = stages.get("vtk_s")
        lines += ["", "The picture step by stage (ftb, 512 x 512, scale 1, alpha 30, beta 10; median seconds; the "
                  "whole picture is load + render + shade + write" + (", beside VTK's render of the same view" if vtk
                                                                     else "") + "):", "",
                  "| shading | load | render | shade | write | picture |" + (" vtk | picture/vtk |" if vtk else ""),
                  "|---|---|---|---|---|---|" + ("---|---|" if vtk else "")]

        def stage_row(name, seconds):            # seconds: load, render, shade, write
            whole = sum(seconds)
            return f"| {name} | " + " | ".join(f"{s:.3f}" for s in seconds) + f" | {whole:.3f} |" + \
                (f" {vtk:.3f} | {whole / vtk:.2f} |" if vtk else "")

        for name in ("gradient", "gradient + ao", "depth-gradient"):
            lines.append(stage_row(name, (stages.get("load_s", 0.0), stages[name]["render"], stages[name]["shade"],
                                          stages["write_s"])))
        fresh = stages.get("fresh")
        if fresh:
            lines.append(stage_row("gradient, fresh process", [fresh[k] for k in ("load", "render", "shade", "write")]))
            lines += ["", f"In a fresh process (`voxrender render object.vxs`, medians of the stages it reports): "
                      f"shade + write {fresh['shade_and_write'] * 1000:.0f} ms; the command's wall time "
                      f"{fresh['wall']:.2f} s, start-up included."]
        lines += ["", f"Threshold, encode and the grey-level normals {stages['normals_at_encode_s']:.2f} s (once per "
                  "object)"]
    if results.get("projection"):
        lines += ["", *_projection_table(results["projection"])]
    if results.get("skin"):
        skin = results["skin"]
        lines += ["", f"vhf_head at {SKIN_THRESHOLD:g} HU (skin: the solid head), {skin['voxels']:,} object voxels, "
                  f"{skin['segments']:,} segments, the paper's views:", ""]
        lines += _views_table(skin["views"], methods)
    if not peers:
        lines += ["", "VTK is not installed: `pip install -e '.[peers]'` adds the peer column."]
    else:
        lines += ["", f"VTK {results['vtk_version']}: vtkFixedPointVolumeRayCastMapper, step opacity at the "
                  "threshold, nearest interpolation, sample distance 1 voxel, parallel projection, its own threads."]
    if results.get("raycast"):
        lines += ["", "Discrete ray casting (median seconds; the logical steps of the rays, and the iterations run: "
                  "26-rays far from the object jump the steps the empty space leaves room for; leaks and misses "
                  "against 6-rays, which meet the contract):",
                  "", "| object | rays | time s | steps 26 | steps 6 | all steps | iterations | late hits | leaks | "
                  "misses |", "|---|---|---|---|---|---|---|---|---|---|"]
        for name, case in results["raycast"].items():
            for connectivity, row in case["rows"].items():
                lines.append(f"| {name} | {connectivity} | {row['seconds']:.2f} | {row['steps_26']:,} | "
                             f"{row['steps_6']:,} | {row['steps_26'] + row['steps_6']:,} | "
                             f"{row.get('iterations', '')} | {row['late_hits']:,} | {row['leaks']:,} | "
                             f"{row['misses']:,} |")
    if results.get("octree"):
        lines += _octree_tables(results["octree"])
    if results.get("octree_files"):
        files = results["octree_files"]
        lines += ["", "Octree methods from a `.vxo` (the octree and its face adjacency kept in the file), a fresh "
                  "`voxrender render` each time, 512 x 512, scale 1: the render seconds each reports (medians of "
                  f"{results['repeat']}); writing the `.vxo` took {files['save_s']:.2f} s", "",
                  "| VPN | octree-btf | octree-ftb | octree-btf/octree-ftb |", "|---|---|---|---|",
                  *(f"| ({', '.join(map(str, row['vpn']))}) | {row['octree-btf']:.3f} | {row['octree-ftb']:.3f} | "
                    f"{row['octree-btf'] / row['octree-ftb']:.2f} |" for row in files["rows"])]
    if results.get("octree_build"):
        big = results["octree_build"]
        peak = f"{big['peak_mb']:.0f} MB peak"
        lines += ["", f"The octree of the head stacked four times ({' x '.join(map(str, big['grid_xyz']))}, "
                  f"{big['voxels']:,} object voxels): the region octree built in {big['build_s']:.2f} s; "
                  f"`voxrender encode big.vxs --octree` (octree, face adjacency, linear codes, written) "
                  f"{big['encode_octree_wall_s']:.2f} s wall, {peak}"]
    if results.get("sorted_octree"):
        lines += ["", "Sorted linear octree against the z-buffer (the linear-octree paper's Table 4; solid cubes, "
                  "256 x 256, median seconds):", "",
                  "| voxels | VPN | zbuffer | octree-sort | zbuffer/octree-sort |", "|---|---|---|---|---|"]
        for row in results["sorted_octree"]:
            for vpn in ("(1, 0, 0)", "(1, 1, 0)", "(1, 1, 1)"):
                z, o = row[f"zbuffer {vpn}"], row[f"octree-sort {vpn}"]
                lines.append(f"| {row['voxels']:,} | {vpn} | {z:.4f} | {o:.4f} | {z / o:.2f} |")
    if results.get("batch"):
        b = results["batch"]
        lines += ["", f"Batch: a {b['views']}-view turntable of vhf_head at {b['size']} x {b['size']} "
                  f"(read and encoded once):", "", "| how | seconds | pictures per second |", "|---|---|---|",
                  f"| `voxrender batch --turntable {b['views']} --jobs 1` | {b['batch_1_s']:.1f} | "
                  f"{b['batch_1_images_per_s']:.2f} |",
                  f"| `voxrender batch --turntable {b['views']} --jobs 2` | {b['batch_2_s']:.1f} | "
                  f"{b['batch_2_images_per_s']:.2f} |"]
        if "separate_s" in b:
            lines.append(f"| {b['views']} separate `voxrender render` commands | {b['separate_s']:.1f} | "
                         f"{b['separate_images_per_s']:.2f} |")
    pipeline = results["pipeline"]
    lines += ["", f"Whole command, DICOM folder to PNG, fresh process ({pipeline['method']}): "
              f"{pipeline['seconds']:.2f} s (`{pipeline['command']}`)", "",
              "Time against N (N^3 volume, N x N picture, view (30, 10)), median seconds:", ""]
    for kind, data in results["scaling"].items():
        scaled = list(data["exponents"])
        lines += [f"| {kind} N | voxels | " + " | ".join(scaled) + " |", "|---|---|" + "---|" * len(scaled)]
        for row in data["rows"]:
            lines.append(f"| {row['n']} | {row['voxels']:,} | " + " | ".join(f"{row[m]:.4f}" for m in scaled) + " |")
        lines += ["", f"fitted exponent of N ({kind}): " +
                  ", ".join(f"{m} {e:.2f}" for m, e in data["exponents"].items()) +
                  "; between the two largest N: " +
                  ", ".join(f"{m} {e:.2f}" for m, e in data["exponents_largest"].items()), ""]
    if results.get("big_stack"):
        lines += big_stack.markdown_lines(results["big_stack"])
    if results.get("studies"):
        lines += studies.markdown_lines(results["studies"])
    lines[1:1] = targets.markdown_lines(results)
    return "\n".join(lines)


def _cli(*args):
    return [sys.executable, "-m", "voxrender.cli", *map(str, args)]


def bench_octree_files(encoded, repeat, size=512):
    """The octree methods as a user runs them: ``voxrender render x.vxo`` in a fresh process, the octree and
    its face adjacency read from the file; the render seconds each reports (medians of ``repeat``, the two
    methods alternating), at the VPNs of Zhao and Davis."""

    rows = []
    with tempfile.TemporaryDirectory() as folder:
        vxo = Path(folder) / "object.vxo"
        started = time.perf_counter()
        encoded.save(vxo, octree=True)
        save_s = time.perf_counter() - started
        for vpn in OCTREE_VPNS:
            seconds = {m: [] for m in ("octree-btf", "octree-ftb")}
            for _ in range(repeat):
                for method in seconds:
                    report = Path(folder) / "stats.json"
                    subprocess.run(_cli("render", vxo, "--method", method, "--vpn", ",".join(map(str, vpn)),
                                        "--scale", "1", "--size", size, "--stats-json", report,
                                        "-o", Path(folder) / "p.png"), check=True, capture_output=True)
                    seconds[method].append(json.loads(report.read_text())["seconds"]["render"])
            rows.append({"vpn": list(vpn), **{m: statistics.median(v) for m, v in seconds.items()}})
    return {"save_s": save_s, "rows": rows}


def bench_octree_build(encoded, copies=4):
    """``voxrender encode big.vxs --octree`` on the head stacked ``copies`` times along z (512 x 512 x 936 at
    four): wall seconds and peak memory of the process, and the build alone in this one."""
    from voxrender.object import octree

    mask = encoded.segments.to_mask()
    big = segments.encode(np.concatenate([mask] * copies, axis=0), encoded.segments.spacing, {"threshold": THRESHOLD})
    del mask
    started = time.perf_counter()
    octree.build_from_segments(big)
    build_s = time.perf_counter() - started
    with tempfile.TemporaryDirectory() as folder:
        vxs.save(big, Path(folder) / "big.vxs")
        # the command in a fresh interpreter that reports its own peak: VmHWM of its memory map (ru_maxrss would
        # keep the high-water mark of the forked copy of this process from before its exec)
        measure = ("import re, resource, sys\nfrom voxrender.cli import main\ntry:\n    main(sys.argv[1:])\n"
                   "finally:\n    try:\n"
                   "        peak = re.search(r'VmHWM:\\s*(\\d+)', open('/proc/self/status').read())[1]\n"
                   "    except (OSError, TypeError):\n"
                   "        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
                   "    print(peak, file=sys.stderr)")
        started = time.perf_counter()
        done = subprocess.run([sys.executable, "-c", measure, "encode", str(Path(folder) / "big.vxs"), "--octree",
                               "-o", str(Path(folder) / "big.vxo")], check=True, capture_output=True, text=True)
        wall_s = time.perf_counter() - started
        peak_kb = int(done.stderr.strip().splitlines()[-1])
    return {"grid_xyz": list(big.shape[::-1]), "voxels": big.voxel_count, "build_s": build_s,
            "encode_octree_wall_s": wall_s, "peak_mb": peak_kb / 1024}


def run(data, repeat, scaling_sizes=SCALING_SIZES, pipeline=True, big=True):
    """All sections; returns the results dict."""
    path = Path(data) / "vhf_head"
    compile_bytecode(HERE)            # the fresh commands start as an installed package does
    started = time.perf_counter()
    volume = io.read_volume(path)
    read_s = time.perf_counter() - started
    encode, encoded = bench_encode(volume, repeat)
    peer, mip_peer, vtk_version = None, None, None
    try:
        import vtk

        peer, vtk_version = VtkPeer(volume.values, THRESHOLD), vtk.vtkVersion.GetVTKVersion()
        mip_peer = VtkMipPeer(volume.values)
    except ImportError:
        pass
    skin = Encoded(segments.encode(prep.binarize(volume, SKIN_THRESHOLD)[0]))
    return {"when": time.strftime("%Y-%m-%d %H:%M"),
            "machine": f"{platform.machine()}, {platform.python_version()}, numpy {np.__version__}",
            "repeat": repeat, "read_s": read_s, "encode": encode, "vtk_version": vtk_version,
            "read": bench_read(path, volume, max(1, repeat // 2)),
            "mask_folder": bench_mask_folder(max(1, repeat // 2)),
            "agreement": bench_agreement(path, max(1, repeat // 2)),
            "index_page": bench_index_page(10_000, max(1, repeat // 2)),
            "index_browser": bench_index_browser(10_000, 300, max(1, repeat // 2)),
            "views": bench_views(encoded, repeat, peer=peer),
            "skin": {"voxels": skin.segments.voxel_count, "segments": skin.segments.segment_count,
                     "views": bench_views(skin, repeat, views=PAPER_VIEWS)},
            "stages": bench_stages(path, repeat, peer=peer),
            "projection": bench_projection(volume.values, repeat, peer=mip_peer),
            "pipeline": bench_pipeline(path, max(1, repeat // 2)) if pipeline else {"command": "", "seconds": math.nan,
                                                                                   "method": DEFAULT_METHOD},
            "scaling": bench_scaling(repeat, scaling_sizes),
            "batch": bench_batch(path),
            "octree": bench_octree({f"vhf_head {THRESHOLD:g} HU": (encoded, 1.0),
                                    f"vhf_head {THRESHOLD:g} HU, the volume fitted": (encoded, None),
                                    "checkerboard 128^3, the volume fitted": (Encoded(segments.encode(checkerboard())),
                                                                               None)},
                                   repeat),
            "octree_files": bench_octree_files(encoded, repeat),
            "octree_build": bench_octree_build(encoded),
            "commands": targets.bench_commands(data, repeat),
            "big_stack": big_stack.bench_big_stack() if big else {"skipped": "left out (--no-big-stack)",
                                                                        "rows": []},
            "studies": studies.run(data, min(repeat, 3)),
            "sorted_octree": bench_sorted_octree(repeat),
            "raycast": bench_raycast(min(repeat, 3), {
                "thin shell 128^3": (segments.encode(thin_shell()), View(30.0, 10.0, 0.0, (256, 256), 1.5)),
                f"vhf_head {THRESHOLD:g} HU": (encoded.segments, View(30.0, 10.0, 0.0, (512, 512), 1.0))})}


@click.command()
@click.option("--data", default=str(Path(__file__).resolve().parents[1].parent / "shared" / "data"),
              show_default=True, help="Folder holding vhf_head/.")
@click.option("--repeat", default=5, show_default=True, type=click.IntRange(1, 100))
@click.option("--out", default="benchmark-results", show_default=True, type=click.Path())
@click.option("--big-stack/--no-big-stack", "big", default=True, show_default=True,
              help="The big-stack section (a 16 GiB stack written once, about 20 minutes of the run).")
def main(data, repeat, out, big):
    """Time every renderer on vhf_head and write benchmark-results/."""
    if not (Path(data) / "vhf_head").is_dir():
        raise SystemExit(f"error: {Path(data) / 'vhf_head'} is absent; the benchmark needs ../shared/data (or --data)")
    results = run(data, repeat, big=big)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps(results, indent=2, default=float))
    (out / "results.md").write_text(markdown(results) + "\n")
    click.echo(markdown(results))


if __name__ == "__main__":
    main()
