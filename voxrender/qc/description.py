"""What an input holds, as ``voxrender info`` prints it: its grid, its values and a threshold they suggest, the
object at a threshold, or its labels with their volumes and how a label map lies on its image.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..object import prep, segments
from ..object.pipeline import PrepOptions, ReadOptions, is_segments_file, load_segments, machine_memory
from ..pictures import colours


def describe(path, read=None, prepare=None, progress=None):
    """Describe an input: an encoded object (``.vxs``, ``.vxo``), or a stack or volume file and what ``prepare``
    selects of it.

    Parameters
    ----------
    path : str or Path
        The input, as the readers take it (:data:`voxrender.READERS`).
    read : ReadOptions, optional
        How to read it.  An encoded object is read as it is.
    prepare : PrepOptions, optional
        What to select: a threshold (default Otsu's, which the description suggests), a label map's labels, or an
        image's labels from another file (``labels=LabelSelection(source=...)``), which are described on the image's
        grid with how both grids relate.
    progress : callable, optional
        ``progress(iterable, length, label)``, wrapped around the slices as they are read.

    Returns
    -------
    dict
        Plain values, in the order ``info`` prints them: ``input``, ``format``, ``dimensions_xyz``,
        ``spacing_mm``; of values, ``value_range``, ``percentiles_1_5_25_50_75_95_99``,
        ``suggested_threshold_otsu`` (and ``suggested_presets`` of a CT); of the object, ``threshold``,
        ``object_voxels``, ``segments``; of labels, ``labels`` (``{label: {"name", "colour", "voxels", "ml"}}``)
        and ``overlaps``.  A stack larger than half the machine's memory is described by its header alone
        (``values`` says so), and ``if_streamed`` says how ``encode`` would read it.

    Examples
    --------
    >>> import numpy as np, pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "ball.npy"
    >>> zz, yy, xx = np.mgrid[:16, :16, :16]
    >>> np.save(path, np.where((xx - 8) ** 2 + (yy - 8) ** 2 + (zz - 8) ** 2 < 25, 1000, 0).astype(np.int16))
    >>> summary = describe(path)
    >>> summary["dimensions_xyz"], summary["suggested_threshold_otsu"], summary["object_voxels"]
    ([16, 16, 16], 500.0, 485)
    """
    path = Path(path)
    read = read or ReadOptions()
    prepare = prepare or PrepOptions()
    if is_segments_file(path):
        return _describe_encoded(path)
    from ..object import stream

    stack = stream.stack_of(path, read)
    if stack is not None and stack.nbytes > machine_memory() // 2:       # described by its header
        summary = {"input": str(path), "format": stack.meta.get("format"),
                   "dimensions_xyz": list(stack.shape[::-1]), "spacing_mm": list(stack.spacing),
                   "dtype": str(stack.dtype), "size_mb": round(stack.nbytes / 1e6),
                   "values": "not read: the stack is larger than half this machine's memory; encode streams it"}
    else:
        summary = _describe_volume(path, read.read(path, progress), prepare)
    if stack is not None:
        summary["if_streamed"] = stream.HOW[stack.how]
    return summary


def _describe_encoded(path):
    """An encoded object: its grid, voxels and segments, what it was selected by, and its levels of detail and
    octree when it keeps them.
    """
    loaded = load_segments(path)
    s = loaded.segments
    summary = {"input": str(path), "format": path.suffix.lower()[1:], "dimensions_xyz": list(s.shape[::-1]),
               "spacing_mm": list(s.spacing), "object_voxels": s.voxel_count, "segments": s.segment_count,
               **{k: v for k, v in s.meta.items() if k != "source"}}
    if s.levels:
        summary["levels"] = [{"level": k, "voxel_edge": level.meta["level_factor"],
                              "dimensions_xyz": list(level.shape[::-1]), "object_voxels": level.voxel_count,
                              "segments": level.segment_count} for k, level in enumerate(s.levels, 1)]
    if loaded.has_octree:
        counts = loaded.octree().counts()
        summary["octree"] = {"side": 1 << loaded.octree().n, **{k: counts[k] for k in ("black", "white", "grey")},
                             "face_adjacency": "kept"}
    return summary


def _describe_volume(path, volume, prepare):
    """A volume read whole: its values, the threshold they suggest, and the object or the labels ``prepare``
    selects.
    """
    values = prep.crop(volume.values, prepare.crop)
    low, high = prep.value_range(values)                 # NaN and inf voxels left out, and counted
    if low is None:
        raise InputError(f"{path}: every voxel is NaN or infinite, so there is nothing to describe")
    padding = prep.padding_value(volume)
    lowest, highest = prep.value_range(values, padding)
    suggested = prep.otsu_threshold(values, padding) if lowest is not None and lowest < highest else low
    sample = np.asarray(values[::max(1, values.shape[0] // 64)])
    if sample.dtype.kind in "fc":                 # its finite values (or all slices', when the sample has none)
        finite = np.isfinite(sample)
        sample = sample[finite] if finite.any() else np.asarray(values)[np.isfinite(values)]
    percentiles = np.percentile(sample, [1, 5, 25, 50, 75, 95, 99])
    summary = {"input": str(path), "format": volume.meta.get("format"),
               "dimensions_xyz": list(volume.shape[::-1]), "spacing_mm": list(volume.spacing),
               "spacing_from": volume.meta.get("spacing_from"), "dtype": str(volume.values.dtype),
               "units": volume.meta.get("units", "stored values"), "value_range": [low, high],
               **{f"{kind}_voxels": count for kind, count in prep.non_finite_counts(values).items()},
               "percentiles_1_5_25_50_75_95_99": [round(float(p), 2) for p in percentiles],
               **({"padding_value": padding, "padding_voxels": int(np.count_nonzero(np.asarray(values) == padding))}
                  if padding is not None else {}),
               "suggested_threshold_otsu": round(suggested, 2)}
    if volume.meta.get("units") == "HU":                  # the tissue windows of a CT
        summary["suggested_presets"] = {name: str(colours.PRESETS[name].window) for name in ("skin", "bone")}
    for key in ("modality", "series", "description", "sorted_by", "orientation", "orientation_from", "affine",
                "reoriented", "masks_reoriented"):
        if volume.meta.get(key):
            summary[key] = volume.meta[key]
    if prepare.labels is not None and prepare.labels.source is None:       # a label map: its labels
        summary.update(_describe_labels(volume, values, path))
        return summary
    if prepare.labels is not None:                                         # an image and its label map
        summary.update(_describe_pairing(volume, prepare.labels.source, prepare.crop))
        return summary
    threshold = suggested if callable(prepare.selecting) or prepare.selecting is None else prepare.selecting
    mask, info = prep.binarize(volume, threshold, crop=prepare.crop, voxel=prepare.voxel,
                               resample=prepare.resample, min_object=prepare.min_object)
    encoded = segments.encode(mask)
    summary.update({"threshold": str(threshold) if isinstance(threshold, prep.Interval) else threshold,
                    "object_grid_xyz": list(mask.shape[::-1]),
                    "object_voxel_mm": info["voxel"], "object_voxels": encoded.voxel_count,
                    "object_fraction": round(encoded.voxel_count / mask.size, 6),
                    "segments": encoded.segment_count})
    return summary


def _describe_labels(volume, values, source):
    """The labels of a label map: each with its name (as a table or the palette would give it), voxels and mL,
    those its file names but that hold no voxel too, and the overlaps its reader resolved.
    """
    from ..pictures.labels import label_list

    prep.check_labels(values, source)
    counts = prep.label_counts(values, volume.meta.get("label_sets"))      # each structure's own voxels
    stored = volume.meta.get("label_table") or {}
    table = colours.label_colours(sorted(set(counts) | {int(k) for k in stored}), stored)
    rows = label_list(table, counts, volume.spacing)
    summary = {"labels": {row.pop("label"): row for row in rows}}
    if volume.meta.get("overlaps"):
        summary["overlaps"] = volume.meta["overlaps"]
    return summary


def _describe_pairing(volume, source, crop):
    """An image's label map: both grids and how they relate, and its labels as they fall on the image's grid."""
    from ..object.pipeline import on_image_grid, read_labels
    from ..space.grids import patient_affine, relate

    labels = read_labels(source, volume)
    relation = relate(labels.shape, patient_affine(labels), volume.shape, patient_affine(volume))
    lines = relation.lines("label map", "image", labels.meta.get("orientation"), volume.meta.get("orientation"))
    paired = replace(volume, values=on_image_grid(labels, volume, source)[0],
                     meta={**labels.meta, "source": str(source)})
    return {"label_map": str(source), "grids": lines,
            **_describe_labels(paired, prep.crop(paired.values, crop), source)}
