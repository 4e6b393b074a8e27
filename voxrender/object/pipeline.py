"""The steps every command shares: from a path on disk to the encoded object.

A ``.vxs`` file is loaded as it is; anything else is read as a slice stack,
cropped, resampled, thresholded and encoded.  The result, :class:`Encoded`, also
keeps what renderers derive from the segments (the region octree), built once on
first use, so that a batch worker rendering many views pays for it once.
"""

from __future__ import annotations

import math
import os
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .. import io
from .._shared import label_sets
from ..errors import InputError
from ..io.dicomfile import is_rtstruct
from . import prep, segments, vxs


@dataclass(frozen=True)
class ReadOptions:
    """How to read a slice stack (see :func:`voxrender.io.read_volume`)."""

    format: str = "auto"
    raw: io.RawLayout | None = None
    spacing: tuple | None = None
    series: str | None = None
    frame: int | None = None
    orientation: str | None = None
    reorient: bool = True
    level: int | None = None
    run: int | None = None

    def read(self, path, progress=None):
        """The :class:`~voxrender.io.Volume` in ``path``, read as these options say."""
        return io.read_volume(path, format=self.format, raw=self.raw, spacing=self.spacing, series=self.series,
                              frame=self.frame, level=self.level, orientation=self.orientation,
                              reorient=self.reorient, progress=progress, run=self.run)


AUTO = "auto"        # PrepOptions.threshold when none is given: decided once, by PrepOptions.selecting


@dataclass(frozen=True)
class PrepOptions:
    """How to select the object (see :func:`voxrender.object.prep.binarize` and
    :func:`voxrender.object.prep.label_map`).

    ``threshold`` (a number, a :class:`~voxrender.object.prep.Interval` or a function of the values) selects grey
    values; ``labels`` selects labels of a label map: the input itself, or a map paired with it
    (``labels.source``), and then an explicit ``threshold`` also applies to the input's grey values.
    ``tissues`` makes one object of several value windows, each a label with its name and colour
    (:func:`voxrender.object.prep.classify`).  Left ``"auto"``, the threshold is what :attr:`selecting` says: Otsu's
    of the grey values, or none when labels or tissues make the object; it stays so through ``replace``, so that
    labels given later (a manifest's row) drop it without being told.

    >>> PrepOptions().selecting is prep.otsu_threshold, PrepOptions(labels=prep.LabelSelection()).selecting
    (True, None)
    """

    threshold: float | prep.Interval | Callable | str | None = AUTO
    crop: tuple | None = None
    voxel: float | None = None
    resample: bool = True
    min_object: int = 0
    labels: prep.LabelSelection | None = None
    tissues: tuple = ()        # (name, Interval, (r, g, b)) each: several tissues of a CT, each a label
    bin: int = 1               # mean binning of bin x bin x bin voxels, after the crop: a preview of a huge stack
    measure_labels: bool = False   # also each label's pieces and whether it touches the edge (a batch's flags)

    @property
    def selecting(self):
        """The threshold that selects the grey values: the one given, else (``"auto"``) Otsu's, or none when labels
        or tissues make the object.
        """
        if isinstance(self.threshold, str) and self.threshold == AUTO:
            return None if self.labels is not None or self.tissues else prep.otsu_threshold
        return self.threshold

    def __post_init__(self):
        if isinstance(self.threshold, str) and self.threshold != AUTO:
            raise InputError(f"{self.threshold!r} is not a threshold; give a number, a window, a function of the "
                             f"values, None, or {AUTO!r}", parameter="threshold")
        if self.voxel is not None and not (self.voxel > 0 and math.isfinite(self.voxel)):
            raise InputError(f"{self.voxel} must be a positive size in mm", parameter="voxel")
        if self.min_object < 0:
            raise InputError(f"{self.min_object} must be 0 or more voxels", parameter="min_object")
        if not (isinstance(self.bin, (int, np.integer)) and self.bin >= 1):
            raise InputError(f"{self.bin!r} must be a whole number of voxels, 1 or more", parameter="bin")


