"""Many studies beside VTK (issue 25, targets 1 and 2): studies per minute from the files, and the whole command.

    python -m benchmarks.studies [--repeat 3] [--data ../shared/data] [--out benchmark-results/studies]

* ``write_studies`` writes 24 studies once into a cache (``$VOXRENDER_BENCH_CACHE`` or ``~/.cache/voxrender-bench``,
  as the big stack): crops of ``vhf_head`` and of ``headsq``, half DICOM series and half ``.nii.gz``, each with its
  own crop, flips, slice count and origin, so that no two are alike.
* ``voxrender batch`` renders 4 views of each (a manifest: 300 HU for ``vhf_head``'s, 1150 for ``headsq``'s), with
  ``--jobs 1`` and ``--jobs 2``, each a fresh process; beside it, in the same run and interleaved with it, a VTK
  script (``VTK_SCRIPT``, a fresh process) renders the same 4 views of each study as a VTK user writes it:
  ``vtkDICOMImageReader`` or ``vtkNIFTIImageReader``, ``vtkFixedPointVolumeRayCastMapper`` with shading (the
  settings of ``benchmarks.bench.VtkPeer``: a step of opacity at the threshold, nearest interpolation, a sample a
  voxel), a parallel camera framed on the object as voxrender frames it (``View.fitted`` and ``frame_together``:
  the object's bounding box as each view sees it, a 5 % margin, one scale for the 4 views), and ``vtkPNGWriter``.
  Studies per minute of each, and the ratio.
* The whole command: a fresh ``voxrender render vhf_head --threshold 300 --alpha 30 --beta 10 --size 512 --scale
  1`` with the stages it reports (``--stats-json``), beside a fresh VTK script drawing the same picture (one pixel
  per voxel, the camera on the volume centre), interleaved.

The VTK script imports only the VTK modules it uses, and numpy: it is what a user would run, and importing
``benchmarks.bench`` (voxrender with it) would add voxrender's start-up to VTK's time, so it holds its own copy of
``VtkPeer``'s few settings rather than importing them.
"""

from __future__ import annotations

import csv
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import click
import numpy as np

from benchmarks import compile_bytecode

STUDIES_VERSION = 2                  # bump when the studies written change: the cache is rewritten
VHF_THRESHOLD = 300.0                # HU, bone (as benchmarks.bench)
HEADSQ_THRESHOLD = 1150.0            # headsq's stored values, bone (../shared/data/README.md)
# the 4 views, by the names voxrender batch gives their pictures (presets, and a30_b10_g0 for an angle triple)
VIEWS = {"anterior": (90.0, 0.0, 0.0), "left": (90.0, 90.0, 0.0), "superior": (0.0, 180.0, 0.0),
         "a30_b10_g0": (30.0, 10.0, 0.0)}
SIZE = 512
MARGIN = 0.05                        # View.fitted's margin
TARGET_RATIO = 3.0                   # voxrender --jobs 2 over VTK, studies per minute
TARGET_PER_MINUTE = 120.0
HERE = Path(__file__).resolve().parents[1]
DEFAULT_DATA = HERE.parent / "shared" / "data"


def default_root():
    """The cache of the studies: beside the big stack's (``benchmarks.big_stack.cache_root``)."""
    from benchmarks.big_stack import cache_root

    return cache_root() / f"studies-v{STUDIES_VERSION}"


# ---------------------------------------------------------------------------------------------------------------
# The studies


def sources(data):
    """The CTs the studies are cut from: name -> (values[z, y, x] int16, spacing (x, y, z) mm, threshold)."""
    from voxrender import io
    from voxrender.io._shared import RawLayout

    data = Path(data)
    vhf = io.read_volume(data / "vhf_head")
    headsq = io.read_volume(data / "headsq", raw=RawLayout(64, 64, np.dtype("<u2")), spacing=(3.2, 3.2, 1.5))
    return {"vhf_head": (np.asarray(vhf.values, dtype=np.int16), tuple(map(float, vhf.spacing)), VHF_THRESHOLD),
            "headsq": (np.asarray(headsq.values).astype(np.int16), tuple(map(float, headsq.spacing)),
                       HEADSQ_THRESHOLD)}


