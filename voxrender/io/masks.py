"""A folder of binary masks, one NIfTI or NRRD file per structure, read as one label map.

This is what TotalSegmentator (``segmentations/liver.nii.gz``, ``spleen.nii.gz`` ...), nnU-Net's per-class exports
and ``dcmrtstruct2nii`` write.  Each file is read with :func:`~voxrender.io.read_volume` (so its sizes and
orientation are checked as for any volume) and becomes one label:

- **Numbering.** A mask's name is its file name without ``.nii.gz``, ``.nii``, ``.seg.nrrd``, ``.nrrd`` or
  ``.nhdr`` (``liver.nii.gz`` is ``liver``); label k (from 1) is the k-th name in natural order
  (:func:`~voxrender.io.natural_key`: ``rib_2`` before ``rib_10``, case aside).
- **Grid.** The label map lies on the first mask's grid; a mask on another grid is placed on it by patient position
  (:func:`voxrender.space.grids.pair`, nearest neighbour).
- **Overlaps.** Each mask keeps its own voxels: a voxel in several masks holds the code of that set of masks
  (:mod:`voxrender._shared.label_sets`, named in ``meta["label_sets"]``), and the pictures show the smallest.  Each
  pair that overlaps is reported in ``meta["overlaps"]``: ``{"labels": [a, b], "names": [...], "voxels": n}``, with
  ``"inside"`` naming the one that lies wholly inside the other.
- **Empty masks** keep their label and name, and are listed in ``meta["empty_labels"]``.

``meta["label_table"]`` names every label (``{"1": {"name": "liver", "colour": None}}``: mask files carry no colour).
A file that holds more than 0 and one other value (a 0/1, 0/255 or boolean mask) is refused, naming it.
"""

from __future__ import annotations

import collections
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .._shared import label_sets
from ..errors import InputError
from . import nifti, nrrd
from ._reading import read_with
from ._shared import (
    Reader,
    Volume,
    check_fits,
    files_beside,
    identity_progress,
    listed,
    natural_key,
    some_names,
    volume_files,
)

SUFFIXES = (".nii", ".nii.gz", ".nrrd", ".nhdr")     # NIfTI's and NRRD's volume files
NAME_ENDINGS = (".nii.gz", ".seg.nrrd", ".nii", ".nrrd", ".nhdr")       # longest first: what a name drops
# Files are read two at a time (gzip inflation and NumPy's passes let go of Python's lock), at most this many
# ahead of the one being placed: a few masks in memory at once, never the whole folder.
WORKERS, LOOK_AHEAD = 2, 2
LABEL_MAP_VALUES = 1000          # a non-binary file of at most this many whole, non-negative values is a label map


def mask_name(path):
    """The structure a mask file holds: its name without the volume file's ending.

    >>> from pathlib import Path
    >>> mask_name(Path("segmentations/liver.nii.gz")), mask_name(Path("Rib_L10.NRRD"))
    ('liver', 'Rib_L10')
    """
    name = path.name
    ending = next((e for e in NAME_ENDINGS if name.lower().endswith(e)), "")
    return name[:len(name) - len(ending)]


def holds_masks(path):
    """A folder whose files, besides notes, are all NIfTI or NRRD volumes (a segmentation's one file per organ).

    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (folder / "liver.nii.gz").write_bytes(b""), (folder / "README.txt").write_text("masks")
    >>> holds_masks(folder), holds_masks(folder / "liver.nii.gz")
    (True, False)
    """
    return path.is_dir() and bool(volume_files(path, SUFFIXES))


