"""Batch rendering: many stacks, many views, one command, on one machine or a Dask cluster.

A batch is a list of :class:`Item` (an input with its preprocessing, method and views).
It runs in two phases of independent tasks:

1. *encode*: each input that still has a picture to make is read, thresholded and encoded
   once, into a cache of ``.vxs`` files keyed by the input's content and the options that
   shape the object (a re-run, or another batch over the same data, reuses it);
2. *render*: each (input, view) loads the cached segments (memory-mapped) and writes its PNG.

Tasks run in worker processes (``jobs``) or on a Dask cluster (``scheduler``); a failing
input is recorded and the others go on; every picture is written atomically, and a
re-run skips the pictures that exist and are valid.  One summary row per picture.

Faults it survives: a worker process that dies (its pictures fail with how it died, the others
are made), a batch killed part-way (the re-run makes the rest and clears the temporaries it
left), a full disk (one error that says how many pictures are there; the summary, if it fits,
agrees), a cache entry damaged or tampered with (its checksum finds it out; it is made again).
Outputs stay inside the batch's folder, which one batch at a time holds (a lock the system
lets go of when its process ends, however it ends).
Memory: a worker holds one volume (and its mask) while it encodes, and only memory-mapped
segments and one picture while it renders, so the peak is about ``jobs`` times the largest
volume plus its mask.
"""

from __future__ import annotations

import contextlib
import csv
import errno
import functools
import glob
import hashlib
import json
import os
import time
import tomllib
import traceback
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from .. import __version__
from .._render import framing_box, method_record, octree_for
from .._shared.executors import executor, why_died
from .._shared.files import atomic_output, check_folder_writable, remove_partials
from .._shared.text import from_spreadsheet_cell, spreadsheet_cell
from ..errors import InputError
from ..object.pipeline import PrepOptions, ReadOptions, is_segments_file, load_segments
from ..object.prep import LabelSelection
from ..outputs import Outputs, about, output, write_outputs
from ..outputs.output_kinds import OUTPUTS, fields_per_output
from ..pictures import RenderOptions, picture
from ..space.view import PRESETS, angles_from_matrix, frame_together, rotation_matrix
from . import parse

SUMMARY_COLUMNS = ["input", "name", "view", "alpha", "beta", "gamma", "method", "output", "status", "error",
                   "labels", "label_volumes", "load_s", "prepare_s", "render_s", "shade_s", "write_s", "total_s",
                   "stats", "overlaps"]
LABEL_COLUMNS = ("labels", "label_volumes", "overlaps")    # what a picture done earlier keeps


@dataclass(frozen=True)
class ViewSpec:
    """A named view of a batch (angles in degrees)."""

    label: str
    alpha: float
    beta: float
    gamma: float = 0.0


def turntable(count, axis="z", base=(90.0, 0.0, 0.0)):
    """``count`` views turning the object about an object axis, starting at ``base`` (default: anterior).

    Each frame is the base rotation after a turn of the object about ``axis``; Theorem 2 turns
    that rotation back into angles.

    >>> [v.label for v in turntable(3)]
    ['turn000', 'turn001', 'turn002']
    >>> round(turntable(4)[1].beta, 6)
    -90.0
    """
    if count < 1:
        raise InputError(f"{count}: a turntable needs at least 1 view", parameter="turntable")
    if axis not in ("x", "y", "z"):
        raise InputError(f"{axis!r} must be x, y or z", parameter="axis")
    base_matrix = rotation_matrix(*base)
    views = []
    for k in range(count):
        angle = 360.0 * k / count
        turn = {"x": rotation_matrix(angle, 0, 0), "y": rotation_matrix(0, angle, 0),
                "z": rotation_matrix(0, 0, angle)}[axis]
        alpha, beta, gamma = angles_from_matrix(base_matrix @ turn)
        views.append(ViewSpec(f"turn{k:03d}", alpha, beta, gamma))
    return views


def parse_views(names=(), angles=(), turntable_count=None, axis="z"):
    """Views from preset names, ``(alpha, beta, gamma)`` triples and a turntable; the anterior view when none.

    >>> [(v.label, v.alpha) for v in parse_views(["left"], [(30, 10, 0)])]
    [('left', 90.0), ('a30_b10_g0', 30.0)]
    """
    views = []
    for name in names:
        if name not in PRESETS:
            raise InputError(f"unknown view {name!r}; choose one of {', '.join(PRESETS)}", parameter="view")
        views.append(ViewSpec(name, *PRESETS[name]))
    for values in angles:
        values = tuple(float(v) for v in values)
        views.append(ViewSpec("a{:g}_b{:g}_g{:g}".format(*values), *values))
    if turntable_count:
        first = views.pop(0) if views else ViewSpec("anterior", *PRESETS["anterior"])
        views.extend(turntable(turntable_count, axis, (first.alpha, first.beta, first.gamma)))
    if not views:
        views.append(ViewSpec("anterior", *PRESETS["anterior"]))
    labels = [v.label for v in views]
    if len(set(labels)) != len(labels):
        raise InputError("the same view is asked for twice; give each view once", parameter="view")
    return views


@fields_per_output(str, picture="{name}/{view}.png")
class Patterns:
    """Where a batch writes each picture: a pattern per output (a field per record of
    :data:`voxrender.outputs.output_kinds.OUTPUTS`, as :class:`~voxrender.outputs.picture_outputs.Outputs` has), with
    ``{name}``, ``{view}``, ``{method}`` and ``{index}``, relative to the batch's folder; ``None`` for an output not
    wanted.

    >>> Patterns(depth="{name}/{view}.npy").outputs("out", name="head", view="left").depth
    PosixPath('out/head/left.npy')
    """

    def outputs(self, out_dir, **fields):
        """The :class:`~voxrender.outputs.picture_outputs.Outputs` of one picture: each pattern filled in with
        ``fields``; an :class:`InputError` names the output whose pattern is not valid.
        """
        paths = {}
        for name, pattern in asdict(self).items():
            try:
                paths[name] = None if pattern is None else Path(out_dir) / pattern.format(**fields)
            except (KeyError, IndexError, ValueError) as exc:
                raise InputError(f"output pattern {pattern!r} is not valid: use {{name}}, {{view}}, {{method}}, "
                                 f"{{index}} ({type(exc).__name__}: {exc})", parameter=name) from None
        return Outputs(**paths)