def plan(count, shapes, seed=25):
    """``count`` distinct studies: source (``headsq`` for the 4th and 7th of every 8, so one DICOM and one NIfTI),
    format (alternately DICOM and NIfTI), crop ``((z0, z1), (y0, y1), (x0, x1))`` (half-open), flips of (z, y, x)
    and origin (x, y, z) mm.

    ``shapes``: source name -> its (nz, ny, nx).  No two studies share shape, flips and origin.
    """
    rng = np.random.default_rng(seed)
    studies, seen = [], set()
    for k in range(count):
        source = "headsq" if k % 8 in (3, 6) else "vhf_head"
        nz, ny, nx = shapes[source]
        while True:
            crop = []
            for n, least in ((nz, 0.45), (ny, 0.6), (nx, 0.6)):
                length = int(rng.integers(int(n * least), n + 1))
                start = int(rng.integers(0, n - length + 1))
                crop.append([start, start + length])
            flips = tuple(bool(f) for f in rng.integers(0, 2, size=3))
            origin = tuple(float(round(v, 1)) for v in rng.uniform(-150, 150, size=3))
            key = (tuple(b - a for a, b in crop), flips, origin)
            if key not in seen:
                seen.add(key)
                break
        studies.append({"name": f"study{k:02d}", "source": source, "format": "dicom" if k % 2 == 0 else "nifti",
                        "crop": crop, "flips": list(flips), "origin": list(origin)})
    return studies


def cut(values, study):
    """The study's voxels: the crop of ``values``, flipped as it says."""
    (z0, z1), (y0, y1), (x0, x1) = study["crop"]
    part = values[z0:z1, y0:y1, x0:x1]
    for axis, flip in enumerate(study["flips"]):
        if flip:
            part = np.flip(part, axis)
    return np.ascontiguousarray(part, dtype=np.int16)


def write_dicom_series(folder, values, spacing, origin, description="voxrender benchmark study"):
    """``values[z, y, x]`` (HU) as an axial CT series, one file per slice: signed 16-bit stored values, rescale 1/0,
    axes along L, P, S (DICOM's identity orientation) from ``origin`` (x, y, z mm)."""
    from pydicom.dataset import FileDataset, FileMetaDataset
    from pydicom.uid import CTImageStorage, ExplicitVRLittleEndian, generate_uid

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    series, study = generate_uid(), generate_uid()
    for z, plane in enumerate(values):
        meta = FileMetaDataset()
        meta.MediaStorageSOPClassUID = CTImageStorage
        meta.MediaStorageSOPInstanceUID = generate_uid()
        meta.TransferSyntaxUID = ExplicitVRLittleEndian
        path = folder / f"slice{z:04d}.dcm"
        ds = FileDataset(str(path), {}, file_meta=meta, preamble=b"\0" * 128)
        ds.SOPClassUID, ds.SOPInstanceUID = CTImageStorage, meta.MediaStorageSOPInstanceUID
        ds.Modality, ds.StudyInstanceUID, ds.SeriesInstanceUID = "CT", study, series
        ds.SeriesDescription, ds.InstanceNumber = description, z + 1
        ds.ImagePositionPatient = [float(origin[0]), float(origin[1]), float(origin[2] + z * spacing[2])]
        ds.ImageOrientationPatient = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
        ds.PixelSpacing = [float(spacing[1]), float(spacing[0])]
        ds.SliceThickness = float(spacing[2])
        ds.SamplesPerPixel, ds.PhotometricInterpretation = 1, "MONOCHROME2"
        ds.Rows, ds.Columns = plane.shape
        ds.BitsAllocated, ds.BitsStored, ds.HighBit, ds.PixelRepresentation = 16, 16, 15, 1
        ds.RescaleSlope, ds.RescaleIntercept = 1, 0
        ds.PixelData = np.ascontiguousarray(plane, dtype="<i2").tobytes()
        ds.save_as(path, enforce_file_format=True)
    return folder