def read_masks(path, progress):
    """Read a folder of binary masks as one label map: label k is the k-th mask's name in natural order.

    Parameters
    ----------
    path : Path
        A folder of NIfTI (``.nii``, ``.nii.gz``) or NRRD (``.nrrd``, ``.nhdr``) files, one mask each.
    progress : callable
        ``progress(iterable, length, label)`` wraps the loop over the files.

    Returns
    -------
    Volume
        Label codes (uint8, or uint16 beyond 254 masks and their shared sets) on the first mask's grid, with its
        spacing, direction and origin; ``meta`` holds ``label_table``, ``label_sets``, ``overlaps``,
        ``empty_labels``, ``overlap_rule`` and ``masks`` (how many).

    Examples
    --------
    >>> import tempfile, pathlib, nibabel
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> for name, x in [("spleen", slice(0, 3)), ("liver", slice(2, 6))]:
    ...     mask = np.zeros((6, 4, 2), np.uint8); mask[x] = 1                 # [i, j, k]
    ...     nibabel.save(nibabel.Nifti1Image(mask, np.eye(4)), folder / f"{name}.nii.gz")
    >>> volume = read_masks(folder, lambda items, length, label: items)
    >>> volume.meta["label_table"]["1"]["name"], np.bincount(volume.values.ravel()).tolist()
    ('liver', [0, 24, 16, 8])
    >>> volume.meta["label_sets"], volume.meta["overlaps"]
    ({'3': [2, 1]}, [{'labels': [1, 2], 'names': ['liver', 'spleen'], 'voxels': 8}])
    """
    if not path.is_dir():
        raise InputError(f"{path} is a file; the masks format reads a folder of masks, one NIfTI or NRRD file each",
                         parameter="format")
    files, beside = volume_files(path, SUFFIXES), files_beside(path, SUFFIXES)
    if not files:
        strays = [f for f in listed(path) if not f.name.lower().endswith(SUFFIXES) and f not in beside]
        raise InputError(f"{path} holds files other than NIfTI or NRRD masks ({some_names(strays)});"
                         " give a folder of masks, one file each", parameter="format")
    if beside:
        warnings.warn(f"{path}: {len(beside)} file{'s' * (len(beside) > 1)} beside the masks "
                      f"{'are' if len(beside) > 1 else 'is'} not masks and {'are' if len(beside) > 1 else 'is'} "
                      f"passed over ({some_names(beside, 5)})", stacklevel=2)
    if len(files) == 1:
        alone = _one_volume(files[0])
        if alone is not None:
            return alone
    files.sort(key=lambda f: (natural_key(mask_name(f)), f.name))
    names = [mask_name(f) for f in files]
    twice = [f.name for f, name in zip(files, names, strict=True) if names.count(name) > 1]
    if twice:
        raise InputError(f"{path} holds two masks of one name ({', '.join(twice)}); keep one of them")
    if len(files) > np.iinfo(np.uint16).max:
        raise InputError(f"{path} holds {len(files)} masks; a label map takes at most 65535")
    painter = first = None
    empty = []
    pool = ThreadPoolExecutor(WORKERS)
    try:
        pending = collections.deque(pool.submit(_read_mask, f) for f in files[:LOOK_AHEAD])
        for label, file in enumerate(progress(files, len(files), "reading masks"), start=1):
            volume, found = pending.popleft().result()
            if label + LOOK_AHEAD <= len(files):
                pending.append(pool.submit(_read_mask, files[label + LOOK_AHEAD - 1]))
            if first is None:
                first = volume
                check_fits(volume.shape, np.uint8 if len(files) < 255 else np.uint16, path)
                painter = label_sets.Painter(volume.shape, len(files))
            else:
                found = _on_grid(volume, found, first, file, files[0])
            if found is None:
                empty.append(label)
                continue
            painter.paint(label, *found)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    codes, sets = painter.finish()
    table = {str(k): {"name": name, "colour": None} for k, name in enumerate(names, start=1)}
    meta = {"format": "masks", "masks": len(files), "overlap_rule": label_sets.RULE, "label_sets": sets,
            "overlaps": label_sets.overlap_report(codes, sets, dict(enumerate(names, start=1))),
            "empty_labels": empty, "label_table": table}
    for key in ("origin", "orientation_from", "spacing_from"):
        if key in first.meta:
            meta[key] = first.meta[key]
    if "reoriented" in first.meta:
        meta["masks_reoriented"] = f"{files[0].name}: {first.meta['reoriented']}"
    return Volume(codes, first.spacing, meta, first.direction)


