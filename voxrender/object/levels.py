"""Levels of detail: an object's runs at 2, 4 and 8 times coarser voxels, for pictures coarser than its voxels.

A picture of a 2048-voxel object 1024 pixels across shows a voxel in four per pixel: drawn from voxels twice as
large, it is the same picture at a fraction of the work.  :func:`coarser` bins an object's runs by a factor: a
coarse voxel is in the object when any of its fine voxels is (so thin structures do not vanish, as they do in the
mean of ``--bin``), and holds the largest label among them.  It works on the runs, a group of coarse slices at a
time, never on the voxels, so a memory-mapped ``.vxs`` larger than memory is read once, in order.  A coarse
voxel's normal is the sum of its fine voxels' grey-level normals, made unit: the gradient of the grey values
averaged over the coarse voxel, without reading the stack again.  Each level is a :class:`Segments` of its own
grid, so every method, oracle and the exact reference apply to it unchanged; the ``.vxs`` keeps them
(:func:`voxrender.object.vxs.save`) and :func:`choose_level` picks one for a picture.

References
----------
.. [1] Meagher, D. (1982). Geometric modeling using octree encoding. Computer Graphics and Image Processing 19,
   129-147: a node of the octree is the union of its eight children, the level of detail its depth.
"""

from __future__ import annotations

import numpy as np

from .._shared import label_sets
from .._shared.mapped import read_mapped, search_mapped
from .._shared.threads import on_threads
from .normals import SurfaceNormals, octahedral_decode, octahedral_encode, surface_band
from .segments import Segments, encode_labels, ranges

FACTORS = (2, 4, 8)          # the levels a .vxs keeps beside its own voxels: level k is 2**k times coarser
_RUNS_AT_ONCE = 1 << 21      # fine runs and normals binned in one group of coarse slices
_CELLS_AT_ONCE = 1 << 23     # and coarse voxels whose normals are summed there, in dense arrays


