"""A study: an input's grey values and labels on its own grid, beside its encoded object.

The surface methods need only the encoded object; the slices and projections of the QC sheet draw the grey values
themselves, with the labels over them.  :func:`load_study` reads the input once and keeps all three: the volume
(canonical frame, cropped, not resampled), the label map placed on its grid (when there is one), and, when asked,
the :class:`~voxrender.object.pipeline.Encoded` object made of them, whose grid (cubic voxels) the pictures are framed
on.  A batch keeps a study's arrays in its cache as ``.npy`` files (:meth:`Study.save`), memory-mapped by the
workers that draw it (:func:`load_saved`).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .. import io
from .._shared import label_sets
from ..errors import InputError
from ..object import prep
from ..object.pipeline import (
    Encoded,
    PrepOptions,
    ReadOptions,
    encode_volume,
    is_segments_file,
    on_image_grid,
    read_labels,
)
from ..space.grids import patient_affine


@dataclass
class Study:
    """One input as the QC pictures draw it.

    Parameters
    ----------
    volume : Volume
        The grey values ``[z, y, x]`` in the canonical frame, cropped, on the input's own grid; its ``meta["origin"]``
        is the patient position of the cropped corner.  For a label map given alone, the map itself.
    labels : ndarray of int, optional
        The label map on the volume's grid (0 background), the chosen labels only.
    stored_table : dict, optional
        The names and colours the label map's file gives (the JSON form a ``.vxs`` keeps, see
        :func:`voxrender.pictures.colours.label_colours`); :meth:`label_table` completes them.
    encoded : Encoded, optional
        The object, on the grid of cubic voxels the pictures are framed on.
    voxel : float
        The edge of that grid's voxels in mm (the finest spacing unless chosen or not resampled).
    resampled : bool
        Whether the object's grid is the cubic one (else the input's own).
    overlaps : list
        The pairs of labels the label map's reader found overlapping (a folder of masks), with their voxels.
    has_grey : bool
        Whether ``volume`` holds grey values (not when the input is the label map itself).
    own_voxels : dict, optional
        ``{label: voxels}`` of each chosen structure on its own, where structures share voxels (``labels`` then
        shows the most specific one a voxel is in, :mod:`voxrender._shared.label_sets`).
    codes, sets : optional
        Where structures share voxels, the label map's codes on the volume's grid and their sets, so that each
        structure is outlined by its own boundary.
    envelopes : tuple of int
        The labels of the patient's outline (BODY, External), outlined in slices, never filled
        (:func:`voxrender._shared.label_sets.envelopes`).
    image, paired : Volume, optional
        The image as read (before the crop) and, when the labels come from a label source paired with it, that
        source placed on its grid, all its labels, with its reader's meta: what an agreement with a reference
        compares (:meth:`voxrender.review.agreement.Comparison.of_study`), so the source is paired once.  Not
        saved.
    """

    volume: io.Volume
    labels: np.ndarray | None = None
    stored_table: dict | None = None
    encoded: Encoded | None = None
    voxel: float = 1.0
    resampled: bool = True
    overlaps: list = field(default_factory=list)
    has_grey: bool = True
    own_voxels: dict | None = None
    codes: np.ndarray | None = None
    sets: dict | None = None
    envelopes: tuple = ()
    image: io.Volume | None = field(default=None, repr=False)
    paired: io.Volume | None = field(default=None, repr=False)

    @property
    def step(self):
        """``(sx, sy, sz)``: an object-grid point ``p`` lies at input index ``p * step`` (see
        :func:`voxrender.pictures._project.project`).
        """
        if not self.resampled:
            return (1.0, 1.0, 1.0)
        return tuple(self.voxel / s for s in self.volume.spacing)

    def window(self, projection="mip"):
        """The window a ``projection`` of the study is shown through when none is given: the 1st to 99th percentile
        (:func:`voxrender.pictures.display.auto_window`) of the study's projection along y, whatever the view, so that
        every view of it (a MIP turntable) is shown alike; found once.  The volume's own percentiles would not do: the
        bone a head's MIP shows is its top one per cent.
        """
        from ..pictures.display import auto_window
        from ..pictures.kinds import PROJECTIONS

        kept = self.__dict__.setdefault("_windows", {})
        if projection not in kept:
            kept[projection] = auto_window(PROJECTIONS[projection].plane(self.volume.values))
        return kept[projection]

    def label_table(self, given=None):
        """``{label: (name, (r, g, b))}`` of the labels the study holds: from ``given`` (a colour table), the file's
        own names and colours, the anatomy table and the palette (:func:`voxrender.pictures.colours.label_colours`).
        """
        from ..pictures.colours import label_colours

        if self.labels is None:
            return {}
        return label_colours(sorted(self.label_voxels()), self.stored_table, given)

    def label_voxels(self):
        """``{label: voxels}`` of the labels the study holds, on its grid (:func:`voxrender.object.prep.label_counts`),
        counted once; each structure's own, where structures share voxels.
        """
        if self.own_voxels is not None:                     # structures that share voxels: each one's own
            return {int(k): v for k, v in self.own_voxels.items()}
        if "_label_voxels" not in self.__dict__:
            self.__dict__["_label_voxels"] = {} if self.labels is None else prep.label_counts(self.labels)
        return self.__dict__["_label_voxels"]

    def save(self, stem):
        """Write the arrays to ``stem.grey.npy`` and ``stem.labels.npy`` and the rest to ``stem.study.json``."""
        from ..outputs import output

        stem = Path(stem)
        output.write_npy(stem.with_name(stem.name + ".grey.npy"), np.ascontiguousarray(self.volume.values))
        if self.labels is not None:
            output.write_npy(stem.with_name(stem.name + ".labels.npy"), np.ascontiguousarray(self.labels))
        if self.codes is not None:
            output.write_npy(stem.with_name(stem.name + ".codes.npy"), np.ascontiguousarray(self.codes))
        volume = self.volume
        output.write_json(stem.with_name(stem.name + ".study.json"), {
            "spacing": list(volume.spacing), "origin": volume.meta.get("origin"),
            "direction": None if volume.direction is None else np.asarray(volume.direction).tolist(),
            "meta": {k: v for k, v in volume.meta.items() if k in _KEPT_META},
            "labels": self.labels is not None, "voxel": self.voxel, "resampled": self.resampled,
            "stored_table": self.stored_table, "overlaps": self.overlaps,
            "has_grey": self.has_grey, "own_voxels": self.own_voxels, "codes": self.codes is not None,
            "sets": self.sets, "envelopes": list(self.envelopes)})


_KEPT_META = ("source", "format", "modality", "units", "series", "orientation", "reoriented", "padding",
              "crop_corner")


def saved_files(stem):
    """The files :meth:`Study.save` writes for ``stem`` (the labels' and codes' only when it has them)."""
    stem = Path(stem)
    return [stem.with_name(stem.name + suffix) for suffix in (".grey.npy", ".labels.npy", ".study.json", ".codes.npy")]


def load_saved(stem, encoded=None):
    """The :class:`Study` that :meth:`Study.save` wrote at ``stem``, its arrays memory-mapped."""
    grey, labels, about, codes = saved_files(stem)
    record = json.loads(about.read_text())
    meta = {**record["meta"], **({"origin": record["origin"]} if record["origin"] is not None else {})}
    volume = io.Volume(np.load(grey, mmap_mode="r"), tuple(record["spacing"]), meta,
                       None if record["direction"] is None else np.asarray(record["direction"]))
    return Study(volume, np.load(labels, mmap_mode="r") if record["labels"] else None, record["stored_table"], encoded,
                 record["voxel"], record["resampled"], record["overlaps"], record["has_grey"], record["own_voxels"],
                 np.load(codes, mmap_mode="r") if record.get("codes") else None, record.get("sets"),
                 tuple(record.get("envelopes") or ()))


def cropped(volume, region):
    """``volume`` cut to ``region`` (``(z, y, x)`` slices, see :func:`voxrender.object.prep.crop`), its origin moved to
    the cropped corner so that it still lies where it lay in the patient.

    >>> from voxrender.io import Volume
    >>> part = cropped(Volume(np.zeros((4, 4, 4)), (2.0, 1.0, 1.0), {"origin": [0.0, 0.0, 0.0]}),
    ...                (slice(1, 3), slice(None), slice(2, 4)))
    >>> part.shape, part.meta["origin"], part.meta["crop_corner"]
    ((2, 4, 2), [4.0, 0.0, 1.0], [2, 0, 1])
    """
    if region is None:
        return volume
    values = prep.crop(volume.values, region)
    corner = np.array([s.indices(n)[0] for s, n in zip(region[::-1], volume.shape[::-1], strict=True)], float)
    meta = {**volume.meta, "crop_corner": [int(v) for v in corner]}      # a point in input voxels lies there
    if "origin" in meta:
        meta["origin"] = [float(v) for v in (patient_affine(volume) @ np.append(corner, 1.0))[:3]]
    return replace(volume, values=values, meta=meta)


def load_study(path, read=None, prepare=None, progress=None, encode=True, normals=True):
    """The :class:`Study` of ``path``: read once, its labels placed on its grid, and, with ``encode``, its object.

    Parameters
    ----------
    path : str or Path
        What :func:`voxrender.load_segments` reads, but a ``.vxs``: an encoded object keeps no grey values.
    read : ReadOptions, optional
    prepare : PrepOptions, optional
        The object's selection, crop and grid; its ``labels`` give the study's label map (the input itself, or
        the map paired with it).
    progress : callable, optional
    encode : bool
        Also encode the object (the surfaces, and the framing of projections need it; slices do not).
    normals : bool
        With the object, its surface normals (the surfaces need them; a projection alone does not).

    Returns
    -------
    Study

    Examples
    --------
    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "cube.npy"
    >>> np.save(path, np.pad(np.full((2, 2, 2), 100, np.int16), 1))
    >>> study = load_study(path, prepare=PrepOptions(threshold=50))
    >>> study.volume.shape, study.encoded.segments.voxel_count, study.labels is None
    ((4, 4, 4), 8, True)
    """
    read = read or ReadOptions()
    prepare = prepare or PrepOptions()
    if is_segments_file(path):
        raise InputError(f"{path} is an encoded object, which keeps no grey values to draw slices or projections "
                         "of; give the slice stack it was made from")
    if prepare.bin > 1:
        raise InputError("slices, projections and QC sheets are drawn from the stack's own voxels, not binned ones; "
                         "drop the binning, or crop the stack", parameter="bin")
    started = time.perf_counter()
    volume = read.read(path, progress)
    seconds = {"load": time.perf_counter() - started}
    selection, labels, table, overlaps, own = prepare.labels, None, None, [], None
    codes, sets, envelopes, paired = None, None, (), None
    if selection is not None:
        if selection.source is None:                       # the input is the label map
            labels_volume = volume
        else:                                              # read once, placed on the image's grid, kept for both
            name = getattr(selection.source, "meta", {}).get("source") if isinstance(selection.source, io.Volume) \
                else selection.source
            found = selection.source if isinstance(selection.source, io.Volume) else \
                read_labels(selection.source, volume, read)
            where = {"origin": volume.meta["origin"]} if "origin" in volume.meta else {}   # now the image's grid
            labels_volume = replace(volume, values=on_image_grid(found, volume, name)[0],
                                    meta={**found.meta, "source": str(name), **where})
            prepare = replace(prepare, labels=replace(selection, source=labels_volume))
            paired = labels_volume
        codes = prep.crop(labels_volume.values, prepare.crop)
        labels, own = _chosen(codes, selection.chosen, labels_volume, prepare.crop is not None)
        sets = labels_volume.meta.get("label_sets") or None
        codes = codes if sets else None
        envelopes = () if selection.envelopes else tuple(label_sets.envelopes(labels_volume.meta))
        table = labels_volume.meta.get("label_table")
        overlaps = labels_volume.meta.get("overlaps") or []
    encoded = None
    if encode:
        started = time.perf_counter()
        encoded = Encoded(encode_volume(volume, prepare, read, progress, source=path, normals=normals),
                          {**seconds, "prepare": time.perf_counter() - started})
    part = cropped(volume, prepare.crop)
    voxel, grid = prep.cubic_grid(part.shape, part.spacing, prepare.voxel, prepare.resample)   # the object's grid
    return Study(part, labels, table, encoded, float(voxel), grid is not None, overlaps,
                 has_grey=selection is None or selection.source is not None, own_voxels=own, codes=codes, sets=sets,
                 envelopes=envelopes, image=volume, paired=paired)


def _chosen(values, chosen, source, cropped):
    """The label map's ``chosen`` labels (all when ``None``), 0 elsewhere, as uint16, a shared voxel showing the most
    specific structure it is in; and, where structures share voxels, each chosen one's own voxels (else ``None``).
    Refused when it holds none of them (:func:`voxrender.object.prep.chosen_labels`).
    """
    name = source.meta.get("source", "the label map")
    prep.check_labels(values, name)
    sets = source.meta.get("label_sets") or {}
    counts = prep.label_counts(values, sets)
    chosen = prep.chosen_labels(counts, chosen, name, cropped).tolist()
    own = {str(k): counts[k] for k in chosen} if sets else None
    return label_sets.resolve(values, sets, chosen), own
