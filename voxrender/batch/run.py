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
import json
import os
from pathlib import Path

import numpy as np

from .._shared.executors import executor, why_died
from .._shared.files import atomic_output, check_folder_writable, remove_partials
from .._shared.text import from_spreadsheet_cell, spreadsheet_cell
from ..errors import InputError
from ..outputs import output
from ..outputs.output_kinds import OUTPUTS
from .tasks import (
    LABEL_COLUMNS,
    NO_SPACE,
    SUMMARY_COLUMNS,
    encode_task,
    is_done,
    png_size,
    render_task,
    summary_row,
)

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
            if exc.errno not in NO_SPACE:
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
            if is_done(outputs, item.options.size):
                kept = earlier.get(str(outputs.picture), {})
                rows[(item.name, view.label)] = summary_row(item, view, outputs.picture, "done earlier",
                                                             **{k: kept[k] for k in LABEL_COLUMNS if kept.get(k)})
            else:
                todo.setdefault(id(item), (item, []))[1].append((index, view))
        if item.makes_sheet and png_size(item.sheet_path(out_dir)) is None:      # its sheet is made by its encode task
            todo.setdefault(id(item), (item, []))
        if item.reference is not None:                  # its agreement is measured by its encode task, every run
            todo.setdefault(id(item), (item, []))
    bar = progress(len(todo) + sum(len(v) for _, v in todo.values())) if progress else None
    pool = executor(jobs, scheduler)
    try:
        encodes = {pool.submit(encode_task, item, str(cache_dir), str(out_dir)): (item, views)
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
                    rows[(item.name, view.label)] = summary_row(item, view, item.output(out_dir, view, index),
                                                                "failed", report["error"],
                                                                no_space=report.get("no_space", False))
                if bar:
                    bar.update(len(views))
                continue
            for index, view in views:
                renders[pool.submit(render_task, item, view, index, report["segments"], str(out_dir),
                                    report["seconds"])] = (item, view, index)
        for future in pool.as_completed(list(renders)):
            item, view, index = renders[future]
            try:
                rows[(item.name, view.label)] = future.result()
            except pool.died as died:
                rows[(item.name, view.label)] = summary_row(item, view, item.output(out_dir, view, index),
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