def machine_memory():
    """The bytes of memory this machine has, or its container's limit (cgroup v2) when that is lower."""
    physical = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    try:
        with open("/sys/fs/cgroup/memory.max") as f:
            limit = f.read().strip()
    except OSError:
        return physical
    return min(physical, int(limit)) if limit.isdigit() else physical


def level_for_picture(path, read, pixels):
    """``read`` with the level of a multiscale input (OME-Zarr) that suits a picture ``pixels`` across, when none is
    given: the finest whose largest side is at most ``pixels`` (:func:`voxrender.io.zarr.choose_level`).  Returns
    ``(read, note)``, the note saying which level was picked (``None`` when there was no choice to make).
    """
    if read.level is not None or is_segments_file(path) or read.format not in ("auto", "zarr") or \
            (read.format == "auto" and io.detect_format(path, read.raw) != "zarr"):
        return read, None
    from ..io.zarr import choose_level, levels

    shapes = levels(path)
    if len(shapes) < 2:
        return read, None
    level = choose_level(path, pixels)
    shown = ", ".join(f"{k}: {'x'.join(map(str, shape[::-1]))}" for k, shape in enumerate(shapes))
    return replace(read, level=level), (f"{path}: level {level} of its {len(shapes)} levels ({shown}), the finest "
                                        f"that suits a picture {pixels} pixels across")


def is_segments_file(path):
    """An encoded object: ``.vxs``, or ``.vxo`` (a ``.vxs`` that also keeps the region octree)."""
    return Path(path).suffix.lower() in (".vxs", ".vxo")