def coarser(segments, factor=2):
    """``segments`` binned by ``factor``: a coarse voxel is in the object when any of its ``factor``³ fine voxels
    is, with the largest label among them; its normal, the unit sum of theirs.

    Parameters
    ----------
    segments : Segments
        The object, with its normals and labels when it has them (a memory-mapped ``.vxs`` is read a group of
        slices at a time).
    factor : int
        The edge of a coarse voxel in fine voxels; the grid is ``ceil(n / factor)`` along each axis, the spacing
        ``factor`` times the fine one.

    Returns
    -------
    Segments
        The coarse object; its ``meta`` is the fine one's with ``level_factor``, its voxel's edge in voxels of the
        full resolution, and, of labels, the full resolution's voxels and mL of each (``label_voxels``,
        ``label_ml``), which its tables show.

    Examples
    --------
    >>> from voxrender.object.segments import encode
    >>> mask = np.zeros((4, 4, 4), bool); mask[0, 0, 0] = mask[3, 2:4, 1:3] = True
    >>> coarse = coarser(encode(mask))
    >>> coarse.shape, coarse.to_mask()[:, :, 0].astype(int).tolist()
    ((2, 2, 2), [[1, 0], [0, 1]])
    """
    if not (isinstance(factor, (int, np.integer)) and factor >= 2):
        raise ValueError(f"factor {factor!r} must be a whole number of voxels, 2 or more")
    nz, ny, nx = segments.shape
    shape = coarse_shape(segments.shape, factor)
    meta = coarse_meta(segments.meta, factor, segments.label_voxels if segments.labels is not None else None,
                       segments.spacing)
    offsets = np.asarray(segments.offsets)
    cny = shape[1]
    segments.check()
    if segments.normals is not None:
        segments.normals.check()

    groups = _slice_groups(segments, factor)

    def runs_of(bounds):                                  # a group of whole coarse slices, on a thread
        first, last = bounds
        rows, starts, ends, labels = _binned_runs(segments, offsets, first, last, factor, shape)
        begin = first // factor * cny
        counts = np.bincount(rows - begin, minlength=((last - 1) // factor + 1) * cny - begin)
        return begin, counts, starts.astype(np.int32), ends.astype(np.int32), \
            None if segments.labels is None else labels.astype(np.uint16)

    counts = np.zeros(shape[0] * cny, np.int64)
    kept = {"starts": [], "ends": [], "labels": []}
    for begin, own, starts, ends, labels in on_threads(runs_of, groups):
        counts[begin:begin + len(own)] = own
        kept["starts"].append(starts)
        kept["ends"].append(ends)
        kept["labels"].append(labels)
    coarse_offsets = np.zeros(len(counts) + 1, np.int64)
    np.cumsum(counts, out=coarse_offsets[1:])
    result = Segments(shape, *(np.concatenate(kept[name]) for name in ("starts", "ends")), coarse_offsets,
                      tuple(float(s) * factor for s in segments.spacing), meta, None,
                      None if segments.labels is None else np.concatenate(kept["labels"]))
    if segments.normals is not None:
        # then the normals, group by group, of the coarse surface (which the coarse runs of the slices beside a
        # group decide)
        found = on_threads(lambda bounds: _binned_normals(segments.normals, *bounds, factor, result), groups)
        source = segments.normals.source.split(", summed over")[0]
        f = meta["level_factor"]
        result.normals = SurfaceNormals(shape, np.concatenate([index for index, _ in found]),
                                        np.concatenate([packed for _, packed in found]),
                                        f"{source}, summed over {f}x{f}x{f} voxels")
    return result


def coarse_shape(shape, factor):
    """The grid of a level ``factor`` times coarser than ``shape``'s: ``ceil(n / factor)`` along each axis."""
    return tuple(-(-n // factor) for n in shape)


def coarse_meta(meta, factor, label_voxels=None, spacing=None):
    """A level's meta: the finer one's (``meta``), with ``level_factor``, its voxel's edge in voxels of the full
    resolution, and of a labelled object (``label_voxels()`` giving the full resolution's ``{label: voxels}``) the
    full resolution's voxels and mL of each label, which its tables show.
    """
    meta = {key: value for key, value in meta.items() if key != "levels"}
    meta["level_factor"] = int(meta.get("level_factor", 1)) * int(factor)
    if label_voxels is not None and "label_voxels" not in meta:     # the tables keep the full resolution's
        own = label_voxels()
        meta["label_voxels"] = {str(k): v for k, v in own.items()}
        meta.setdefault("label_ml", {str(k): label_sets.millilitres(v, spacing) for k, v in own.items()})
    return meta


def build_levels(segments, factors=FACTORS):
    """The coarser levels of ``segments``: one :func:`coarser` object for each of ``factors`` (each a multiple of
    the one before, and made from it, so the object is read once at full resolution).

    >>> from voxrender.object.segments import encode
    >>> [level.shape for level in build_levels(encode(np.ones((8, 8, 8), bool)))]
    [(4, 4, 4), (2, 2, 2), (1, 1, 1)]
    """
    levels, finer, done = [], segments, 1
    for factor in factors:
        if factor % done:
            raise ValueError(f"the factors {factors} must each be a multiple of the one before")
        finer = coarser(finer, factor // done)
        levels.append(finer)
        done = factor
    return tuple(levels)


def choose_level(factors, pixel_voxels):
    """The level (0 the full resolution; ``k`` the ``k``-th of ``factors``) whose voxel is the largest no larger
    than a pixel of ``pixel_voxels`` full-resolution voxels.

    >>> choose_level((2, 4, 8), 2.0), choose_level((2, 4, 8), 1.9), choose_level((2, 4, 8), 100.0)
    (1, 0, 3)
    """
    fitting = [k for k, factor in enumerate(factors, 1) if factor <= pixel_voxels * (1 + 1e-9)]
    return max(fitting, default=0)


def _slice_groups(segments, factor):
    """``(first, last)`` fine slices of groups of whole coarse slices, each holding about ``_RUNS_AT_ONCE`` runs and
    normals (or one coarse slice): the work of one pass of :func:`_binned_runs` and :func:`_binned_normals`.
    """
    nz, ny, nx = segments.shape
    bounds = np.append(np.arange(0, nz, factor), nz)
    work = np.asarray(segments.offsets[bounds * ny], np.int64)
    if segments.normals is not None:
        work = work + search_mapped(segments.normals.index, bounds * (ny * nx))
    plane = -(-ny // factor) * -(-nx // factor)
    most = max(1, _CELLS_AT_ONCE // plane)                 # coarse slices a group's dense sums may span
    groups, first = [], 0
    while first < len(bounds) - 1:
        last = max(int(np.searchsorted(work, work[first] + _RUNS_AT_ONCE, "right")) - 1, first + 1)
        last = min(last, len(bounds) - 1, first + most)
        groups.append((int(bounds[first]), int(bounds[last])))
        first = last
    return groups


def _binned_runs(segments, offsets, first, last, factor, shape):
    """The coarse runs of fine slices ``first .. last - 1`` (whole coarse slices): their coarse rows, starts, ends
    and labels, sorted by row and start.  Each fine run covers coarse voxels ``start // f .. end // f`` of its
    coarse row; the runs of one label that overlap or touch in a coarse row are merged, and where labels meet,
    the largest wins.
    """
    ny = segments.shape[1]
    _, cny, cnx = shape
    lo, hi = int(offsets[first * ny]), int(offsets[last * ny])
    counts = np.diff(offsets[first * ny:last * ny + 1])
    fine_rows = np.repeat(np.arange(first * ny, last * ny, dtype=np.int64), counts)
    z, y = np.divmod(fine_rows, ny)
    rows = z // factor * cny + y // factor
    starts = read_mapped(segments.starts, lo, hi) // factor
    ends = read_mapped(segments.ends, lo, hi) // factor
    labels = np.ones(hi - lo, np.int64) if segments.labels is None else read_mapped(segments.labels, lo, hi) \
        .astype(np.int64)
    rows, starts, ends, labels = _merged(rows, starts, ends, labels, cnx)
    if segments.labels is not None and len(rows):
        rows, starts, ends, labels = _painted(rows, starts, ends, labels, cnx)
    return rows, starts, ends, labels


def _merged(rows, starts, ends, labels, width):
    """The union of the runs ``[starts, ends]`` of each (row, label): sorted, the overlapping and touching merged."""
    span = width + 2                     # a run of one (row, label) never reaches the next one's keys
    group = rows * (int(labels.max(initial=0)) + 1) + labels
    order = np.lexsort((starts, group))
    group, keyed_starts = group[order], group[order] * span + starts[order]
    reach = np.maximum.accumulate(group * span + ends[order])       # the furthest end so far, in key space
    new = np.ones(len(order), bool)
    new[1:] = keyed_starts[1:] > reach[:-1] + 1
    first = np.flatnonzero(new)
    last = np.append(first[1:], len(order))[:len(first)] - 1       # none when there are no runs
    return rows[order][first], starts[order][first], reach[last] - group[first] * span, labels[order][first]


def _painted(rows, starts, ends, labels, width):
    """The labelled runs of rows where the runs of different labels may overlap, the largest label winning: each
    row's runs are painted on a line of its own, in the order of their labels, and read back as runs.
    """
    present, line_of = np.unique(rows, return_inverse=True)
    lines = np.zeros((len(present), width), np.uint16)
    order = np.argsort(labels, kind="stable")                # the largest label painted last
    lengths = ends[order] - starts[order] + 1
    columns, owner = ranges(starts[order], lengths, owners=True)
    flat = line_of[order][owner] * width + columns
    np.maximum.at(lines.reshape(-1), flat, labels[order][owner].astype(np.uint16))
    painted = encode_labels(lines[:, None, :])
    repeats = np.diff(painted.offsets)
    return np.repeat(present, repeats), painted.starts, painted.ends, painted.labels


def _binned_normals(normals, first, last, factor, coarse):
    """The normals of the coarse surface's voxels in fine slices ``first .. last - 1``: the coarse object's voxels
    with an empty 6-neighbour (:func:`~voxrender.object.normals.surface_band`), as the full resolution keeps the
    band, each the unit sum of the normals of its fine voxels (a voxel without fine normals, or whose fine normals
    cancel, has none).  The empty side of the coarse surface keeps none: a hit point's normal comes from the
    object's side (:meth:`voxrender.object.normals.SurfaceNormals.at` weighs the corners that have one), and the
    file is smaller.  Returns their sorted voxel numbers and packed normals.
    """
    plane = normals.shape[1] * normals.shape[2]
    lo, hi = (int(v) for v in search_mapped(normals.index, [first * plane, last * plane]))
    fine = read_mapped(normals.index, lo, hi).astype(np.int64)
    packed = read_mapped(np.asarray(normals.packed).reshape(-1), 2 * lo, 2 * hi).reshape(-1, 2)
    below, above = max(first // factor - 1, 0), min((last - 1) // factor + 2, coarse.shape[0])
    return summed_normals(fine, packed, normals.shape, first, last, factor, _decoded(coarse, below, above), below)


def summed_normals(fine, packed, shape, first, last, factor, solid, below):
    """:func:`_binned_normals` of the fine normals ``fine`` (sorted voxel numbers of a grid of ``shape``) and
    their ``packed`` normals, all those of fine slices ``first .. last - 1``, given the coarse object's slices
    ``below ..`` as a bool mask ``solid``, which holds the slice beside the group's on each side where there is
    one: their coarse voxel numbers and packed normals.
    """
    nz, ny, nx = shape
    cnz, cny, cnx = coarse_shape(shape, factor)
    plane = ny * nx
    z, rest = np.divmod(fine, plane)
    y, x = np.divmod(rest, nx)
    # summed on the dense grid of the group's coarse slices (bincount: no sort of the fine voxels)
    bottom, top = first // factor, (last - 1) // factor + 1
    base = bottom * cny * cnx
    local = (z // factor * cny + y // factor) * cnx + x // factor - base
    cells = (top - bottom) * cny * cnx
    present = np.flatnonzero(np.bincount(local, minlength=cells))
    # each fine voxel's place among the cells present: the sums below are then as long as those, not the grid
    place = np.zeros(cells, np.int32 if len(present) < 2 ** 31 else np.int64)
    place[present] = np.arange(len(present))
    place = place[local]
    unit = octahedral_decode(packed)
    total = np.stack([np.bincount(place, weights=unit[:, k], minlength=len(present)) for k in range(3)], axis=1)
    length = np.sqrt(np.einsum("nk,nk->n", total, total))
    surface = (surface_band(solid) & solid)[bottom - below:top - below].reshape(-1)    # beside: the neighbours
    kept = (length > 1e-6) & surface[present]
    index_type = np.int32 if cnz * cny * cnx < 2 ** 31 else np.int64
    return (present[kept] + base).astype(index_type), octahedral_encode(total[kept] / length[kept, None])


def _decoded(segments, first, last):
    """Slices ``first .. last - 1`` of ``segments`` as a bool mask ``[z, y, x]``."""
    nz, ny, nx = segments.shape
    lo, hi = int(segments.offsets[first * ny]), int(segments.offsets[last * ny])
    counts = np.diff(segments.offsets[first * ny:last * ny + 1])
    rows = np.repeat(np.arange(first * ny, last * ny, dtype=np.int64), counts)
    starts, ends = np.asarray(segments.starts[lo:hi], np.int64), np.asarray(segments.ends[lo:hi], np.int64)
    mask = np.zeros((last - first) * ny * nx, bool)
    mask[ranges((rows - first * ny) * nx + starts, ends - starts + 1)] = True
    return mask.reshape(last - first, ny, nx)
