"""The two kinds of task a batch runs in its workers: encoding an input once (into the cache) and rendering one view
of it; and the summary row each picture gets.
"""

from __future__ import annotations

import errno
import functools
import json
import os
import time
import traceback
from dataclasses import replace
from pathlib import Path

from .._render import framing_box, method_record, octree_for
from ..errors import InputError
from ..object.pipeline import is_segments_file, load_segments
from ..outputs import about, output, write_outputs
from ..pictures import level_for, picture
from ..space.view import frame_together
from .cache import cache_key, checksum, is_intact, load_encoded, load_study_files, record_of, study_files

SUMMARY_COLUMNS = ["input", "name", "view", "alpha", "beta", "gamma", "method", "output", "status", "error",
                   "labels", "label_volumes", "load_s", "prepare_s", "render_s", "shade_s", "write_s", "total_s",
                   "stats", "overlaps"]
LABEL_COLUMNS = ("labels", "label_volumes", "overlaps")    # what a picture done earlier keeps


def encode_task(item, cache_dir, out_dir=None):
    """Phase 1: the cached ``.vxs`` of ``item`` (made now if absent), with its grey values when its pictures are
    projections, and its QC sheet when wanted and not there yet; with a reference, the agreement of its labels
    (``report["agreement"]``, :data:`voxrender.review.agreement.COLUMNS`); returns a small report dict.

    A study encoded now with a reference is read and paired with its labels once, for both
    (:meth:`voxrender.review.agreement.Comparison.of_study`); one already in the cache is read for its agreement alone.
    """
    report, study = _encode_object(item, cache_dir, out_dir)
    if item.reference is None or "error" in report:
        return report
    from ..review.agreement import COLUMNS, Comparison

    try:
        comparison = Comparison.of_study(study, item.reference, item.read) if study is not None else \
            Comparison(item.input, item.prepare.labels.source, item.reference, item.read)
        rows = comparison.metrics(item.tolerance_mm)
    except InputError as exc:
        return {"input": item.input, "error": str(exc)}
    except Exception as exc:  # a bug must not stop the other inputs; it is reported in the summary
        return {"input": item.input, "error": f"internal error: {type(exc).__name__}: {exc}",
                "traceback": traceback.format_exc()}
    return {**report, "agreement": [{k: row[k] for k in COLUMNS} for row in rows]}


def _encode_object(item, cache_dir, out_dir=None):
    """:func:`encode_task`'s object, grey values and sheet: its report, and the study when one was read."""
    started = time.perf_counter()
    sheet = item.sheet_path(out_dir) if item.makes_sheet and out_dir is not None else None
    try:
        make_sheet = sheet is not None and png_size(sheet) is None
        if is_segments_file(item.input):
            if item.needs_grey:
                raise InputError(f"{item.input} is an encoded object, which keeps no grey values to project; give "
                                 "the slice stack it was made from")
            return {"input": item.input, "segments": item.input, "seconds": {"load": 0.0, "prepare": 0.0}}, None
        with_octree = method_record(item.method).octree          # kept in the cache: built once, not per view
        key = cache_key(item.input, item.read, item.prepare)
        target = Path(cache_dir) / f"{key}.{'vxo' if with_octree else 'vxs'}"
        report = {"input": item.input, "segments": str(target), "seconds": {"load": 0.0, "prepare": 0.0}}
        grey_kept = not item.needs_grey or all(p.is_file() for p in study_files(target))
        if is_intact(target) and grey_kept and not make_sheet:      # a damaged or tampered entry is made again
            return {**report, "cached": True, "key_seconds": time.perf_counter() - started}, None
        study = None
        # a study holds the labels paired with the image, which the agreement reuses (a study is never binned)
        if item.needs_grey or make_sheet or (item.reference is not None and item.prepare.bin == 1):
            from ..qc.study import load_study

            study = load_study(item.input, item.read, item.prepare)
            loaded = study.encoded
        else:
            loaded = load_segments(item.input, item.read, item.prepare)
        try:
            if item.needs_grey:                      # before the object: an intact entry has its grey values
                study.save(target.with_suffix(""))
            loaded.save(target, octree=with_octree)
            output.write_json(record_of(target), checksum(target))
            if make_sheet:
                from ..qc.qc import qc_sheet

                sheet.parent.mkdir(parents=True, exist_ok=True)
                output.write_png(sheet, qc_sheet(study, item.options, item.sheet_views(), item.slices,
                                                 title=f"{item.name}: {item.input}"))
        except OSError as exc:          # the disk refused, not the input nor voxrender
            return _write_failure({"input": item.input}, exc), None
        return {**report, "seconds": loaded.seconds, "cached": False}, study
    except InputError as exc:
        return {"input": item.input, "error": str(exc)}, None
    except Exception as exc:  # a bug must not stop the other inputs; it is reported in the summary
        return {"input": item.input, "error": f"internal error: {type(exc).__name__}: {exc}",
                "traceback": traceback.format_exc()}, None