def write_nifti(path, values, spacing, origin):
    """``values[z, y, x]`` as a ``.nii.gz`` whose axes run along L, P, S (the canonical frame, as the DICOM
    series): the RAS affine has -x, -y spacing, and ``origin`` (LPS mm) as RAS."""
    import nibabel

    affine = np.diag([-spacing[0], -spacing[1], spacing[2], 1.0])
    affine[:3, 3] = (-origin[0], -origin[1], origin[2])
    image = nibabel.Nifti1Image(np.ascontiguousarray(values.transpose(2, 1, 0)), affine)
    image.set_qform(affine, code=1)
    image.set_sform(affine, code=1)
    nibabel.save(image, str(path))
    return Path(path)


def write_studies(root=None, data=DEFAULT_DATA, count=24, cut_from=None):
    """The studies, written once into ``root`` (default ``default_root()``) and reused while their plan holds.

    ``cut_from`` (default ``sources(data)``) gives the volumes to cut them from, as :func:`sources` does.  Returns
    a list of dicts: name, source, format, crop, flips, origin, ``path`` (a DICOM folder or a ``.nii.gz``),
    ``threshold``, ``shape`` (nz, ny, nx) and ``spacing``.
    """
    root = Path(root or default_root())
    folder = root / f"studies-{count}"
    marker = folder / "studies.json"
    if marker.is_file():
        kept = json.loads(marker.read_text())
        if kept.get("version") == STUDIES_VERSION and all(Path(s["path"]).exists() for s in kept["studies"]):
            return kept["studies"]
    cut_from = cut_from or sources(data)
    studies = plan(count, {name: values.shape for name, (values, _, _) in cut_from.items()})
    folder.mkdir(parents=True, exist_ok=True)
    for study in studies:
        values, spacing, threshold = cut_from[study["source"]]
        part = cut(values, study)
        if study["format"] == "dicom":
            path = write_dicom_series(folder / study["name"], part, spacing, study["origin"])
        else:
            path = write_nifti(folder / f"{study['name']}.nii.gz", part, spacing, study["origin"])
        study.update(path=str(path), threshold=threshold, shape=list(part.shape), spacing=list(spacing))
    marker.write_text(json.dumps({"version": STUDIES_VERSION, "studies": studies}, indent=1))
    return studies


def write_manifest(path, studies, views=VIEWS):
    """The batch's manifest: each study with its threshold and the 4 views (preset names, or angle triples)."""
    from voxrender.space.view import PRESETS

    triples = ";".join(name if PRESETS.get(name) == angles else ",".join(f"{a:g}" for a in angles)
                       for name, angles in views.items())
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["input", "threshold", "views"])
        for study in studies:
            writer.writerow([study["path"], f"{study['threshold']:g}", triples])
    return Path(path)


# ---------------------------------------------------------------------------------------------------------------
# The VTK script: a fresh process, VTK and numpy only