@dataclass
class Encoded:
    """An encoded object: its segments (with their surface normals), the seconds spent loading (``load``) and
    preparing (``prepare``) them, and the region octree, read from the file that keeps it or built on first use,
    and kept (:meth:`octree`).
    """

    segments: segments.Segments
    seconds: dict = field(default_factory=dict)
    _octree: object = field(default=None, repr=False)
    _levels: dict = field(default_factory=dict, repr=False)        # {level: Encoded}, made once

    def octree(self, max_memory=None):
        """The region octree of the object (built now if it has not been); a build whose estimated memory is over
        ``max_memory`` bytes (default: half the machine's) is refused before it starts.
        """
        if self._octree is None:
            from .octree import build_from_segments, check_build_memory

            check_build_memory(self.segments, max_memory or machine_memory() // 2)
            self._octree = build_from_segments(self.segments)
        return self._octree

    def at_level(self, level):
        """The object at a level of detail (:meth:`~voxrender.object.segments.Segments.at_level`), as an
        :class:`Encoded` of its own that builds its own octree when asked; itself at level 0.
        """
        if not level:
            return self
        if level not in self._levels:
            self._levels[level] = Encoded(self.segments.at_level(level), dict(self.seconds))
        return self._levels[level]

    @property
    def has_octree(self):
        """Whether the region octree is at hand (read from the file, or built)."""
        return self._octree is not None

    def save(self, path, octree=False, levels=False):
        """Write the object to a ``.vxs`` file; with ``octree``, also its region octree, linear octree and the
        face adjacency of its leaves (built now if they have not been), so that octree methods rendering from
        the file pay only their traversal; with ``levels``, also the object at 2, 4 and 8 times coarser voxels
        (:mod:`voxrender.object.levels`, built now if it does not keep them), which pictures coarser than its
        voxels are drawn from.  Levels it keeps are kept.
        """
        from .octree import sections

        if levels and not self.segments.levels:
            from .levels import build_levels

            self.segments.levels = build_levels(self.segments)
        vxs.save(self.segments, path, sections(self.octree()) if octree else None)


def load_segments(path, read=None, prepare=None, progress=None):
    """The object in ``path``: a ``.vxs`` file, or a slice stack to binarize and encode.

    Parameters
    ----------
    path : str or Path
    read : ReadOptions, optional
    prepare : PrepOptions, optional
    progress : callable, optional

    Returns
    -------
    Encoded

    Examples
    --------
    >>> import tempfile, pathlib, numpy as np
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "cube.npy"
    >>> np.save(path, np.pad(np.full((2, 2, 2), 100, np.int16), 1))
    >>> load_segments(path, prepare=PrepOptions(threshold=50)).segments.voxel_count
    8
    """
    read = read or ReadOptions()
    prepare = prepare or PrepOptions()
    started = time.perf_counter()
    if is_segments_file(path):
        if not Path(path).is_file():
            raise InputError(f"no such file: {path}")
        from .octree import from_sections

        header, arrays = vxs.read_sections(path)
        encoded = vxs.from_sections(header, arrays, path)
        return Encoded(encoded, {"load": time.perf_counter() - started, "prepare": 0.0},
                       from_sections(arrays, encoded.shape, path))
    volume = read.read(path, progress)
    loaded = time.perf_counter()
    encoded = encode_volume(volume, prepare, read, progress, source=path)
    return Encoded(encoded, {"load": loaded - started, "prepare": time.perf_counter() - loaded})


def encode_volume(volume, prepare=None, read=None, progress=None, source=None, normals=True):
    """The object in a :class:`~voxrender.io.Volume` already read (or made from an array), as
    :class:`~voxrender.object.segments.Segments` with their surface normals: :func:`load_segments` without the reading.

    ``read`` says how to read a label map paired with the volume by its path (``prepare.labels.source``, which
    may also be a ``Volume`` on the same grid); ``source`` names where the volume came from (default: its
    ``meta["source"]``).  Without ``normals`` the surface normals are left out (a projection, which draws no
    surface, frames itself by the object alone).

    Examples
    --------
    >>> import numpy as np
    >>> from voxrender.io import Volume
    >>> encode_volume(Volume(np.pad(np.full((2, 2, 2), 100, np.int16), 1)), PrepOptions(threshold=50)).voxel_count
    8
    """
    read = read or ReadOptions()
    prepare = prepare or PrepOptions()
    meta = source_meta(volume, source)
    if prepare.bin > 1 and prepare.labels is not None:
        raise InputError("binning averages grey values, which would mix labels; select the object by a threshold "
                         "or a window to bin it, or leave the label map unbinned", parameter="bin")
    if prepare.bin > 1:                 # a preview: the cropped volume binned (its crop is done)
        volume = prep.binned(volume, prepare.bin, prepare.crop)
        prepare = replace(prepare, crop=None)
        meta["binned"] = prepare.bin
    if prepare.tissues:
        labels, info = prep.classify(volume, [window for _, window, _ in prepare.tissues], crop=prepare.crop,
                                     voxel=prepare.voxel, resample=prepare.resample, progress=progress)
        encoded = segments.encode_labels(labels, info["spacing"], {**meta, "threshold": info["threshold"],
                                                                 "voxel_mm": info["voxel"]})
        present = np.unique(encoded.labels).tolist()           # from the runs: the volume is 100 times larger
        encoded.meta.update(labels=present, label_table={
            str(k): {"name": name, "colour": list(colour)}
            for k, (name, _, colour) in enumerate(prepare.tissues, 1) if k in present})
        encoded.normals = _grey_normals(volume, labels > 0, info, prepare) if normals else None
    elif prepare.labels is None:
        mask, info = prep.binarize(volume, prepare.selecting, crop=prepare.crop, voxel=prepare.voxel,
                                   resample=prepare.resample, min_object=prepare.min_object, progress=progress)
        encoded = segments.encode(mask, info["spacing"], {**meta, "threshold": info["threshold"],
                                                          "voxel_mm": info["voxel"]})
        encoded.normals = _grey_normals(volume, mask, info, prepare) if normals else None
    else:
        encoded = _encode_labels(volume, read, prepare, meta, progress, normals)
    encoded.meta["normals_from"] = encoded.normals.source if normals else "none: the picture draws no surface"
    return encoded


def source_meta(volume, source=None):
    """What an object keeps of the volume (or :class:`~voxrender.io._stack.Stack`) it was made of: where it came
    from, its shape and spacing as read, and what its reader said of it.
    """
    meta = {"source": str(source or volume.meta.get("source", "an array")), "input_shape": list(volume.shape),
            "input_spacing": list(volume.spacing)}
    meta.update({k: v for k, v in volume.meta.items()
                 if k in ("format", "modality", "units", "series", "orientation", "orientation_from", "reoriented")})
    return meta


def _encode_labels(volume, read, prepare, meta, progress, normals=True):
    """The chosen labels of a label map (the input, or the map paired with it) as segments: one label per run
    when each label is an object of its own, else one object.
    """
    from .normals import surface_normals

    selection = prepare.labels
    label_volume = volume
    if isinstance(selection.source, io.Volume):           # an array given to the library, on the image's grid
        label_volume = selection.source
        label_name = label_volume.meta.get("source", "the label array")
    elif selection.source is not None:
        label_name = selection.source
        label_volume = read_labels(selection.source, volume, read)
    elif prepare.selecting is not None:
        raise InputError("a label map is selected by its labels, not by a threshold: drop it, or give the label map "
                         "as the labels of the image it was made from", parameter="threshold")
    if selection.source is not None:
        values, lost = on_image_grid(label_volume, volume, label_name)
        label_volume = replace(label_volume, values=values)
        if lost:
            meta["label_ml_outside"] = lost
        meta["label_source"] = str(label_name)
    if label_volume.meta.get("overlaps"):          # a folder of masks: the pairs its reader gave to one label
        meta["overlaps"] = label_volume.meta["overlaps"]
    # the label map lies on the image's grid: resample both with the image's spacing
    labels, info = prep.label_map(replace(label_volume, spacing=volume.spacing), selection, crop=prepare.crop,
                                  voxel=prepare.voxel, resample=prepare.resample)
    meta.update(labels=info["labels"], voxel_mm=info["voxel"])
    if info["set_aside"]:
        table = label_volume.meta.get("label_table") or {}
        names = ", ".join(f"{(table.get(str(k)) or {}).get('name') or 'label'} (label {k})" for k in info["set_aside"])
        meta["set_aside"] = info["set_aside"]
        warnings.warn(f"{names} is left out of the surface: it holds the patient's outline and would hide the "
                      "structures inside it (draw it with --with-body, or by choosing its label)", stacklevel=2)
    if selection.source is not None and prepare.selecting is not None:
        mask, found = prep.binarize(volume, prepare.selecting, crop=prepare.crop, voxel=prepare.voxel,
                                    resample=prepare.resample, progress=progress)
        labels[~mask] = 0
        meta["threshold"] = found["threshold"]
        if not labels.any():
            raise InputError("no labelled voxel passes the threshold; choose another threshold or labels",
                             parameter="threshold")
    if prepare.min_object > 1:
        from skimage.morphology import remove_small_objects

        labels[~remove_small_objects(labels > 0, max_size=prepare.min_object - 1, connectivity=3)] = 0
    # each label's own voxels, in mL on the image's grid, as given: what every table counts, whatever the picture
    # keeps of them (a threshold or a speck size says so in the rows)
    meta["label_ml"] = {str(label): label_sets.millilitres(count, volume.spacing)
                        for label, count in info["voxels"].items()}
    meta["label_voxels"] = {str(label): count for label, count in info["voxels"].items()}
    if prepare.measure_labels:                          # on the image's grid, as given: pieces and the edge
        measured = label_sets.shapes(prep.crop(label_volume.values, prepare.crop),
                                     label_volume.meta.get("label_sets") or {}, info["voxels"])
        meta["label_pieces"] = {str(k): v[0] for k, v in measured.items()}
        meta["label_border"] = {str(k): v[1] for k, v in measured.items()}
    within = [f"threshold {_said(meta['threshold'])}" if "threshold" in meta else "",
              f"pieces of {prepare.min_object} voxels or more" if prepare.min_object > 1 else ""]
    if any(within):
        meta["labels_shown"] = "the picture shows it within the " + " and ".join(w for w in within if w)
    if selection.separate:
        table = label_volume.meta.get("label_table")
        if table:
            meta["label_table"] = {k: v for k, v in table.items() if int(k) in info["voxels"]}
        encoded = segments.encode_labels(labels, info["spacing"], meta)
    else:
        encoded = segments.encode(labels > 0, info["spacing"], meta)
    encoded.normals = surface_normals(labels > 0) if normals else None
    return encoded


def read_labels(source, image, read=None):
    """The label map that ``source`` holds for ``image``, on its own grid (:func:`on_image_grid` places it on the
    image's): a label map, a folder of masks, a DICOM SEG, an RTSTRUCT (its contours drawn on the image's grid), or
    a DICOM folder holding a SEG or RTSTRUCT beside its slices (the image's own folder too).  A segmentation that
    references another series than the image's is refused, naming both; the errors name the label map.
    """
    from ..io import rtstruct

    path = Path(source)
    try:
        if path.is_dir() and io.READERS["dicom"].sniff(path):
            path = _segmentation_in(path, image)
        if is_rtstruct(path):                 # contours have no grid: they are drawn on the image's own
            labels = rtstruct.read_rtstruct(path, image)
        else:
            labels = replace(read or ReadOptions(), format="auto", frame=None).read(path)
    except InputError as exc:
        raise InputError(f"the label map: {exc.message}", parameter="labels_from") from None
    if labels.meta.get("format") == "rtstruct":
        rtstruct.check_reference(labels.meta, image)     # any series it references; else the frame of reference
        return labels
    referenced, series = labels.meta.get("referenced_series"), image.meta.get("series")
    if referenced and series and referenced != series:
        raise InputError(f"the label map {path} was made on series {referenced}, but the image is series {series}; "
                         "give the image it was made on", parameter="labels_from")
    return labels


def _segmentation_in(folder, image):
    """The one segmentation file a DICOM folder holds beside its slices."""
    from ..io.dicomfile import segmentation_files

    same = Path(image.meta.get("source", "")).resolve() == folder.resolve()
    found = [Path(f) for f in image.meta.get("segmentations", [])] if same else segmentation_files(folder)
    if not found:
        raise InputError(f"{folder} holds DICOM files but no segmentation (SEG or RTSTRUCT) beside its slices; "
                         "give the label map itself")
    if len(found) > 1:
        raise InputError(f"{folder} holds {len(found)} segmentations ({', '.join(f.name for f in found[:4])}); "
                         "give the one to show")
    return found[0]


def _said(threshold):
    """A threshold as the rows say it: ``300`` or ``[-300, 300]``."""
    return f"{threshold:g}" if isinstance(threshold, (int, float)) else str(threshold)


def on_image_grid(label_volume, volume, label_name):
    """The label map's values on the image's grid: placed by patient position (:func:`voxrender.space.grids.pair`) when
    both say where they lie; taken as they are when one does not (an array, a ``.npy``, headerless slices) and
    the shapes agree.  Also ``{label: mL}`` of each structure's own voxels that lie outside the image, which
    placing it loses, with one warning that names them (a SEG with a frame on a slice set aside).
    """
    from ..space.grids import pair, patient_affine, relate

    placed = [v.direction is not None and "origin" in v.meta for v in (label_volume, volume)]
    if all(placed):
        values = pair(label_volume, volume, f"the label map {label_name}",
                      partial=label_volume.meta.get("format") == "seg")        # a SEG keeps only frames it needs
        relation = relate(label_volume.shape, patient_affine(label_volume), volume.shape, patient_affine(volume))
        return values, ({} if relation.overlap >= 1 else _lost(label_volume, volume, label_name))
    if label_volume.shape != volume.shape:
        unplaced = "the label map" if not placed[0] else "the image"
        raise InputError(f"the label map {label_name} has shape {label_volume.shape[::-1]} (x, y, z) but the image "
                         f"has {volume.shape[::-1]}, and {unplaced} does not say where it lies in the patient, so "
                         "they cannot be paired by position; give the label map made from this image",
                         parameter="labels_from")
    return label_volume.values, {}


def _lost(label_volume, volume, label_name):
    """``{label: mL}`` of the structures' own voxels outside the image, warned of."""
    from ..space.grids import outside

    sets = label_volume.meta.get("label_sets") or {}
    beyond = label_sets.structure_counts(outside(label_volume, volume), sets)
    if not beyond:
        return {}
    whole = label_sets.structure_counts(label_volume.values, sets)
    table = label_volume.meta.get("label_table") or {}
    lost = {label: label_sets.millilitres(n, label_volume.spacing) for label, n in beyond.items()}
    said = "; ".join(f"{(table.get(str(k)) or {}).get('name') or f'label {k}'}: {100 * n / whole[k]:.3g} % "
                     f"({lost[k]:g} mL)" for k, n in beyond.items())
    warnings.warn(f"the label map {label_name} reaches beyond the image, and of its structures this much lies "
                  f"outside it, where no picture shows it and no count on the image's grid holds it: {said}",
                  stacklevel=3)
    return {str(k): v for k, v in lost.items()}


def _grey_normals(volume, mask, info, prepare):
    """The surface normals of ``mask`` from the volume's grey values: the cropped input's own voxels when the mask
    lies on its grid, cubic samples of it at the mask's grid points when it was resampled; from the mask itself
    when the volume holds only two values (a binary input).
    """
    from .normals import surface_normals

    values = prep.crop(volume.values, prepare.crop)
    if prep.non_finite_counts(values):      # NaN and inf are outside the object: its lowest value (a copy, rarely)
        values = np.where(np.isfinite(values), values, prep.value_range(values)[0])
    if len(np.unique(np.asarray(values[::7, ::7, ::7]))) <= 2:
        return surface_normals(mask)
    step = grid_step(volume.spacing, info["voxel"], prepare.resample)
    if on_input_grid(step, values.shape, mask.shape):
        return surface_normals(mask, values)
    return surface_normals(mask, grey_sampler(values, step))


def on_input_grid(step, shape, grid):
    """Whether the object's grid is the input's own (its points ``step`` input voxels apart, about 1, and as many),
    so that the normals take the input's voxels rather than samples between them.
    """
    return bool(np.allclose(step, 1)) and tuple(shape) == tuple(grid)


def grid_step(spacing, voxel, resample=True):
    """How many input voxels (x, y, z) apart the object's grid points are: a point ``k`` along an axis lies
    ``k * voxel / spacing`` input voxels from the first.
    """
    return np.array([voxel / s for s in spacing]) if resample else np.ones(3)


def grey_sampler(values, step, first_point=0, first_value=0):
    """``sample(points)``: the grey ``values`` at points ``(N, 3)`` (x, y, z) of the object's grid, ``step`` input
    voxels apart, by a cubic B-spline of the 4 x 4 x 4 voxels around each (the nearest voxel's value beyond the
    edge).  For a slab: the points are the object's from its slice ``first_point``, and ``values`` the input's
    from its slice ``first_value``.

    The B-spline is not prefiltered: it smooths the values a little rather than passing through them, which
    softens the terraces of an upsampled grid, and it reaches only the voxels around a point.  So a slab with two
    slices of the input beyond the points it samples gives the same values, to the last bit, as the whole volume
    (the slice numbers are added and taken away as whole numbers, which is exact).
    """
    from scipy import ndimage

    def sample(points):
        at = np.array(points, np.float64)
        at[:, 2] += first_point
        at *= step
        at[:, 2] -= first_value
        return ndimage.map_coordinates(values, at[:, ::-1].T, output=np.float64, order=3, mode="nearest",
                                       prefilter=False)

    return sample