NO_SPACE = (errno.ENOSPC, errno.EDQUOT)



def _write_failure(row, exc):
    """``row`` failed by a write the system refused (``exc``): its error says which file and why; a full disk is
    marked (``no_space``) for :func:`run_batch` to report.
    """
    where = f"cannot write {exc.filename}: " if exc.filename else "cannot write: "
    return {**row, "error": where + (exc.strerror or str(exc)), "no_space": exc.errno in NO_SPACE}




@functools.lru_cache(maxsize=8)
def _dicom_study(source, series):
    """The DICOM series a picture joins (:func:`voxrender.outputs.secondary_capture.dicom_study`), read once per
    worker.
    """
    from ..outputs.secondary_capture import dicom_study

    return dicom_study(source, series)



def summary_row(item, view, picture_path, status, error="", **numbers):
    """The summary row of one picture (see ``SUMMARY_COLUMNS``): which input, view and method, where it went, its
    ``status`` (``"ok"``, ``"done earlier"`` or ``"failed"``) and ``error``, and, once made, its ``numbers``.
    """
    return {"input": item.input, "name": item.name, "view": view.label, "alpha": view.alpha, "beta": view.beta,
            "gamma": view.gamma, "method": item.method, "output": str(picture_path), "status": status,
            "error": error, **numbers}



def render_task(item, view, index, segments_path, out_dir, encode_seconds):
    """Phase 2: render one view of one input and write its outputs; returns its summary row."""
    outputs = item.outputs(out_dir, view, index)
    try:
        status = Path(segments_path).stat()
        stamp = (status.st_size, status.st_mtime_ns)
        encoded = load_encoded(str(segments_path), stamp)
        study = load_study_files(str(segments_path), stamp) if item.needs_grey else None
        chosen = framed(item, view, encoded.segments)
        if encoded.segments.levels and study is None:      # an input .vxs with levels: the one that suits the view
            level, chosen = level_for(encoded.segments, chosen, item.options, item.read.level)
            encoded = encoded.at_level(level)
        result = picture(encoded.segments, chosen, item.options, tree=octree_for(item.method, encoded), study=study)
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
                return _write_failure(summary_row(item, view, outputs.picture, "failed"), exc)
            raise
    except InputError as exc:
        return summary_row(item, view, outputs.picture, "failed", str(exc))
    except Exception as exc:  # reported in the summary; the batch goes on
        return summary_row(item, view, outputs.picture, "failed", f"internal error: {type(exc).__name__}: {exc}")
    return summary_row(item, view, outputs.picture, "ok", stats=json.dumps(result.image.stats, default=float),
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



def is_done(outputs, size):
    """Whether a view's :class:`~voxrender.outputs.picture_outputs.Outputs` are finished: its picture a readable
    PNG of the expected ``size = (H, W)``, and each other output there (each is written whole or not at all).
    """
    return png_size(outputs.picture) == tuple(size) and all(path.is_file() for path in outputs.wanted().values())



def png_size(path):
    """``(H, W)`` of the PNG at ``path`` once it decodes whole; ``None`` when it is missing, truncated or no PNG
    (then it is made again).
    """
    import imageio.v3 as iio

    try:
        return tuple(iio.imread(path, extension=".png").shape[:2])          # decodes it all
    except Exception:  # missing, truncated or not a PNG
        return None