VTK_SCRIPT = r'''
"""A VTK user's script: each study read, ray cast with shading from each view, written as PNG.

    python vtk_studies.py job.json   (job: studies [{name, path, format, threshold}], views [[label, a, b, g]], size,
                                      scale (pixels per voxel, the camera on the volume centre) or none (framed on
                                      the object as voxrender frames it), out, report)
"""
import time

started = time.perf_counter()
import json, math, sys
from pathlib import Path

import numpy as np
import vtkmodules.vtkRenderingOpenGL2  # noqa: F401  (the window's implementation)
import vtkmodules.vtkRenderingVolumeOpenGL2  # noqa: F401  (the ray caster's image display helper)
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkObject
from vtkmodules.vtkCommonDataModel import vtkPiecewiseFunction
from vtkmodules.vtkIOImage import vtkDICOMImageReader, vtkNIFTIImageReader, vtkPNGWriter
from vtkmodules.vtkRenderingCore import vtkRenderer, vtkRenderWindow, vtkVolume, vtkVolumeProperty, \
    vtkWindowToImageFilter
from vtkmodules.vtkRenderingVolume import vtkFixedPointVolumeRayCastMapper

seconds = {"import": time.perf_counter() - started, "read": 0.0, "frame": 0.0, "render": 0.0, "write": 0.0}
vtkObject.GlobalWarningDisplayOff()


def rotation(alpha, beta, gamma):
    """voxrender's R = Rz(gamma) Ry(beta) Rx(alpha): its rows are the picture's right, down and forward (LPS)."""
    def cs(d):
        if d % 90 == 0:
            return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[int(d // 90) % 4]
        return math.cos(math.radians(d)), math.sin(math.radians(d))
    (ca, sa), (cb, sb), (cg, sg) = cs(alpha), cs(beta), cs(gamma)
    rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    rz = np.array([[cg, -sg, 0], [sg, cg, 0], [0, 0, 1]])
    return rz @ ry @ rx


job = json.loads(Path(sys.argv[1]).read_text())
height = width = int(job["size"])
out = Path(job["out"])
window = vtkRenderWindow()
window.SetOffScreenRendering(1)
window.SetSize(width, height)
for study in job["studies"]:
    t = time.perf_counter()
    if study["format"] == "dicom":
        reader = vtkDICOMImageReader()
        reader.SetDirectoryName(study["path"])
    else:
        reader = vtkNIFTIImageReader()
        reader.SetFileName(study["path"])
    reader.Update()
    image = reader.GetOutput()
    threshold = float(study["threshold"])
    if study["format"] == "dicom":        # vtkDICOMImageReader keeps the stored values: the threshold in them
        threshold = (threshold - reader.GetRescaleOffset()) / (reader.GetRescaleSlope() or 1.0)
    t2 = time.perf_counter()
    seconds["read"] += t2 - t
    nx, ny, nz = image.GetDimensions()
    spacing, origin = np.array(image.GetSpacing()), np.array(image.GetOrigin())
    # VTK's world axes against the patient's L, P, S: the DICOM reader stores rows bottom-up and the slices from
    # the last (y toward A, z toward I: a turn of 180 degrees about x); the NIfTI reader keeps the file's order
    axes = np.diag([1.0, -1.0, -1.0]) if study["format"] == "dicom" else np.eye(3)
    centre = origin + spacing * (np.array([nx, ny, nz]) - 1) / 2
    rotations = [rotation(*view[1:]) @ axes for view in job["views"]]   # rows: right, down, forward in VTK's world
    if job.get("scale"):                  # pixels per voxel of the smallest spacing, on the volume centre
        mm_scale = job["scale"] / spacing.min()
        framing = [(centre, mm_scale)] * len(rotations)
    else:                                 # the object's bounding box as each view sees it; one scale for all views
        values = vtk_to_numpy(image.GetPointData().GetScalars()).reshape(nz, ny, nx)
        inside = values >= threshold
        box = []
        for axis in (2, 1, 0):           # x, y, z: the first and last index holding the object
            hit = np.flatnonzero(inside.any(axis=tuple(a for a in range(3) if a != axis)))
            box.append((hit[0] - 0.5, hit[-1] + 0.5) if hit.size else (-0.5, 0.5))
        corners = np.array([[x, y, z] for x in box[0] for y in box[1] for z in box[2]]) * spacing + origin
        fits = []
        for r in rotations:
            xs, ys = (corners - centre) @ r[0], (corners - centre) @ r[1]
            scale = min(width / ((xs.max() - xs.min()) * (1 + 2 * job["margin"])),
                        height / ((ys.max() - ys.min()) * (1 + 2 * job["margin"])))
            fits.append((centre + (xs.max() + xs.min()) / 2 * r[0] + (ys.max() + ys.min()) / 2 * r[1], scale))
        common = min(scale for _, scale in fits)
        framing = [(focal, common) for focal, _ in fits]
    opacity = vtkPiecewiseFunction()                  # benchmarks.bench.VtkPeer's settings
    low, high = image.GetScalarTypeMin(), image.GetScalarTypeMax()   # the type's range: no pass over the values
    opacity.AddPoint(min(low, threshold) - 1, 0.0)
    opacity.AddPoint(threshold - 1e-3, 0.0)
    opacity.AddPoint(threshold, 1.0)
    opacity.AddPoint(max(high, threshold) + 1, 1.0)
    prop = vtkVolumeProperty()
    prop.SetScalarOpacity(opacity)
    prop.SetInterpolationTypeToNearest()
    prop.ShadeOn()
    prop.SetAmbient(0.2)                              # faces a crop cuts (no gradient) grey, not black: drawn
    prop.SetDiffuse(0.8)
    mapper = vtkFixedPointVolumeRayCastMapper()
    mapper.SetInputConnection(reader.GetOutputPort())
    mapper.AutoAdjustSampleDistancesOff()
    mapper.SetSampleDistance(float(spacing.min()))    # a sample a voxel
    volume = vtkVolume()
    volume.SetMapper(mapper)
    volume.SetProperty(prop)
    renderer = vtkRenderer()
    renderer.AddVolume(volume)
    window.AddRenderer(renderer)
    camera = renderer.GetActiveCamera()
    camera.ParallelProjectionOn()
    t3 = time.perf_counter()
    seconds["frame"] += t3 - t2
    (out / study["name"]).mkdir(parents=True, exist_ok=True)
    for view, r, (focal, mm_scale) in zip(job["views"], rotations, framing):
        t = time.perf_counter()
        camera.SetFocalPoint(*focal)
        camera.SetPosition(*(focal - 4000 * r[2]))   # the viewer looks along forward
        camera.SetViewUp(*(-r[1]))                   # picture up is -down
        camera.SetParallelScale(height / (2 * mm_scale))
        renderer.ResetCameraClippingRange()
        window.Render()
        t2 = time.perf_counter()
        grab = vtkWindowToImageFilter()
        grab.SetInput(window)
        grab.ShouldRerenderOff()                     # the picture just rendered, not a second render
        grab.ReadFrontBufferOff()
        writer = vtkPNGWriter()
        writer.SetInputConnection(grab.GetOutputPort())
        writer.SetFileName(str(out / study["name"] / f"{view[0]}.png"))
        writer.Write()
        t3 = time.perf_counter()
        seconds["render"] += t2 - t
        seconds["write"] += t3 - t2
    window.RemoveRenderer(renderer)
seconds["total"] = time.perf_counter() - started
Path(job["report"]).write_text(json.dumps({"seconds": seconds}))
'''