@dataclass
class Item:
    """One input of a batch: where it is, how to read, threshold and render it, which views, where they go."""

    input: str
    name: str
    read: ReadOptions = field(default_factory=ReadOptions)
    prepare: PrepOptions = field(default_factory=PrepOptions)
    options: RenderOptions = field(default_factory=RenderOptions)
    views: list = field(default_factory=lambda: parse_views())
    patterns: Patterns = field(default_factory=Patterns)
    per_label: bool = False
    manifest_outputs: tuple = ()      # the outputs whose pattern a manifest row gave: its errors name the row
    qc_sheet: bool = False            # also its QC sheet (voxrender.qc.qc.qc_sheet), with these slices
    slices: object = None
    dicom_study_from: str | None = None   # the DICOM series its DICOM pictures join (default: its input)
    reference: str | None = None      # a reference segmentation its labels are held to (agreement.csv)
    tolerance_mm: float = 2.0         # of the normalised surface Dice

    @property
    def method(self):
        """The name of the item's renderer."""
        return self.options.method

    def label_picture(self, picture_path, label):
        """Where the picture of one label goes, with ``per_label``: beside the view's picture, ``-label{N}``
        added to its name.
        """
        return picture_path.with_name(f"{picture_path.stem}-label{label}{picture_path.suffix}")

    def outputs(self, out_dir, view, index):
        """The :class:`~voxrender.outputs.picture_outputs.Outputs` of one view of the item, in ``out_dir``."""
        return self.patterns.outputs(out_dir, name=self.name, view=view.label, method=self.method, index=index)

    def output(self, out_dir, view, index):
        """Where the picture of one view of the item goes."""
        return self.outputs(out_dir, view, index).picture

    def sheet_path(self, out_dir):
        """Where its QC sheet goes: ``OUT/sheets/{name}.png``."""
        return Path(out_dir) / "sheets" / f"{self.name}.png"

    @property
    def makes_sheet(self):
        """Whether it gets a QC sheet: asked for, and its input holds grey values (an encoded object does not, and
        shows in the batch's contact sheet alone).
        """
        return self.qc_sheet and not is_segments_file(self.input)

    @property
    def needs_grey(self):
        """Whether its pictures draw grey values (projections), which the cache then keeps beside the object."""
        return self.options.drawn.grey_values

    def sheet_views(self):
        """The views its QC sheet shows: all of them, or four spread over a turntable's frames."""
        views = self.views if len(self.views) <= 6 else [self.views[k * len(self.views) // 4] for k in range(4)]
        return [(v.label, (v.alpha, v.beta, v.gamma)) for v in views]


def expand_inputs(patterns):
    """Paths and glob patterns to existing paths, in order, each once.

    >>> expand_inputs([])
    []
    """
    found = []
    for pattern in patterns:
        matches = sorted(glob.glob(str(pattern))) if glob.has_magic(str(pattern)) else [str(pattern)]
        if not matches:
            raise InputError(f"no input matches {pattern!r}")
        for match in matches:
            if match not in found:
                found.append(match)
    return found


def _unique_names(paths):
    """A short, distinct name per input: its folder or file name, numbered when two are the same.

    >>> _unique_names(["a/ct", "b/ct", "c/head.mha", "d/ct.nii.gz"])
    ['ct', 'ct-2', 'head', 'ct-3']
    """
    names, seen = [], {}
    for path in paths:
        base = Path(path).name
        if not Path(path).is_dir():
            for suffix in (".nii.gz", ".seg.nrrd", Path(path).suffix):
                if suffix and base.lower().endswith(suffix):
                    base = base[:-len(suffix)]
                    break
        base = base or "input"
        seen[base] = seen.get(base, 0) + 1
        names.append(base if seen[base] == 1 else f"{base}-{seen[base]}")
    return names


def _names(rows):
    """Each row's study name: its ``name`` column when given (the same CT once per model), else one made from its
    input (:func:`_unique_names`); a name is a file name of its own, and no two are the same.
    """
    given = [str(row.get("name") or "").strip() for row in rows]
    made = _unique_names([row["input"] for row in rows])
    names = [g or m for g, m in zip(given, made, strict=True)]
    for name, row in zip(given, rows, strict=True):
        if name and (name in (".", "..") or any(c in name for c in '/\\\0') or name.startswith(".")):
            raise InputError(f"{row['input']}: the name {name!r} is not a file name of its own; give one without "
                             "slashes that does not begin with a dot", parameter="manifest")
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError(f"two studies are named {twice[0]!r}; give each row of the manifest a name of its own "
                         "(its 'name' column)", parameter="manifest")
    return names


def read_manifest(path):
    """Rows of a manifest: CSV with a header, or TOML with ``[[input]]`` tables.

    Columns (all but ``input`` optional): ``input``, ``name`` (the study's name in file names and on the page;
    default: from its input), ``labels`` (a label map of the input: the picture shows its labels), ``threshold``
    (with ``labels``, it also selects the input's values), ``views`` (preset names and ``a,b,g`` triples separated
    by ``;``), ``method``, ``output`` (a pattern).  Relative inputs and label maps are taken from the manifest's folder.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"no such manifest: {path}")
    nul = path.read_bytes().find(b"\0")
    if nul >= 0:                                          # no path or value can hold one (csv reads it as text)
        raise InputError(f"manifest {path} holds a NUL byte (at byte {nul}); it is damaged or is not text")
    try:
        if path.suffix.lower() == ".toml":
            rows = tomllib.loads(path.read_text()).get("input", [])
        else:
            with open(path, newline="") as f:
                rows = list(csv.DictReader(f))
    except (tomllib.TOMLDecodeError, csv.Error, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read manifest {path}: {exc}") from None
    if not rows or any("input" not in row or not str(row["input"]).strip() for row in rows):
        raise InputError(f"manifest {path} needs an 'input' column (CSV header) or [[input]] tables (TOML), "
                         "with a path in every row")
    for row in rows:
        for column in ("input", "labels", "reference"):
            if str(row.get(column) or "").strip() and not Path(str(row[column]).strip()).is_absolute():
                row[column] = str(path.parent / str(row[column]).strip())
    return rows


def items_from(inputs, manifest_rows, read, prepare, options, views, patterns, per_label=False, qc_sheet=False,
               slices=None, dicom_study_from=None, reference=None, tolerance_mm=2.0):
    """The batch's items: one per input path, then one per manifest row (its columns override).

    A row's ``labels``, ``threshold``, ``views``, ``method`` and ``output`` (the picture's pattern) are text,
    parsed here.  A row's label map makes the object its labels (each in its colour); the threshold then
    applies only when the row or the command gives one.  With ``qc_sheet`` each item also gets its QC sheet, with
    ``slices`` (a :class:`~voxrender.qc.qc.SliceOptions`); ``dicom_study_from`` names the DICOM series that DICOM
    pictures join.  ``reference`` (or a row's ``reference`` column) is a segmentation each study's labels are held to,
    their normalised surface Dice at ``tolerance_mm``.
    """
    rows = [{"input": p} for p in inputs] + list(manifest_rows)
    if not rows:
        raise InputError("no inputs: give paths, globs or a manifest", parameter="inputs")
    names = _names(rows)
    items = []
    for row, name in zip(rows, names, strict=True):
        try:
            item_views = views
            if str(row.get("views") or "").strip():
                parts = [p.strip() for p in str(row["views"]).split(";") if p.strip()]
                item_views = parse_views([p for p in parts if "," not in p],
                                         [parse.vector(p, "views") for p in parts if "," in p])
            item_prepare = prepare
            if str(row.get("labels") or "").strip():
                chosen = prepare.labels.chosen if prepare.labels else None
                item_prepare = replace(prepare, labels=LabelSelection(chosen, True, Path(str(row["labels"]))))
            if str(row.get("threshold") or "").strip():        # on top of the row's labels, when it gives both
                item_prepare = replace(item_prepare, threshold=parse.threshold(str(row["threshold"])))
            item_options = options
            if str(row.get("method") or "").strip():
                item_options = replace(options, method=str(row["method"]).strip())
        except InputError as exc:
            raise InputError(f"{row['input']}: {exc}") from None
        given = str(row.get("output") or "").strip()
        item_patterns = replace(patterns, picture=given or patterns.picture)
        if item_prepare.labels is not None:                # the pieces and the edge of each label, for the flags
            item_prepare = replace(item_prepare, measure_labels=True)
        item_reference = str(row.get("reference") or "").strip() or (None if reference is None else str(reference))
        if item_reference and (item_prepare.labels is None or item_prepare.labels.source is None):
            raise InputError(f"{row['input']}: a reference is held against the study's labels; give its labels "
                             "too (a manifest's labels column)", parameter="reference")
        items.append(Item(str(row["input"]), name, read, item_prepare, item_options, item_views, item_patterns,
                          per_label, ("picture",) if given else (), qc_sheet, slices,
                          None if dicom_study_from is None else str(dicom_study_from), item_reference,
                          tolerance_mm))
    if patterns.dicom is not None:
        _check_dicom_sources(items)
    return items


def _check_dicom_sources(items):
    """Every item whose pictures are written as DICOM has a study to join: its input is DICOM, or the batch names
    one; refused before anything is made.
    """
    from ..io import detect_format

    for item in items:
        source = item.dicom_study_from or item.input
        try:
            is_dicom = Path(source).exists() and detect_format(source) == "dicom"
        except InputError:
            is_dicom = False
        if not is_dicom:
            raise InputError(f"{source} is not DICOM, so its pictures have no study to join; name the DICOM series "
                             "it was made from, or write no DICOM pictures", parameter="dicom_study_from")


def _content_files(path):
    """The files an input is made of: a folder's (a series, a mask folder), or the file and the data files a
    detached header names.
    """
    if path.is_dir():
        return sorted(p for p in path.rglob("*") if p.is_file())
    files = [path]
    if path.suffix.lower() == ".mhd":
        files += [p for p in path.parent.iterdir() if p.suffix.lower() in (".raw", ".zraw")]
    if path.suffix.lower() == ".nhdr":                      # a detached NRRD header names its data file
        files += [p for p in path.parent.iterdir() if p.name.startswith(path.stem + ".") and p != path]
    return files


def cache_key(path, read, prepare):
    """Hex digest of the input's content (every file's name and bytes) and the options that shape the object."""
    digest = hashlib.sha256()
    path = Path(path)
    if not path.exists():            # a manifest's row may name anything
        raise InputError(f"no such file or folder: {path}", parameter="inputs")
    files = _content_files(path)
    if prepare.labels is not None and prepare.labels.source is not None:      # the paired label map shapes it too
        if not Path(prepare.labels.source).exists():
            raise InputError(f"no such file or folder: {prepare.labels.source}", parameter="labels_from")
        files += _content_files(Path(prepare.labels.source))
    for file in files:
        digest.update(str(file.relative_to(path) if file.is_relative_to(path) else file.name).encode())
        _add_bytes(digest, file)
    digest.update(json.dumps([asdict(read), asdict(prepare), __version__], sort_keys=True, default=_stable).encode())
    return digest.hexdigest()[:32]


def _stable(value):
    """A text for ``value`` that is the same in every process (a function's name, not its address)."""
    return getattr(value, "__qualname__", None) or str(value)


# ------------------------------------------------------------------ the two kinds of task (run in workers)

def _encode_task(item, cache_dir, out_dir=None):
    """Phase 1: the cached ``.vxs`` of ``item`` (made now if absent), with its grey values when its pictures are
    projections, and its QC sheet when wanted and not there yet; with a reference, the agreement of its labels
    (``report["agreement"]``, :data:`voxrender.review.agreement.COLUMNS`); returns a small report dict.
    """
    report = _encode_object(item, cache_dir, out_dir)
    if item.reference is None or "error" in report:
        return report
    from ..review.agreement import COLUMNS, Comparison

    try:
        rows = Comparison(item.input, item.prepare.labels.source, item.reference, item.read).metrics(item.tolerance_mm)
    except InputError as exc:
        return {"input": item.input, "error": str(exc)}
    except Exception as exc:  # a bug must not stop the other inputs; it is reported in the summary
        return {"input": item.input, "error": f"internal error: {type(exc).__name__}: {exc}",
                "traceback": traceback.format_exc()}
    return {**report, "agreement": [{k: row[k] for k in COLUMNS} for row in rows]}


def _encode_object(item, cache_dir, out_dir=None):
    """:func:`_encode_task`'s object, grey values and sheet."""
    started = time.perf_counter()
    sheet = item.sheet_path(out_dir) if item.makes_sheet and out_dir is not None else None
    try:
        make_sheet = sheet is not None and _png_size(sheet) is None
        if is_segments_file(item.input):
            if item.needs_grey:
                raise InputError(f"{item.input} is an encoded object, which keeps no grey values to project; give "
                                 "the slice stack it was made from")
            return {"input": item.input, "segments": item.input, "seconds": {"load": 0.0, "prepare": 0.0}}
        with_octree = method_record(item.method).octree          # kept in the cache: built once, not per view
        key = cache_key(item.input, item.read, item.prepare)
        target = Path(cache_dir) / f"{key}.{'vxo' if with_octree else 'vxs'}"
        report = {"input": item.input, "segments": str(target), "seconds": {"load": 0.0, "prepare": 0.0}}
        grey_kept = not item.needs_grey or all(p.is_file() for p in _study_files(target))
        if _is_intact(target) and grey_kept and not make_sheet:      # a damaged or tampered entry is made again
            return {**report, "cached": True, "key_seconds": time.perf_counter() - started}
        study = None
        if item.needs_grey or make_sheet:
            from ..qc.study import load_study

            study = load_study(item.input, item.read, item.prepare)
            loaded = study.encoded
        else:
            loaded = load_segments(item.input, item.read, item.prepare)
        try:
            if item.needs_grey:                      # before the object: an intact entry has its grey values
                study.save(target.with_suffix(""))
            loaded.save(target, octree=with_octree)
            output.write_json(_record_of(target), _checksum(target))
            if make_sheet:
                from ..qc.qc import qc_sheet

                sheet.parent.mkdir(parents=True, exist_ok=True)
                output.write_png(sheet, qc_sheet(study, item.options, item.sheet_views(), item.slices,
                                                 title=f"{item.name}: {item.input}"))
        except OSError as exc:          # the disk refused, not the input nor voxrender
            return _write_failure({"input": item.input}, exc)
        return {**report, "seconds": loaded.seconds, "cached": False}
    except InputError as exc:
        return {"input": item.input, "error": str(exc)}
    except Exception as exc:  # a bug must not stop the other inputs; it is reported in the summary
        return {"input": item.input, "error": f"internal error: {type(exc).__name__}: {exc}",
                "traceback": traceback.format_exc()}


def _study_files(target):
    """The grey values and the record a cache entry keeps beside the object when its pictures draw them (the labels
    and codes too, when it has them).
    """
    from ..qc.study import saved_files

    grey, _, record, _ = saved_files(target.with_suffix(""))
    return [grey, record]


def _record_of(entry):
    """The record beside a cache entry: its size and checksum, written once the entry is whole."""
    return entry.with_name(entry.name + ".json")


def _add_bytes(digest, path):
    """Feed the bytes of the file at ``path`` to ``digest``, a block at a time."""
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)


def _checksum(path):
    """The size and SHA-256 of the file at ``path``."""
    digest = hashlib.sha256()
    _add_bytes(digest, path)
    return {"bytes": Path(path).stat().st_size, "sha256": digest.hexdigest()}


def _is_intact(entry):
    """Whether the cache entry exists and its bytes are those its record says were written."""
    try:
        record = json.loads(_record_of(entry).read_text())
        return record["bytes"] == entry.stat().st_size and record == _checksum(entry)
    except (OSError, ValueError, KeyError, TypeError):   # no entry, no record, or a damaged record
        return False


_NO_SPACE = (errno.ENOSPC, errno.EDQUOT)


def _write_failure(row, exc):
    """``row`` failed by a write the system refused (``exc``): its error says which file and why; a full disk is
    marked (``no_space``) for :func:`run_batch` to report.
    """
    where = f"cannot write {exc.filename}: " if exc.filename else "cannot write: "
    return {**row, "error": where + (exc.strerror or str(exc)), "no_space": exc.errno in _NO_SPACE}


@functools.lru_cache(maxsize=2)
def _encoded(path, stamp):
    """The object at ``path`` (``stamp``: its size and time, so a remade file is read again), kept between the
    tasks of a worker with its octree (read from a ``.vxo``, or built once per object, not once per picture).
    """
    return load_segments(path)


@functools.lru_cache(maxsize=2)
def _study(path, stamp):
    """The grey values kept beside the object at ``path`` (memory-mapped), with the object, kept as :func:`_encoded`."""
    from ..qc.study import load_saved

    return load_saved(Path(path).with_suffix(""), _encoded(path, stamp))


@functools.lru_cache(maxsize=8)
def _dicom_study(source, series):
    """The DICOM series a picture joins (:func:`voxrender.outputs.secondary_capture.dicom_study`), read once per
    worker.
    """
    from ..outputs.secondary_capture import dicom_study

    return dicom_study(source, series)


def _summary_row(item, view, picture_path, status, error="", **numbers):
    """The summary row of one picture (see ``SUMMARY_COLUMNS``): which input, view and method, where it went, its
    ``status`` (``"ok"``, ``"done earlier"`` or ``"failed"``) and ``error``, and, once made, its ``numbers``.
    """
    return {"input": item.input, "name": item.name, "view": view.label, "alpha": view.alpha, "beta": view.beta,
            "gamma": view.gamma, "method": item.method, "output": str(picture_path), "status": status,
            "error": error, **numbers}


def _render_task(item, view, index, segments_path, out_dir, encode_seconds):
    """Phase 2: render one view of one input and write its outputs; returns its summary row."""
    outputs = item.outputs(out_dir, view, index)
    try:
        status = Path(segments_path).stat()
        stamp = (status.st_size, status.st_mtime_ns)
        encoded = _encoded(str(segments_path), stamp)
        study = _study(str(segments_path), stamp) if item.needs_grey else None
        result = picture(encoded.segments, framed(item, view, encoded.segments), item.options,
                         tree=octree_for(item.method, encoded), study=study)
        told = about(encoded.segments)
        if outputs.dicom is not None:
            told.update(_dicom_fields(item, out_dir, index))
        try:
            for path in outputs.wanted().values():
                path.parent.mkdir(parents=True, exist_ok=True)
            seconds = write_outputs(result, outputs, told)   # this picture's stages
            if item.per_label and result.labels is not None:
                _write_label_pictures(item, result, encoded.segments, outputs.picture)
        except BaseException as exc:    # a view's outputs are all there or none: a re-run makes them all again
            for path in [*outputs.wanted().values(),
                         *(item.label_picture(outputs.picture, label) for label in result.label_table or ())]:
                path.unlink(missing_ok=True)
            if isinstance(exc, OSError):   # the disk refused, not the input nor voxrender
                return _write_failure(_summary_row(item, view, outputs.picture, "failed"), exc)
            raise
    except InputError as exc:
        return _summary_row(item, view, outputs.picture, "failed", str(exc))
    except Exception as exc:  # reported in the summary; the batch goes on
        return _summary_row(item, view, outputs.picture, "failed", f"internal error: {type(exc).__name__}: {exc}")
    return _summary_row(item, view, outputs.picture, "ok", stats=json.dumps(result.image.stats, default=float),
                       labels=len(result.image.stats.get("label_pixels", {})) if result.labels is not None else "",
                       label_volumes=json.dumps([{k: row[k] for k in ("label", "name", "colour", "voxels", "ml",
                                                                      "shown", "components", "border") if k in row}
                                                 for row in result.label_rows]) if result.label_rows else "",
                       overlaps=json.dumps(encoded.segments.meta.get("overlaps") or []),
                       load_s=encode_seconds.get("load", 0.0), prepare_s=encode_seconds.get("prepare", 0.0),
                       **{f"{stage}_s": value for stage, value in seconds.items()})   # load and prepare: the input's


def _dicom_fields(item, out_dir, index):
    """What a DICOM picture of ``item`` needs: its source study, and the series all its views share (a UID made of
    the source series, the batch's folder and the item's name, so a re-run keeps them in it) and its number there.
    """
    from pydicom.uid import generate_uid

    study = _dicom_study(item.dicom_study_from or item.input, item.read.series)
    series = generate_uid(entropy_srcs=[study.series_uid, os.path.realpath(out_dir), item.name])
    return {"dicom_study": study, "dicom_series_uid": series, "dicom_instance_number": index + 1}


def _write_label_pictures(item, result, segments, picture_path):
    """With ``per_label``: each label the picture shows, alone, in its colour, from the same view and frame."""
    options = replace(item.options, legend=False)
    for label, (_, colour) in result.label_table.items():
        if str(label) in result.image.stats["label_pixels"]:
            alone = picture(segments.only(label), result.image.view,
                            replace(options, colour=tuple(c / 255 for c in colour)))
            output.write_png(item.label_picture(picture_path, label), alone.rgb)


def framed(item, view, encoded):
    """The view of ``item`` at ``view``'s angles.  Framing the object (no scale given) over several views, one
    scale fits them all, so the size does not jump between the frames of a turntable; each view is centred.
    """
    chosen = item.options.view(view.alpha, view.beta, view.gamma)
    if item.options.scale is not None or item.options.fit != "object" or len(item.views) < 2:
        return chosen
    others = [item.options.view(v.alpha, v.beta, v.gamma) for v in item.views]
    return frame_together([chosen, *others], encoded.shape, framing_box(encoded, item.options.clip))[0]


def _is_done(outputs, size):
    """Whether a view's :class:`~voxrender.outputs.picture_outputs.Outputs` are finished: its picture a readable
    PNG of the expected ``size = (H, W)``, and each other output there (each is written whole or not at all).
    """
    return _png_size(outputs.picture) == tuple(size) and all(path.is_file() for path in outputs.wanted().values())


def _png_size(path):
    """``(H, W)`` of the PNG at ``path`` once it decodes whole; ``None`` when it is missing, truncated or no PNG
    (then it is made again).
    """
    import imageio.v3 as iio

    try:
        return tuple(iio.imread(path, extension=".png").shape[:2])          # decodes it all
    except Exception:  # missing, truncated or not a PNG
        return None



# ------------------------------------------------------------------ the batch

def run_batch(items, out_dir, jobs=None, scheduler=None, cache_dir=None, animations=(), fps=12, progress=None,
              make_sheet=False, min_dice=0.8, min_nsd=None, verdicts=None):
    """Run a batch; return the summary rows (also written to ``out_dir/summary.csv``).

    Parameters
    ----------
    items : list of Item
    out_dir : path
        Pictures go here (named by each item's pattern), with ``summary.csv``.
    jobs : int
        Worker processes (default: the machine's cores); with ``scheduler``, local Dask workers.
    scheduler : str, optional
        ``"local"`` for a local Dask cluster, or a scheduler address.
    cache_dir : path, optional
        Where encoded objects are kept (default ``out_dir/.voxrender-cache``).
    animations : iterable of str
        ``"gif"`` and/or ``"mp4"``: every item's views as one animation ``out_dir/{name}.gif``.
    progress : callable, optional
        ``progress(length)`` returning an object with ``update(n)`` and ``close()`` (a progress bar).
    make_sheet : bool
        Also lay every item's pictures out in ``out_dir/sheet.png``: a row per input, a column per view.
    min_dice, min_nsd : float, optional
        With references: the limits under which a label's agreement is flagged (``flags.csv``).
    verdicts : dict, optional
        ``{study: (verdict, note)}`` of an earlier review (:func:`voxrender.qc.index_page.read_verdicts`), put into
        the index page.

    Besides the pictures it writes ``summary.csv`` and ``index.html`` (thumbnails linked to the pictures, with
    each row's numbers and errors).

    Raises
    ------
    InputError
        Before anything is rendered: an output outside ``out_dir`` or over an input, a cache inside an input, a
        pattern that is not valid, a folder that cannot be written, or one that another batch is using.  After:
        the disk was full (the message says how many pictures are there, and whether the summary fitted).
    """
    out_dir = Path(out_dir)
    _check_patterns(items, out_dir)
    held = cache_dir is not None and _input_holding(cache_dir, items)
    if held:
        raise InputError(f"the cache {cache_dir} would be written inside the input {held}; give a folder apart "
                         "from the inputs")
    _make_folder(out_dir)
    check_folder_writable(out_dir)
    with _folder_lock(out_dir):
        own_cache = cache_dir is None           # another batch may be writing in a cache it was given
        cache_dir = Path(cache_dir or out_dir / ".voxrender-cache")
        _make_folder(cache_dir)
        for folder in _folders_written(items, out_dir) | ({cache_dir} if own_cache else set()):
            remove_partials(folder)      # what a batch killed while writing left
        ordered, study_errors, agreements = _render_all(items, out_dir, jobs, scheduler, cache_dir, progress)
        no_space = any([row.pop("no_space", False) for row in ordered])     # every row's mark popped
        unwritten = _write_reports(out_dir, ordered, items, study_errors, agreements, min_dice, min_nsd, verdicts)
        if no_space or unwritten:
            there = sum(row["status"] in ("ok", "done earlier") for row in ordered)
            listed = ", ".join(unwritten[:-1]) + " and " + unwritten[-1] if len(unwritten) > 1 else "".join(unwritten)
            said = f"{listed} not written" if unwritten else f"{out_dir / 'summary.csv'} says which"
            raise InputError(f"no space left on device in {out_dir}: {there} of {len(ordered)} pictures are there, "
                             f"the others were not made; {said}")
        for kind in animations:
            for item in items:
                _animate(item, out_dir, kind, fps, ordered)
        if make_sheet:
            _write_sheet(out_dir / "sheet.png", items, ordered)
    return ordered


def _folders_written(items, out_dir):
    """The folders the batch writes in: its own, and each one its outputs go to."""
    return {out_dir} | {path.parent for item in items for index, view in enumerate(item.views)
                        for path in item.outputs(out_dir, view, index).wanted().values()}


def _write_reports(out_dir, rows, items, study_errors, agreements=None, min_dice=0.8, min_nsd=None, verdicts=None):
    """Write ``summary.csv``, ``flags.csv``, ``agreement.csv`` (with references) and ``index.html``; the names of
    those a full disk left unwritten (and removed, as the ones of an earlier run would not say what is there now).
    """
    from ..qc.index_page import write_index
    from ..review import agreement, flags

    agreements = agreements or {}
    found = flags.cohort_flags(_label_rows(items, rows, agreements), min_dice=min_dice, min_nsd=min_nsd)
    studies = _study_rows(items, rows, study_errors, out_dir, found)
    for study in studies:                              # an earlier review's verdicts (voxrender batch --verdicts)
        study.verdict, study.note = (verdicts or {}).get(study.name, ("", ""))
    reports = [(out_dir / "summary.csv", lambda path: _write_summary(path, rows)),
               (out_dir / "flags.csv", lambda path: output.write_csv(path, flags.COLUMNS, found))]
    if agreements:
        reports.append((out_dir / "agreement.csv", lambda path: output.write_csv(
            path, ("study", *agreement.COLUMNS),
            [{**row, "study": item.name} for item in items for row in agreements.get(item.name, [])])))
    reports.append((out_dir / "index.html", lambda path: write_index(path, studies)))
    unwritten = []
    for path, write in reports:
        try:
            write(path)
        except OSError as exc:
            if exc.errno not in _NO_SPACE:
                raise
            path.unlink(missing_ok=True)
            unwritten.append(path.name)
    return unwritten


def _label_rows(items, rows, agreements):
    """Every study's labels with their own volumes (the summary's), and with a reference their Dice, NSD and
    pieces, matched by name: what :func:`voxrender.review.flags.cohort_flags` takes.  The pieces and the border are
    measured with the labels (``PrepOptions.measure_labels``), the Dice and NSD with the reference.
    """
    from .._shared.label_sets import label_key

    first = {}
    for row in rows:
        if row.get("label_volumes") and row["name"] not in first:
            first[row["name"]] = json.loads(row["label_volumes"])
    found = []
    for item in items:
        scores = {label_key(r["name"], r["label"]): r for r in agreements.get(item.name, [])}
        for label in first.get(item.name, []):
            score = scores.pop(label_key(label["name"], label["label"]), {})
            found.append({"study": item.name, **label, "dice": score.get("dice"), "nsd": score.get("nsd"),
                          "components": label.get("components", score.get("components"))})
        found += [{"study": item.name, "label": None, "name": r["name"], "voxels": None, "ml": None,
                   "dice": r["dice"], "nsd": r["nsd"]} for r in scores.values()]      # the reference's alone
    return found


def _make_folder(folder):
    """Make ``folder`` (and its parents) unless it exists; a folder the system refuses is bad input."""
    try:
        Path(folder).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot make the folder {folder}: {exc.strerror}") from None


LOCK_NAME = ".voxrender-lock"


@contextlib.contextmanager
def _folder_lock(out_dir):
    """Hold ``out_dir`` for this batch: a second batch on the same folder is refused while this one runs.

    The lock is a POSIX record lock on ``out_dir/.voxrender-lock``, which holds the holder's pid for the
    message.  The system lets go of it when its process ends, however it ends, so a killed batch's lock file
    does not block the next run; it is this process's alone, not its workers'.  The file stays: removing it
    would let two batches lock two different files.
    """
    import fcntl

    fd = os.open(Path(out_dir) / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        try:
            fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno not in (errno.EACCES, errno.EAGAIN):
                raise
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
            raise InputError(f"{out_dir} is in use by another batch (process {holder}); wait for it to end, or "
                             "give another folder") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield
    finally:
        os.close(fd)


def _render_all(items, out_dir, jobs, scheduler, cache_dir, progress):
    """The two phases of the batch (see the module's docstring): the summary rows, in the items' order, the errors
    of the items whose encoding failed (their QC sheet too), by name, and the agreement rows of those with a
    reference, by name.
    """
    jobs = jobs or os.cpu_count() or 1
    rows = {}
    todo = {}
    study_errors, agreements = {}, {}
    earlier = _earlier_rows(out_dir)
    for item in items:
        for index, view in enumerate(item.views):
            outputs = item.outputs(out_dir, view, index)
            if _is_done(outputs, item.options.size):
                kept = earlier.get(str(outputs.picture), {})
                rows[(item.name, view.label)] = _summary_row(item, view, outputs.picture, "done earlier",
                                                             **{k: kept[k] for k in LABEL_COLUMNS if kept.get(k)})
            else:
                todo.setdefault(id(item), (item, []))[1].append((index, view))
        if item.makes_sheet and _png_size(item.sheet_path(out_dir)) is None:      # its sheet is made by its encode task
            todo.setdefault(id(item), (item, []))
        if item.reference is not None:                  # its agreement is measured by its encode task, every run
            todo.setdefault(id(item), (item, []))
    bar = progress(len(todo) + sum(len(v) for _, v in todo.values())) if progress else None
    pool = executor(jobs, scheduler)
    try:
        encodes = {pool.submit(_encode_task, item, str(cache_dir), str(out_dir)): (item, views)
                   for item, views in todo.values()}
        renders = {}
        for future in pool.as_completed(list(encodes)):
            item, views = encodes[future]
            try:
                report = future.result()
            except pool.died as died:
                report = {"input": item.input, "error": why_died(died)}
            if bar:
                bar.update(1)
            if report.get("agreement") is not None:
                agreements[item.name] = report["agreement"]
            if "error" in report:
                study_errors[item.name] = report["error"]
                for index, view in views:
                    rows[(item.name, view.label)] = _summary_row(item, view, item.output(out_dir, view, index),
                                                                "failed", report["error"],
                                                                no_space=report.get("no_space", False))
                if bar:
                    bar.update(len(views))
                continue
            for index, view in views:
                renders[pool.submit(_render_task, item, view, index, report["segments"], str(out_dir),
                                    report["seconds"])] = (item, view, index)
        for future in pool.as_completed(list(renders)):
            item, view, index = renders[future]
            try:
                rows[(item.name, view.label)] = future.result()
            except pool.died as died:
                rows[(item.name, view.label)] = _summary_row(item, view, item.output(out_dir, view, index),
                                                             "failed", why_died(died))
            if bar:
                bar.update(1)
    finally:
        pool.close()
        if bar:
            bar.close()
    return [rows[(item.name, view.label)] for item in items for view in item.views], study_errors, agreements


def _earlier_rows(out_dir):
    """The rows of the summary an earlier run left, by picture: a picture done earlier keeps its labels, so the
    summary and the index page of a re-run say what a fresh run would.
    """
    try:
        with open(Path(out_dir) / "summary.csv", newline="") as f:
            rows = [{k: from_spreadsheet_cell(v) for k, v in row.items()} for row in csv.DictReader(f)]
            return {row["output"]: row for row in rows if row.get("output")}
    except (OSError, csv.Error, UnicodeDecodeError):
        return {}


def _check_patterns(items, out_dir):
    """Every output of every picture gets a distinct path inside ``out_dir``, not an input's, with the right ending,
    and can be given (normals need gradient shading), before anything is made.

    Inside means once ``..`` and symbolic links are resolved: an absolute pattern, a ``..`` or a link inside the
    folder that points out of it is refused.  An error about a pattern a manifest row gave names that row, not a
    parameter of the command.
    """
    folder = os.path.realpath(out_dir)
    seen = {}
    for item in items:
        for index, view in enumerate(item.views):
            try:
                outputs = item.outputs(out_dir, view, index)
            except InputError as exc:
                if exc.parameter not in item.manifest_outputs:
                    raise
                raise InputError(f"{item.input}: the manifest's {exc.message}") from None
            outputs.check(item.options)
            for kind, path in outputs.wanted().items():
                pattern, ending = getattr(item.patterns, kind), OUTPUTS[kind].suffix
                given, parameter = ((f"{item.input}: the manifest's output pattern {pattern!r}", None)
                                    if kind in item.manifest_outputs else (f"output pattern {pattern!r}", kind))
                resolved = os.path.realpath(path)
                if os.path.commonpath([folder, resolved]) != folder:
                    through = "" if os.path.abspath(path) == resolved else f" (a symbolic link leads to {resolved})"
                    raise InputError(f"{given} puts {path} outside the batch's folder {out_dir}{through}; give a "
                                     "pattern relative to the folder that stays inside it", parameter=parameter)
                source = _input_holding(resolved, items)
                if source:
                    raise InputError(f"{given} would write {path} over or inside the input {source}; choose names "
                                     "apart from the inputs", parameter=parameter)
                if path.suffix.lower() != ending:
                    raise InputError(f"{given} must end in {ending}", parameter=parameter)
                if path in seen:
                    raise InputError(f"{given} gives {path} twice; add {{name}} or {{view}}", parameter=parameter)
                seen[path] = True


def _input_holding(path, items):
    """The input (or label map) of ``items`` that ``path`` is, or is inside; ``None`` when it is none of them."""
    resolved = os.path.realpath(path)
    for item in items:
        labels = item.prepare.labels
        for source in [item.input] + ([labels.source] if labels is not None and labels.source is not None else []):
            real = os.path.realpath(source)
            if resolved == real or resolved.startswith(real + os.sep):
                return source
    return None


def _animate(item, out_dir, kind, fps, rows):
    """Every view of ``item`` as one animation (only when all its pictures exist)."""
    import imageio.v3 as iio

    frames = [r["output"] for r in rows if r["name"] == item.name and r["status"] in ("ok", "done earlier")]
    if len(frames) != len(item.views) or len(frames) < 2:
        return
    target = Path(out_dir) / f"{item.name}.{kind}"
    pictures = [iio.imread(f) for f in frames]
    widest = max(p.shape[1] for p in pictures)         # a legend beside a frame widens it by the labels it shows
    pictures = np.stack([np.pad(p, [(0, 0), (0, widest - p.shape[1])] + [(0, 0)] * (p.ndim - 2), mode="edge")
                         for p in pictures])
    try:
        with atomic_output(target) as tmp:
            if kind == "gif":
                iio.imwrite(tmp, pictures, extension=".gif", duration=1000 / fps, loop=0)
            else:
                iio.imwrite(tmp, pictures, extension=".mp4", fps=fps, codec="libx264", macro_block_size=1)
    except (ImportError, OSError, RuntimeError, ValueError) as exc:
        needs = " (MP4 needs pip install 'voxrender[video]')" if kind == "mp4" else ""
        raise InputError(f"cannot write {target}: {exc}{needs}") from None


def _study_rows(items, rows, study_errors, out_dir, flags=()):
    """The index page's row of each item (:class:`voxrender.qc.index_page.StudyRow`): its sheet, its views (a turntable
    when they are one), its labels and overlaps, its flags (:func:`voxrender.review.flags.cohort_flags`) and its
    error, with paths relative to ``out_dir``.
    """
    from ..qc.index_page import StudyRow

    def relative(path):
        path = Path(path)
        return str(path.relative_to(out_dir)) if path.is_relative_to(out_dir) else str(path)

    from ..review.flags import in_words, severity

    by_name, flagged = {}, {}
    for row in rows:
        by_name.setdefault(row["name"], []).append(row)
    for flag in flags:                                   # grouped once: a cohort has many studies and flags
        flagged.setdefault(flag["study"], []).append(flag)
    studies = []
    for item in items:
        own = by_name.get(item.name, [])
        made = [row for row in own if row["status"] in ("ok", "done earlier")]
        error = study_errors.get(item.name) or next((row["error"] for row in own if row["status"] == "failed"), "")
        pictures = [(row["view"], relative(row["output"])) for row in made]
        turning = len(made) > 1 and len(made) == len(own) and all(row["view"].startswith("turn") for row in own)
        labels = next((json.loads(row["label_volumes"]) for row in own if row.get("label_volumes")), [])
        sheet = item.sheet_path(out_dir) if item.makes_sheet else None
        seconds = [row["total_s"] for row in made if isinstance(row.get("total_s"), float)]
        studies.append(StudyRow(item.name, item.input, error, relative(sheet) if sheet and sheet.is_file() else None,
                                [] if turning else pictures, [path for _, path in pictures] if turning else [],
                                labels, next((json.loads(row["overlaps"]) for row in own if row.get("overlaps")), []),
                                sum(seconds) if seconds else None,
                                [in_words(f) for f in flagged.get(item.name, [])],
                                severity(flagged[item.name]) if item.name in flagged else ()))
    return studies


def _write_sheet(path, items, rows):
    """Every item's pictures in one sheet: a row per input, a column per view (missing pictures left black)."""
    import imageio.v3 as iio

    from ..qc.sheet import sheet

    by_key = {(row["name"], row["view"]): row for row in rows}
    pictures, captions = [], []
    for item in items:
        row_pictures, row_captions = [], []
        for view in item.views:
            row = by_key[(item.name, view.label)]
            if row["status"] in ("ok", "done earlier"):
                row_pictures.append(iio.imread(row["output"]))
            else:
                row_pictures.append(np.zeros((*item.options.size, 3), np.uint8))
            row_captions.append(f"{item.name}, {view.label}")
        pictures.append(row_pictures)
        captions.append(row_captions)
    output.write_png(path, sheet(pictures, captions))


def _write_summary(path, rows):
    with atomic_output(path) as tmp, open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, SUMMARY_COLUMNS, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: spreadsheet_cell(f"{v:.4f}" if isinstance(v, float) else v) for k, v in row.items()})
