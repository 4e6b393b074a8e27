"""The skipping of a maximum (minimum) projection: the blocks of faces whose bound cannot change a ray's answer
are left out (:func:`fold_skipping`, after Mroz et al.), the bounds found over tiles of voxels
(:func:`block_bounds`), and a few rays read straight from the volume (:func:`fold_pairs`); the answer is the one
every face gives, bit for bit.
"""

from __future__ import annotations

import copy
import math

import numpy as np

from .._shared.threads import on_threads
from . import _project_rays
from ._project_march import fold_whole_layers
from ._project_rays import Slices, along, face_crossings, ignored

BLOCK_FACES = 16         # faces per block
TILE = 4                 # the blocks' bounds are per tile of TILE x TILE voxels across the main axis
# a block's rays are read straight from the volume when fewer than a slice's pixels over this: (slices read in
# place, slices read in blocks, which cost more a pixel)
PAIRS_PER_PIXEL = (200, 10)


def fold_skipping(values, rays, layers, mode, result, faces, progress, fold_ends):
    """Fold the layers the rays pass through whole into ``result`` (the maximum or minimum), skipping, for each
    ray, the blocks of faces that cannot change its answer.

    The faces are cut into blocks of ``BLOCK_FACES``; :func:`block_bounds` gives every ray an upper bound (for
    the minimum, a lower bound) of the voxels it can meet in each block.  Each ray first takes its exact fold over
    the block of the highest bound (a value it does meet, so a bound of its answer from the other side); then a
    block is followed, exactly, only for the rays whose bound there beats what they hold.  The result is the one
    every face gives, as a block skipped holds nothing above (below) what the ray already has.

    ``fold_ends()`` folds the rays' first and last layers into ``result``: it runs on a thread of its own while
    the bounds are found.
    """
    from concurrent.futures import ThreadPoolExecutor

    ends = ThreadPoolExecutor(1)
    ends_done = ends.submit(fold_ends)
    beats = np.greater if mode == "mip" else np.less
    neutral = ignored(mode, values.dtype)
    blocks = [range(max(j - 1, faces.start), min(j + BLOCK_FACES, faces.stop))   # the face before: its layer's
              for j in range(faces.start, faces.stop, BLOCK_FACES)]               # middle voxels
    bounds = block_bounds(values, rays, layers, mode, blocks)
    paths = Paths(values, rays, layers)
    # each thread's slice buffers, kept from block to block, a block's slices read at once
    buffers = [{"block": BLOCK_FACES + 2} for _ in range(_project_rays.THREADS)]
    best, highest = np.zeros(rays.count, np.intp), bounds[0].copy()
    for k in range(1, len(blocks)):
        higher = beats(bounds[k], highest)
        best[higher] = k
        np.copyto(highest, bounds[k], where=higher)
    ends_done.result()
    ends.shutdown()
    runs = max(1, min(_project_rays.THREADS, len(blocks) // 2))

    def first(k, out, buffers):
        mine = best == k
        fold_rays(values, rays, layers, mode, out, blocks[k], np.flatnonzero(mine & beats(bounds[k], out)),
                   paths, buffers)
        bounds[k][mine] = neutral                                                   # done

    def then(k, out, buffers):
        fold_rays(values, rays, layers, mode, out, blocks[k], np.flatnonzero(beats(bounds[k], out)), paths,
                   buffers)

    # first into the result (each ray in one block only), then each thread into its own copy of it; the blocks
    # handed out one at a time, as the threads come for them (their work differs much)
    on_threads(lambda k, state: first(k, *state), range(len(blocks)), [(result, b) for b in buffers[:runs]])
    results = [result] + [result.copy() for _ in range(runs - 1)]
    numbers = range(len(blocks)) if progress is None else progress(range(len(blocks)), len(blocks), mode)
    on_threads(lambda k, state: then(k, *state), numbers, list(zip(results, buffers[:runs], strict=False)))
    for other in results[1:]:
        (np.maximum if mode == "mip" else np.minimum)(result, other, out=result)



def fold_rays(values, rays, layers, mode, result, faces, chosen, paths, buffers):
    """:func:`fold_whole_layers` for the rays ``chosen`` (indices, increasing) alone: a few rays straight from the
    volume (:func:`fold_pairs`), many through the slices.
    """
    if not chosen.size:
        return
    if chosen.size * PAIRS_PER_PIXEL[paths.blocked] < paths.nb * paths.nc:
        fold_pairs(paths, mode, result, faces, chosen)
        return
    some = copy.copy(layers)
    some.first, some.last = layers.first[chosen], layers.last[chosen]
    part = result[chosen]
    fold_whole_layers(values, rays.reordered(chosen), some, mode, part, faces, None, buffers)
    result[chosen] = part



class Paths:
    """What :func:`fold_pairs` needs of every ray, worked out once, as :func:`fold_whole_layers` works it out:
    where it crosses the faces along the main axis (the whole and fractional parts of its minor indices + 1/2 at
    face 0, ``A``, and the steps ``r`` per face) and the side of the edges it passes on.
    """

    def __init__(self, values, rays, layers):
        a, b, c = layers.a, layers.b, layers.c
        self.rb, self.rc, whole_b, whole_c, part_b, part_c, self.side = face_crossings(rays, layers)
        self.whole_b, self.whole_c = whole_b.astype(np.intp), whole_c.astype(np.intp)
        self.part_b32, self.part_c32 = part_b.astype(np.float32), part_c.astype(np.float32)
        self.first, self.last = layers.first, layers.last
        self.flat, self.origin = layers.flat, layers.origin
        self.stride_a, self.stride_b, self.stride_c = (layers.strides[k] for k in (a, b, c))
        self.nb, self.nc = layers.sizes[b], layers.sizes[c]
        self.floats = values.dtype.kind == "f"
        self.blocked = Slices(values, 2 - a).blocks



def fold_pairs(paths, mode, result, faces, chosen, chunk=4096):
    """What :func:`fold_whole_layers` folds into ``result`` at ``faces`` for the rays ``chosen``, the same voxels
    (the same arithmetic), read straight from the volume for every (ray, face) pair at once: no slice is copied,
    so it pays for the rays alone.
    """
    fold = np.maximum if mode == "mip" else np.minimum
    neutral = ignored(mode, paths.flat.dtype)
    rb, rc = paths.rb, paths.rc
    js = np.arange(faces.start, faces.stop)
    # per face, as fold_whole_layers works them out (the carries compare float32 parts with float64 thresholds)
    split = [(divmod(j * rb, 1.0), divmod(j * rc, 1.0)) for j in faces]
    steps_b = np.array([s[0][0] for s in split])
    steps_c = np.array([s[1][0] for s in split])
    below_b = np.array([1 - s[0][1] for s in split])
    below_c = np.array([1 - s[1][1] for s in split])
    edge = (steps_b[:-1] + (rb > 0)) * rc - (steps_c[:-1] + (rc > 0)) * rb     # the edge before each face
    # the index along b moves across a layer when the carries differ, or the steps grew and the carry went
    grew_b, grew_c = steps_b[1:] != steps_b[:-1], steps_c[1:] != steps_c[:-1]
    along_b, along_c = (1 if rb > 0 else -1), (1 if rc > 0 else -1)
    layer_before = (js - 1) * paths.stride_a + paths.origin
    steps_b, steps_c = steps_b.astype(np.intp), steps_c.astype(np.intp)
    for start in range(0, chosen.size, chunk):
        rays = chosen[start:start + chunk]
        carry_b = paths.part_b32[rays, None] >= below_b
        carry_c = paths.part_c32[rays, None] >= below_c
        ib = paths.whole_b[rays, None] + steps_b
        ib += carry_b
        ic = paths.whole_c[rays, None] + steps_c
        ic += carry_c
        crossed = (paths.first[rays, None] < js) & (js <= paths.last[rays, None])
        # the two voxels beside each face (layers j - 1 and j); neutral where the ray does not cross it there or
        # is outside the volume (the slice buffers' rim)
        inside = inside_volume(paths, ib, ic)
        inside &= crossed
        cells = ib * paths.stride_b
        cells += ic * paths.stride_c
        cells += layer_before
        found = fold(finite_take(paths, cells, neutral), finite_take(paths, cells + paths.stride_a, neutral))
        found = np.where(inside, found, neutral)
        if rb and rc and len(js) > 1:
            # the voxel between two crossings, in the layer between faces j - 1 and j, as middle_voxels finds it (for
            # all pairs at once: most rays cross both minor axes' faces in most layers)
            moves_b = (carry_b[:, 1:] != carry_b[:, :-1]) != grew_b
            moves_c = (carry_c[:, 1:] != carry_c[:, :-1]) != grew_c
            both = moves_b & moves_c & crossed[:, 1:] & crossed[:, :-1]
            z = edge + carry_b[:, :-1] * rc - carry_c[:, :-1] * rb - paths.side[rays, None]
            b_first = z < 0 if rb * rc > 0 else z > 0
            ib, ic = ib[:, :-1] + b_first * along_b, ic[:, :-1] + ~b_first * along_c
            both &= inside_volume(paths, ib, ic)
            middle = cells[:, :-1] + paths.stride_a
            middle += np.where(b_first, along_b * paths.stride_b, along_c * paths.stride_c)
            middle = np.where(both, finite_take(paths, middle, neutral), neutral)
            fold(found[:, 1:], middle, out=found[:, 1:])
        result[rays] = fold(result[rays], fold.reduce(found, axis=1))



def inside_volume(paths, ib, ic):
    """Whether minor indices ``ib, ic`` lie in the volume (a negative index is a large unsigned one)."""
    inside = ib.view(np.uintp) < paths.nb
    inside &= ic.view(np.uintp) < paths.nc
    return inside



def finite_take(paths, cells, neutral):
    """The voxels at flat indices ``cells`` (any, outside the volume too: the caller masks them), NaN and
    infinite ones ``neutral``.
    """
    found = paths.flat.take(cells, mode="clip")
    if paths.floats:
        found[~np.isfinite(found)] = neutral
    return found



def block_bounds(values, rays, layers, mode, blocks):
    """For every block of faces (a range of them) and every ray, a bound of the values of the voxels the ray can
    meet at those faces in :func:`fold_whole_layers`: above all of them for the maximum (below, for the minimum),
    ignoring NaN; the fold's neutral value where the ray crosses none of the block's faces.  ``(len(blocks),
    rays.count)``, of the values' type.

    The layers beside a block's faces are folded along the main axis, then over tiles of ``TILE`` x ``TILE``
    voxels of the other two axes (the axis next to itself in memory last, on the least data), and each tile takes
    the tiles a ray's path across the block can reach from it (how far it moves along each minor axis over the
    block's faces, and a voxel each side for rounding).  A ray looks the bound up at the tile where it starts.
    """
    reduce = np.fmax if mode == "mip" else np.fmin
    neutral = ignored(mode, values.dtype)
    a, b, c = layers.a, layers.b, layers.c
    axis, tile = 2 - a, TILE
    strides = [abs(s) for s in values.strides]
    # the minor axes in the order they are folded: the larger stride first
    minor = sorted((2 - b, 2 - c), key=lambda k: -strides[k])
    spans = [slice(block.start - 1, block.stop) for block in blocks]      # face j reads layers j - 1 and j
    if strides[axis] < min(strides[k] for k in minor):
        # the main axis is next to itself in memory: the tiles first (each a fold across slices), then blocks
        small = values
        for k in minor:
            small = fold_tiles(small, k, tile, reduce)
        folded = [reduce.reduce(along(small, axis, span), axis=axis) for span in spans]
    else:
        folded = []
        for span in spans:
            plane = reduce.reduce(along(values, axis, span), axis=axis)   # (c, b): c's array axis comes first
            for k in (0, 1) if strides[minor[0]] == strides[2 - c] else (1, 0):
                plane = fold_tiles(plane, k, tile, reduce)
            folded.append(plane)
    bound = np.stack(folded)                                               # (blocks, c tiles, b tiles)
    if bound.dtype.kind == "f":
        bound[np.isnan(bound)] = neutral
    d = rays.direction
    faces = max(len(block) for block in blocks) - 1
    tiles = bound.shape[1:]
    starts, steps = [], []
    for k, array_axis in ((c, 1), (b, 2)):
        r = d[k] / d[a]
        # the tiles a path can reach from the one where it starts: its excursion over the faces, two voxels before
        # (rounding, and the carries of fold_whole_layers) and one after
        reach = (math.ceil(abs(r) * faces) + 3) // tile + 2
        window = bound.copy()
        n = tiles[array_axis - 1]
        for s in range(1, min(reach, n)):
            reduce(along(window, array_axis, slice(0, n - s)), along(bound, array_axis, slice(s, n)),
                   out=along(window, array_axis, slice(0, n - s)))
        bound = window
        # index + 1/2 at face j is start + j r; in tiles, less the two voxels, in single precision (a part of a
        # voxel off at most, within the margin)
        starts.append(((rays.q0[k] + 0.5 - (rays.q0[a] + 0.5) * r - 2) / tile).astype(np.float32))
        steps.append(r)
    out = np.empty((len(blocks), rays.count), bound.dtype)
    where = np.empty(rays.count, np.float32)
    cell = np.empty(rays.count, np.int32)
    for n, block in enumerate(blocks):
        # the tile of the lowest voxel along each minor axis the path can meet at the block's faces
        for start, r, size, scale in zip(starts, steps, tiles, (tiles[1], 1), strict=True):
            np.add(start, (block.start if r >= 0 else block.stop - 1) * r / tile, out=where)
            np.clip(where, 0, size - 1, out=where)
            if scale == 1:
                cell += where.astype(np.int32)
            else:
                np.multiply(where.astype(np.int32), scale, out=cell)
        bound[n].ravel().take(cell, out=out[n])
    # neutral where the ray crosses none of the block's faces (first < j <= last)
    ends = np.array([(block.start, block.stop - 1) for block in blocks])
    low = np.searchsorted(ends[:, 1], layers.first + 1)              # the first block with a face it crosses
    high = np.searchsorted(ends[:, 0], layers.last, side="right")     # after the last
    numbers = np.arange(len(blocks))[:, None]
    out[(numbers < low) | (numbers >= high)] = neutral
    return out



def fold_tiles(array, axis, tile, reduce):
    """``array`` folded by ``reduce`` over runs of ``tile`` along ``axis`` (the last run may be shorter), read in
    place whatever its strides.
    """
    out = along(array, axis, slice(0, None, tile)).copy()
    for s in range(1, tile):
        part = along(array, axis, slice(s, None, tile))
        head = along(out, axis, slice(0, part.shape[axis]))
        reduce(head, part, out=head)
    return out