def vtk_available():
    try:
        import vtkmodules.vtkRenderingVolume  # noqa: F401
    except ImportError:
        return False
    return True


def run_vtk(studies, out, views=VIEWS, size=SIZE, scale=None, python=sys.executable):
    """The VTK script over ``studies`` in a fresh process: (wall seconds, its stage seconds)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    script, job, report = out / "vtk_studies.py", out / "job.json", out / "vtk-report.json"
    script.write_text(VTK_SCRIPT)
    job.write_text(json.dumps({"studies": [{k: s[k] for k in ("name", "path", "format", "threshold")} for s in studies],
                               "views": [[name, *angles] for name, angles in views.items()], "size": size,
                               "scale": scale, "margin": MARGIN, "out": str(out), "report": str(report)}))
    started = time.perf_counter()
    subprocess.run([python, str(script), str(job)], check=True, capture_output=True, cwd=out)
    wall = time.perf_counter() - started
    return wall, json.loads(report.read_text())["seconds"]


def cli(*args, python=sys.executable):
    return [python, "-m", "voxrender.cli", *map(str, args)]


def run_batch(manifest, out, jobs, size=SIZE, python=sys.executable, env=None):
    """``voxrender batch --manifest`` in a fresh process into the empty folder ``out``: wall seconds."""
    started = time.perf_counter()
    subprocess.run(cli("batch", "--manifest", manifest, "-o", out, "--jobs", jobs, "--size", size, python=python),
                   check=True, capture_output=True, env=env)
    return time.perf_counter() - started


def batch_stages(summary):
    """Where a batch's time went, from its ``summary.csv``: mean seconds per study of load and prepare, and per
    view of render, shade and write."""
    with open(summary, newline="") as f:
        rows = [row for row in csv.DictReader(f) if row["status"] == "ok"]
    studies = {row["input"]: row for row in rows}.values()
    per_study = {k: statistics.mean(float(row[f"{k}_s"] or 0) for row in studies) for k in ("load", "prepare")}
    per_view = {k: statistics.mean(float(row[f"{k}_s"] or 0) for row in rows) for k in ("render", "shade", "write")}
    return {**per_study, **per_view}


def drawn_pixels(png):
    """Pixels of a picture that are not the black background."""
    import imageio.v3 as iio

    picture = iio.imread(png)
    return int(np.count_nonzero(picture[..., :3].max(axis=-1) if picture.ndim == 3 else picture))


def bench_studies(studies, repeat, views=VIEWS, size=SIZE, vtk=None):
    """Studies per minute of ``voxrender batch`` (``--jobs 1`` and ``--jobs 2``) and of the VTK script (when
    ``vtk``, default: when it is installed), each a fresh process, the three interleaved, medians of ``repeat``;
    and the pixels each draws of the first study's views (the framing's check)."""
    vtk = vtk_available() if vtk is None else vtk
    walls = {"jobs 1": [], "jobs 2": [], **({"vtk": []} if vtk else {})}
    vtk_stages, stages = [], {}
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        manifest = write_manifest(folder / "manifest.csv", studies, views)
        for r in range(repeat):
            for how in walls:
                out = folder / f"{how.replace(' ', '')}-{r}"
                if how == "vtk":
                    wall, seconds = run_vtk(studies, out, views, size)
                    vtk_stages.append(seconds)
                else:
                    wall = run_batch(manifest, out, int(how.split()[1]), size)
                    stages.setdefault(how, []).append(batch_stages(out / "summary.csv"))
                walls[how].append(wall)
        first = studies[0]["name"]
        pixels = {"voxrender": [drawn_pixels(folder / "jobs2-0" / first / f"{v}.png") for v in views]}
        if vtk:
            pixels["vtk"] = [drawn_pixels(folder / "vtk-0" / first / f"{v}.png") for v in views]
    n = len(studies)
    result = {"studies": n, "views": len(views), "size": size, "repeat": repeat,
              "formats": {f: sum(s["format"] == f for s in studies) for f in ("dicom", "nifti")},
              "sources": {src: sum(s["source"] == src for s in studies) for src in ("vhf_head", "headsq")},
              "rows": {how: {"seconds": statistics.median(w), "all": w, "per_minute": 60 * n / statistics.median(w)}
                       for how, w in walls.items()},
              "pixels": pixels,
              "batch_stages": {how: {k: statistics.median(r[k] for r in runs) for k in runs[0]}
                               for how, runs in stages.items()}}
    if vtk_stages:
        result["vtk_stages"] = {k: statistics.median(s[k] for s in vtk_stages) for k in vtk_stages[0]}
    return result


def bench_whole_command(data, repeat, size=SIZE):
    """A fresh ``voxrender render vhf_head`` (stages from ``--stats-json``) and a fresh VTK script drawing the same
    picture (alpha 30, beta 10, one pixel per voxel), alternating; medians of ``repeat``."""
    path = Path(data) / "vhf_head"
    ours, stages, theirs, their_stages = [], [], [], []
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        command = cli("render", path, "--threshold", f"{VHF_THRESHOLD:g}", "--alpha", 30, "--beta", 10, "--size",
                      size, "--scale", 1, "--stats-json", folder / "stats.json", "-o", folder / "voxrender.png")
        vtk = vtk_available()
        for _ in range(repeat):
            started = time.perf_counter()
            subprocess.run(command, check=True, capture_output=True)
            ours.append(time.perf_counter() - started)
            stages.append(json.loads((folder / "stats.json").read_text())["seconds"])
            if vtk:
                wall, seconds = run_vtk([{"name": "vhf_head", "path": str(path), "format": "dicom",
                                          "threshold": VHF_THRESHOLD}], folder / "vtk",
                                        {"a30_b10_g0": (30.0, 10.0, 0.0)}, size, scale=1.0)
                theirs.append(wall)
                their_stages.append(seconds)
        pixels = {"voxrender": drawn_pixels(folder / "voxrender.png")}
        if vtk:
            pixels["vtk"] = drawn_pixels(folder / "vtk" / "vhf_head" / "a30_b10_g0.png")
    names = [k for k in stages[0] if k != "total"]
    result = {"command": f"voxrender render vhf_head --threshold {VHF_THRESHOLD:g} --alpha 30 --beta 10 --size "
                         f"{size} --scale 1", "repeat": repeat, "wall": statistics.median(ours), "walls": ours,
              "stages": {k: statistics.median(s.get(k, 0.0) for s in stages) for k in names}, "pixels": pixels}
    if theirs:
        result["vtk_wall"] = statistics.median(theirs)
        result["vtk_walls"] = theirs
        result["vtk_stages"] = {k: statistics.median(s[k] for s in their_stages) for k in their_stages[0]}
    return result


def run(data, repeat, count=24, root=None):
    """The section: the studies (written once), their batch beside VTK, and the whole command beside VTK."""
    studies = write_studies(root, data, count)
    compile_bytecode(HERE)            # voxrender's fresh processes start as an installed package does, VTK's too
    return {"when": time.strftime("%Y-%m-%d %H:%M"), "load": os.getloadavg()[0],
            "machine": f"{platform.machine()}, {os.cpu_count()} cores, {platform.python_version()}",
            "commit": _commit(), "studies": bench_studies(studies, repeat),
            "whole_command": bench_whole_command(data, max(repeat, 3))}


def _commit():
    try:
        head = subprocess.run(["git", "-C", str(HERE), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(HERE), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + (" (with uncommitted changes)" if dirty else "")


def _met(ok):
    return "met" if ok else "missed"


def markdown_lines(results):
    """The section of results.md."""
    s = results["studies"]
    rows = s["rows"]
    lines = ["", f"Many studies (issue 25): {s['studies']} studies ({s['sources']['vhf_head']} cut from vhf_head at "
             f"{VHF_THRESHOLD:g} HU, {s['sources']['headsq']} from headsq at {HEADSQ_THRESHOLD:g}; "
             f"{s['formats']['dicom']} DICOM series, {s['formats']['nifti']} .nii.gz; crops, flips, slice counts and "
             f"origins all different) x {s['views']} views at {s['size']} x {s['size']}, from the files, each run a "
             f"fresh process, interleaved; median of {s['repeat']} (commit {results.get('commit', '?')}, load "
             f"{results.get('load', float('nan')):.1f}):", "",
             "| how | seconds | studies per minute |", "|---|---|---|"]
    names = {"jobs 1": "`voxrender batch --jobs 1`", "jobs 2": "`voxrender batch --jobs 2`",
             "vtk": "VTK script (vtkDICOMImageReader / vtkNIFTIImageReader, ray cast with shading, framed as "
                    "voxrender frames, vtkPNGWriter)"}
    for how, row in rows.items():
        lines.append(f"| {names[how]} | {row['seconds']:.1f} | {row['per_minute']:.0f} |")
    notes = []
    if "vtk" in rows:
        ratio = rows["jobs 2"]["per_minute"] / rows["vtk"]["per_minute"]
        notes.append(f"voxrender `--jobs 2` / VTK: {ratio:.2f}x (target >= {TARGET_RATIO:g}x: {_met(ratio >= 3)}); "
                     f"`--jobs 1` / VTK: {rows['jobs 1']['per_minute'] / rows['vtk']['per_minute']:.2f}x")
    best = rows["jobs 2"]["per_minute"]
    notes.append(f"voxrender `--jobs 2`: {best:.0f} studies per minute (target >= {TARGET_PER_MINUTE:g}: "
                 f"{_met(best >= TARGET_PER_MINUTE)})")
    for how, st in s.get("batch_stages", {}).items():
        notes.append(f"inside `voxrender batch --{how}` (its summary.csv, mean seconds): per study load "
                     f"{st['load']:.3f}, prepare {st['prepare']:.3f}; per view render {st['render']:.3f}, shade "
                     f"{st['shade']:.3f}, write {st['write']:.3f}")
    if s.get("vtk_stages"):
        notes.append("VTK's own stages over all studies (s): " +
                     ", ".join(f"{k} {v:.2f}" for k, v in s["vtk_stages"].items()))
    pixels = s.get("pixels", {})
    if pixels.get("vtk"):
        notes.append("pixels drawn, the first study's views (voxrender / VTK): " +
                     ", ".join(f"{name} {a:,} / {b:,}" for name, a, b in zip(VIEWS, pixels["voxrender"],
                                                                            pixels["vtk"], strict=False)) +
                     " (VTK leaves the faces a crop cuts unlit: black, not counted)")
    w = results.get("whole_command")
    if w:
        notes.append(f"the whole command, a fresh process each (median of {w['repeat']}, alternating with VTK): "
                     f"`{w['command']}` {w['wall']:.2f} s wall (target <= 0.5 s: {_met(w['wall'] <= 0.5)}); its "
                     "stages: " + ", ".join(f"{k} {v:.3f}" for k, v in w["stages"].items()) +
                     f"; start-up and the rest {w['wall'] - sum(w['stages'].values()):.2f} s")
        if "vtk_wall" in w:
            notes.append("the VTK script for the same picture (vtkDICOMImageReader, ray cast with shading, parallel "
                         f"camera at one pixel per voxel, vtkPNGWriter): {w['vtk_wall']:.2f} s wall; its stages: " +
                         ", ".join(f"{k} {v:.3f}" for k, v in w["vtk_stages"].items() if k != "total") +
                         f"; voxrender / VTK wall {w['wall'] / w['vtk_wall']:.2f}; pixels drawn "
                         f"{w['pixels']['voxrender']:,} / {w['pixels']['vtk']:,}")
    return lines + [""] + [f"- {note}" for note in notes]


@click.command()
@click.option("--data", default=str(DEFAULT_DATA), show_default=True, help="Folder holding vhf_head/ and headsq/.")
@click.option("--repeat", default=3, show_default=True, type=click.IntRange(1, 100))
@click.option("--count", default=24, show_default=True, type=click.IntRange(1, 200), help="Studies written.")
@click.option("--out", default="benchmark-results/studies", show_default=True, type=click.Path())
def main(data, repeat, count, out):
    """Time voxrender batch and a VTK script over many studies, and the whole command beside VTK."""
    if not (Path(data) / "vhf_head").is_dir() or not (Path(data) / "headsq").is_dir():
        raise SystemExit(f"error: {data} lacks vhf_head/ or headsq/; the benchmark needs ../shared/data (or --data)")
    results = run(data, repeat, count)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps(results, indent=2, default=float))
    text = "\n".join(markdown_lines(results)).strip()
    (out / "results.md").write_text(text + "\n")
    click.echo(text)


if __name__ == "__main__":
    main()