def _one_volume(file):
    """The volume a folder of one volume file holds, when it is not a mask (a CT, a label map); ``None`` for a mask,
    which is a folder of one structure.
    """
    volume = _read_file(file)
    try:
        _where(volume.values, file)
    except InputError:
        volume.meta["read_as"] = f"the one volume file of its folder, {file.name}"
        return volume
    return None


def _read_file(file):
    """A NIfTI or NRRD file of the folder as :func:`voxrender.io.read_volume` reads it, by its format's reader."""
    format, reader = ("nifti", nifti.READER) if file.name.lower().endswith(nifti.SUFFIXES) else ("nrrd", nrrd.READER)
    return read_with(reader, file, format, identity_progress, {})


def _read_mask(file):
    """One mask, in the canonical frame, and where it is on its own grid (:func:`_where`); on a worker thread."""
    try:
        volume = _read_file(file)
    except InputError as exc:
        if exc.parameter != "frame":
            raise
        raise InputError(f"{file} is a 4-D file (several volumes); a folder of masks holds one 3-D mask a file: "
                         "take it out of the folder") from None
    return volume, _where(volume.values, file)


def _on_grid(volume, found, first, file, first_file):
    """Where a mask is on the first mask's grid: as found, on the same grid; else placed by patient position."""
    from ..space import grids

    if found is None:
        return None
    placed = grids.pair(volume, first, label_name=str(file), image_name=f"the first mask, {first_file.name}",
                        parameter=None)
    return found if placed is volume.values else _where(placed, file)     # pair hands back a grid that is the same


def _where(values, file):
    """The bounding box (slices) of a mask's nonzero voxels and which voxels of the box they are, or ``None`` for
    an empty mask; a file that holds other values than 0 and one more is refused.  Whole-volume passes are only a
    reduction to the occupied slices: the rest works on the mask's slab and box.
    """
    if values.dtype.kind in "ub":
        occupied = values.max(axis=(1, 2)) > 0
    else:                                              # negative values are nonzero too: slice by slice
        occupied = np.array([np.any(plane != 0) for plane in values])
    slices = np.flatnonzero(occupied)
    if not len(slices):
        return None
    slab = values[slices[0]:slices[-1] + 1]
    inside = slab != 0
    rows, columns = np.flatnonzero(inside.any(axis=(0, 2))), np.flatnonzero(inside.any(axis=(0, 1)))
    rows, columns = slice(rows[0], rows[-1] + 1), slice(columns[0], columns[-1] + 1)
    inside = inside[:, rows, columns]
    held = slab[:, rows, columns][inside]
    if not held.min() == held.max():                  # not: a NaN compares false
        raise _not_a_mask(values, file)
    return (slice(slices[0], slices[-1] + 1), rows, columns), inside


def _not_a_mask(values, file):
    """The error for a file in a mask folder that holds more than two values, saying what it holds."""
    distinct = np.unique(values)
    distinct = distinct[~np.isnan(distinct)] if distinct.dtype.kind == "f" else distinct
    low, high = (f"{v:g}" for v in (distinct[0], distinct[-1]))
    whole = distinct.dtype.kind in "ui" or bool(np.all(distinct == np.round(distinct)))
    if whole and distinct[0] >= 0 and len(distinct) <= LABEL_MAP_VALUES:
        return InputError(f"{file} holds {len(distinct)} distinct values ({low} .. {high}): it is a label map, not a "
                          "mask; give it alone with labels")
    return InputError(f"{file} holds grey values ({len(distinct)} distinct, {low} .. {high}): it is an image, not a "
                      "mask; a folder of masks holds one binary mask a file (0 and one other value)")


READER = Reader(read_masks, suffixes=(), options=(), sniff=holds_masks)
