"""Surface normals from grey values (Höhne and Bernstein's grey-level gradient shading), kept with the object.

Voxel depth images are terraced; the grey values of a CT are not: the partial-volume effect makes them fall
smoothly across a surface, so their gradient is a smooth, accurate normal.  :func:`surface_normals` takes the
gradient (a 3 x 3 x 3 Sobel kernel: a central difference along the axis, smoothed across it) at every voxel of
the surface *band* (object voxels with an empty 6-neighbour and empty voxels with an object 6-neighbour) and
keeps it, octahedrally quantised to two 16-bit numbers, in a :class:`SurfaceNormals`.  Where no grey values
exist (a label map, a binary ``.npy``, an old ``.vxs``) the binary mask is used instead, through the derivative
of a Gaussian of one voxel (5 x 5 x 5), which smooths its steps.  At a picture's hit points the normals of the
eight surrounding voxel centres are interpolated trilinearly, so every method, whatever its depth image came from,
gets the same smooth normals; a hit on a face the object was cut by takes that face's normal (:func:`cut_normals`).
"""

from __future__ import annotations

import itertools
import math
import os
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .._shared.mapped import is_mapped, prefetch, read_mapped
from .._shared.threads import on_threads
from .segments import label_at


def _stencil(radius, smooth, derive):
    """Offsets ``(n, 3)`` (dx, dy, dz) and the gradient kernels ``(3, n)`` of separable 1-D weights."""
    offsets = np.array(list(itertools.product(range(-radius, radius + 1), repeat=3)))
    kernels = np.stack([np.prod([(derive if k == axis else smooth)[offsets[:, k] + radius] for k in range(3)], axis=0)
                        for axis in range(3)])
    return offsets, kernels


_t = np.arange(-2, 3, dtype=float)
# Grey values: the Sobel kernel (a central difference along the axis, 1 2 1 across it).  A binary mask: the
# derivative of a Gaussian of one voxel over 5 x 5 x 5, which smooths its steps.
SOBEL_1D = np.array([1.0, 2.0, 1.0]), np.array([-1.0, 0.0, 1.0])          # (smooth, derive)
GAUSSIAN_1D = np.exp(-_t ** 2 / 2), _t * np.exp(-_t ** 2 / 2)
SOBEL = _stencil(1, *SOBEL_1D)
GAUSSIAN = _stencil(2, *GAUSSIAN_1D)
# The look-ups of SurfaceNormals.at read a memory-mapped index or normals larger than this a block of FILE_BLOCK
# values at a time from the file: through the mapping, the pages they touch would stay in memory (gigabytes).
RESIDENT_BYTES = 1 << 28
FILE_BLOCK = 1 << 22
THREAD_VOXELS = 1 << 16    # the voxels (or normals) worth a thread of their own


def octahedral_encode(normals):
    """Unit vectors ``(N, 3)`` to ``(N, 2)`` int16 (octahedral mapping; about 0.005 degrees of error).

    >>> octahedral_decode(octahedral_encode(np.array([[0.0, 0.6, -0.8]]))).astype(float).round(4).tolist()
    [[0.0, 0.6, -0.8]]
    """
    n = np.asarray(normals, dtype=np.float64)
    return np.concatenate(_in_chunks(lambda a, b: _octahedral(n[a:b]), len(n)))


def _octahedral(n):
    """:func:`octahedral_encode` of float64 vectors ``n``, in this thread."""
    return _octahedral_of(*n.T)


def _octahedral_of(x, y, z):
    """:func:`octahedral_encode` of vectors given as their x, y and z (float64 arrays: passes over contiguous
    columns are several times faster than across the rows of ``(N, 3)``), in this thread.
    """
    scale = np.maximum((np.abs(x) + np.abs(y)) + np.abs(z), 1e-30)       # summed as np.sum sums a row of 3
    x, y, z = x / scale, y / scale, z / scale
    below = z < 0
    packed = np.empty((len(x), 2), np.int16)
    packed[:, 0] = np.rint(np.where(below, (1 - np.abs(y)) * np.where(x >= 0, 1, -1), x) * 32767)
    packed[:, 1] = np.rint(np.where(below, (1 - np.abs(x)) * np.where(y >= 0, 1, -1), y) * 32767)
    return packed


def octahedral_decode(packed):
    """``(N, 2)`` int16 back to unit vectors ``(N, 3)`` float32."""
    return np.stack(_decode(_words(packed)), axis=1)


def _words(packed):
    """Packed normals ``(N, 2)`` int16 as one int32 word each: a gather moves one word, not a pair."""
    return np.ascontiguousarray(packed, np.int16).view(np.int32).ravel()


def _decode(words):
    """The unit vectors of packed normals as words (:func:`_words`): their x, y and z, each a contiguous
    float32 array.
    """
    pair = words.view(np.int16).reshape(-1, 2)
    x, y = pair[:, 0] * np.float32(1 / 32767), pair[:, 1] * np.float32(1 / 32767)
    z = 1 - np.abs(x) - np.abs(y)
    shift = np.maximum(-z, 0)
    x -= np.copysign(shift, x)              # x >= 0 (never -0.0: it comes from an integer) gives +shift
    y -= np.copysign(shift, y)
    length = np.sqrt(x * x + y * y + z * z)
    return x / length, y / length, z / length


def surface_band(mask):
    """Object voxels with an empty 6-neighbour (or on the volume's edge) and empty voxels with an object one.

    The voxels of every 6-neighbour pair that differ, by shifted slices: the same band as SciPy's
    ``binary_dilation`` minus ``binary_erosion`` with a 6-neighbourhood (the edge counting as empty), many times
    faster.

    >>> int(surface_band(np.pad(np.ones((3, 3, 3), bool), 1)).sum())
    80
    """
    mask = np.asarray(mask, dtype=bool)
    band = np.zeros_like(mask)
    scratch = np.empty(mask.size, bool)             # one buffer for the three axes' differences
    for axis in range(3):
        lead, trail = [slice(None)] * 3, [slice(None)] * 3
        lead[axis], trail[axis] = slice(1, None), slice(None, -1)
        lead, trail = tuple(lead), tuple(trail)
        differ = scratch[:mask[lead].size].reshape(mask[lead].shape)
        np.not_equal(mask[lead], mask[trail], out=differ)     # both voxels of a differing pair are in the band
        band[lead] |= differ
        band[trail] |= differ
        for end in (0, -1):                         # object voxels on the volume's edge
            edge = [slice(None)] * 3
            edge[axis] = end
            band[tuple(edge)] |= mask[tuple(edge)]
    return band


def band_voxels(mask, slices=16, own=None):
    """The ``(z, y, x)`` coordinates of the voxels of :func:`surface_band`, found a few slices at a time (each
    with the slice before and after it) so that no whole-volume array is made: new memory is slow to touch.
    With ``own = (first, last)``, only those of slices ``first .. last - 1``: ``mask`` is then a slab of a larger
    mask with a slice of it on either side (where the larger one has it), whose own band is not kept.

    >>> z, y, x = band_voxels(np.pad(np.ones((3, 3, 3), bool), 1), slices=2)
    >>> len(z), (int(z.min()), int(z.max()))
    (80, (0, 4))
    """
    mask = np.asarray(mask, dtype=bool)
    nz = mask.shape[0]
    begin, end = own or (0, nz)

    def block(first):
        last = min(first + slices, end)
        below, above = max(first - 1, 0), min(last + 1, nz)
        # the extra slices only show their neighbours to the chosen ones: their own band (which counts the
        # block's ends as the volume's edge) is not kept
        band = surface_band(mask[below:above])[first - below:first - below + last - first]
        z, y, x = np.unravel_index(np.flatnonzero(band), band.shape)
        return z + first, y, x

    found = on_threads(block, range(begin, end, slices))          # the blocks on threads, in order
    return tuple(np.concatenate(part) for part in zip(*found, strict=True)) if found else (np.zeros(0, np.int64),) * 3


@dataclass
class SurfaceNormals:
    """Outward unit normals at the voxels of a surface band: linear voxel ``index`` (sorted) and ``packed``
    octahedral normals, for a volume of ``shape = (nz, ny, nx)``; ``source`` says what they came from.
    """

    shape: tuple
    index: np.ndarray
    packed: np.ndarray
    source: str = "grey values"
    unchecked: object = field(default=None, repr=False, compare=False)   # a file's check, made on first use

    def check(self):
        """Run the check a file's normals were loaded with (that the index rises), once: it reads the whole index,
        which a picture drawn from a coarser level never needs.
        """
        pending, self.unchecked = self.unchecked, None
        if pending is not None:
            pending()

    def prefetch(self):
        """Have a file's normals read from disk in the background, when they are read through their mapping (no
        larger than ``RESIDENT_BYTES``): a picture's look-ups reach most of their pages.
        """
        prefetch(*(array for array in (self.index, self.packed) if array.nbytes <= RESIDENT_BYTES))

    @cached_property
    def unit(self):
        """All the unit normals, decoded: x, y and z rows ``(3, M)`` float32."""
        self.check()
        return np.stack(_decode(_words(self.packed)))

    @cached_property
    def _bitmap(self):
        """The band as bits, one per voxel of the volume and 64 to a word, and the count of band voxels before
        each word: the place of any voxel in ``index`` without a search.
        """
        self.check()
        index = np.asarray(self.index, np.int64)
        words = np.zeros(int(np.prod(self.shape, dtype=np.int64)) // 64 + 2, np.uint64)
        word = index >> 6
        first = np.flatnonzero(np.r_[True, word[1:] != word[:-1]]) if len(word) else word
        words[word[first]] = np.bitwise_or.reduceat(np.uint64(1) << (index & 63).astype(np.uint64), first)
        before = np.zeros(len(words), np.int32 if len(index) < 2 ** 31 else np.int64)
        np.cumsum(np.bitwise_count(words)[:-1], out=before[1:])
        return words, before

    def _place(self, linear):
        """For voxel numbers ``linear`` (any integers; those off the volume are not there): their place in
        ``index`` (where they are, or would be), and whether they are there.
        """
        words, before = self._bitmap
        clipped = np.clip(linear, 0, len(words) * 64 - 1)
        at = clipped >> 6
        word, bit = np.take(words, at), (clipped & 63).astype(np.uint64)
        place = np.take(before, at) + np.bitwise_count(word & ((np.uint64(1) << bit) - np.uint64(1)))
        return place, ((word >> bit) & np.uint64(1)).astype(bool) & (clipped == linear)

    def at(self, points):
        """Normals ``(N, 3)`` at object points ``(N, 3)`` (x, y, z), interpolated from the eight voxel centres
        around each; NaN where none of the eight has one.
        """
        self.check()
        points = np.asarray(points, dtype=np.float64)
        nz, ny, nx = self.shape
        index = np.asarray(self.index)                                    # a plain array, not a memory map
        if not len(index) or not len(points):
            return np.full((len(points), 3), np.nan, np.float32)
        many = "unit" in self.__dict__ or 8 * len(points) >= len(index)      # as many corners as normals
        # the bitmap grows with the volume, not the object: a small object in a vast volume keeps the search
        bitmap = many and ("_bitmap" in self.__dict__ or nz * ny * nx // 64 <= 16 * len(index))
        if len(points) < 2 * THREAD_VOXELS:
            return self._interpolate(points, index, many, bitmap)
        if many:                       # what the threads share, made once before them
            self.unit                                                     # noqa: B018 (a cached property)
            if bitmap:
                self._bitmap                                              # noqa: B018
        parts = np.array_split(points, min(os.cpu_count() or 1, len(points) // THREAD_VOXELS))
        return np.concatenate(on_threads(lambda part: self._interpolate(part, index, many, bitmap), parts))

    def _interpolate(self, points, index, many, bitmap):
        """:meth:`at` of ``points``, the normals decoded all at once (``many``, from the ``bitmap`` or a search)
        or only at the points' corners.
        """
        nz, ny, nx = self.shape
        base = np.floor(points).astype(np.int64)
        x, y, z = base.T
        # the weights of the two voxel centres around each point along each axis; 0 for one off the volume, so
        # that a corner there, whatever the look-up below finds for it, counts for nothing
        (x0, x1), (y0, y1), (z0, z1) = (
            ((1 - f) * ((low >= 0) & (low < size)), f * ((low >= -1) & (low < size - 1)))
            for low, f, size in zip(base.T, (points - base).astype(np.float32).T, (nx, ny, nz), strict=True))
        rows = np.stack([z0 * y0, z0 * y1, z1 * y0, z1 * y1])                      # the rows (dz, dy): (4, N)
        dz, dy = np.array([0, 0, 1, 1])[:, None], np.array([0, 1, 0, 1])[:, None]
        # the four rows around each point, all looked up at once; voxel x + 1 of a row, when present, sorts
        # right after voxel x (or at x's place if x is absent)
        linear = ((z + dz) * ny + (y + dy)) * nx + x                                 # (4, N)
        top = len(index) - 1
        if bitmap:
            # looked up in the bitmap, made once for every later picture
            slot, there = self._place(linear)
            after, there_next = slot + there, self._place(linear + 1)[1]
        elif index.nbytes > RESIDENT_BYTES and is_mapped(index):    # a huge file's: read a block at a time
            slot, there, there_next = _search_in_blocks(index, linear)
            after = slot + there
        else:                                       # a small picture, or object in a vast volume: a search
            slot = np.minimum(np.searchsorted(index, linear.astype(index.dtype, copy=False)), top)
            there = index[slot] == linear           # at x = -1 that is the last voxel of the row before
            after = slot + there
            there_next = index[np.minimum(after, top)] == linear + 1
        slot, after = np.minimum(slot, top), np.minimum(after, top)
        # (8, N): x, then x + 1; a missing corner weighs 0 (decoding all is cheaper than picking those found)
        weights = np.concatenate([rows * x0 * there, rows * x1 * there_next])
        slots = np.concatenate([slot, after]).ravel()
        if many:                                                  # decoded once, for every later picture
            corners = np.take(self.unit, slots, axis=1)         # (take: a tenth of the time of [:, slots])
        else:                                                     # a small picture: decode just its corners
            words = _words(self.packed)
            big = words.nbytes > RESIDENT_BYTES and is_mapped(words)
            corners = _decode(_take_in_blocks(words, slots) if big else np.take(words, slots))
        total = np.stack([np.einsum("cn,cn->n", weights, c.reshape(weights.shape)) for c in corners], axis=1)
        length = np.sqrt(np.einsum("nk,nk->n", total, total))[:, None]
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(length > 1e-12, total / length, np.nan).astype(np.float32)


def _search_in_blocks(index, linear, block=None):
    """:meth:`SurfaceNormals.at`'s search of voxel numbers ``linear`` in the sorted, memory-mapped ``index``,
    reading from its file only the blocks they fall in (:func:`~voxrender._shared.mapped.read_mapped`), so that its
    pages do not stay in memory: each number's place (``np.searchsorted``'s), whether it is there, and whether
    the number after it is at the place after.
    """
    block = block or FILE_BLOCK
    wanted = linear.ravel()
    order = np.argsort(wanted, kind="stable")
    wanted = wanted[order]
    firsts = index[::block]                                 # the first of each block: a page each
    blocks = np.maximum(np.searchsorted(firsts, wanted, "right") - 1, 0)
    bounds = np.searchsorted(blocks, np.arange(len(firsts) + 1))
    slot, there, there_next = (np.empty(len(wanted), np.int64), np.empty(len(wanted), bool),
                               np.empty(len(wanted), bool))
    for k in np.flatnonzero(bounds[1:] > bounds[:-1]):          # a Python loop over blocks, not numbers
        lo, hi = bounds[k], bounds[k + 1]
        values = read_mapped(index, k * block, (k + 1) * block + 2)     # and the two after, for the neighbours
        own = min(block, len(index) - k * block)
        part = wanted[lo:hi]
        local = np.searchsorted(values[:own], part)         # past the block: before the next block's first
        found = values[np.minimum(local, len(values) - 1)] == part
        found &= local < len(values)
        after = local + found
        slot[lo:hi] = k * block + local
        there[lo:hi] = found
        there_next[lo:hi] = (after < len(values)) & (values[np.minimum(after, len(values) - 1)] == part + 1)
    placed = np.empty_like(order)
    placed[order] = np.arange(len(order))
    return tuple(a[placed].reshape(linear.shape) for a in (slot, there, there_next))


def _take_in_blocks(array, positions, block=None):
    """``np.take(array, positions)`` from a memory-mapped ``array``, reading from its file only the blocks the
    positions fall in (as :func:`_search_in_blocks`).
    """
    block = block or FILE_BLOCK
    order = np.argsort(positions, kind="stable")
    wanted = positions[order]
    bounds = np.searchsorted(wanted, np.arange(0, len(array) + block, block))
    out = np.empty(len(positions), array.dtype)
    for k in np.flatnonzero(bounds[1:] > bounds[:-1]):
        lo, hi = bounds[k], bounds[k + 1]
        out[order[lo:hi]] = read_mapped(array, k * block, (k + 1) * block)[wanted[lo:hi] - k * block]
    return out


def surface_normals(mask, sample=None, source=None, *, own=None, offset=0, shape=None):
    """The outward normals of ``mask``'s surface band.

    Parameters
    ----------
    mask : ndarray of bool ``[z, y, x]``
        The object (its voxels have the high values).
    sample : ndarray or callable, optional
        The grey values: an array on ``mask``'s grid, or ``sample(points)`` giving them at object points
        ``(N, 3)`` (x, y, z; whole or fractional voxels of ``mask``'s grid).  Beyond the grid's edge a value is
        its nearest voxel's.  Default: the mask itself, as 0 and 1 (the binary fallback).
    source : str, optional
        What the normals came from, for the record (default: "grey values", or "the binary mask").
    own, offset, shape : optional
        For a slab of a larger mask (a stack read a slab at a time): the normals of its slices ``own = (first,
        last)`` only, ``mask`` holding beside them as many slices of the larger mask as the stencil reaches (where
        it has them; ``sample``'s points are the slab's); ``offset``, the larger mask's slice that is the slab's
        first; ``shape``, the larger mask's.  The normals of the slabs, one after another, are the larger mask's.

    Returns
    -------
    SurfaceNormals

    Examples
    --------
    >>> zz, yy, xx = np.mgrid[:9, :9, :9] - 4
    >>> normals = surface_normals(xx ** 2 + yy ** 2 + zz ** 2 <= 9)
    >>> normals.at(np.array([[7.5, 4.0, 4.0]])).round(3).tolist()     # on the +x side
    [[1.0, 0.0, 0.0]]
    """
    mask = np.asarray(mask, dtype=bool)
    nz, ny, nx = shape = tuple(shape or mask.shape)
    if sample is None:
        sample, source = mask, source or "the binary mask"
    offsets, kernels = GAUSSIAN if source == "the binary mask" else SOBEL
    z, y, x = band_voxels(mask, own=own)
    if callable(sample):
        gradient = _gradient_of_samples(sample, np.stack([x, y, z], axis=1), offsets, kernels).T.copy()
    else:
        smooth, derive = GAUSSIAN_1D if source == "the binary mask" else SOBEL_1D
        gradient = _gradient_on_grid(sample, (z, y, x), smooth, derive)
    found = _in_chunks(lambda a, b: _outward_packed(gradient[:, a:b]), len(z))
    keep = np.concatenate([kept for kept, _ in found])
    index = (((z + offset) * ny + y) * nx + x)[keep].astype(np.int32 if math.prod(shape) < 2 ** 30 else np.int64)
    return SurfaceNormals(shape, index, np.concatenate([packed for _, packed in found]), source or "grey values")


def _outward_packed(gradient):
    """Which of the gradients ``(3, n)`` are not zero, and the outward unit normals of those, packed: the object
    is where values are high, so outward is down the gradient.
    """
    gx, gy, gz = gradient
    length = np.sqrt((gx * gx + gy * gy) + gz * gz)                 # as np.linalg.norm sums a row of 3
    keep = length > 1e-9
    scale = length[keep]
    return keep, _octahedral_of(-gx[keep] / scale, -gy[keep] / scale, -gz[keep] / scale)


def stencil_radius(source):
    """How many slices on either side the normals of a slab need (:func:`surface_normals`'s ``own``)."""
    return 2 if source == "the binary mask" else 1


def _gradient_of_samples(sample, centres, offsets, kernels):
    """The gradient at ``centres`` from ``sample(points)`` at every offset of the stencil: any sampler."""
    gradient = np.zeros((len(centres), 3))
    chunk = max(1, 4_000_000 // len(offsets))
    for start in range(0, len(centres), chunk):
        part = centres[start:start + chunk]
        values = _stencil_samples(sample, part, offsets)
        found = np.zeros((3, len(part)))
        for k, weights in enumerate(kernels.T):       # summed in one order, not by BLAS (whose order varies)
            found += weights[:, None] * values[:, k]
        gradient[start:start + chunk] = found.T
    return gradient


def _stencil_samples(sample, centres, offsets):
    """``sample`` at every ``centres + offsets`` point: ``(len(centres), len(offsets))`` float64.  The stencils
    of neighbouring voxels overlap, so whole-numbered centres (a band's voxels) have each distinct point sampled
    once, about ten times fewer, each value the one the point alone gets.  Centres that are not whole numbers, or
    spread too thinly over their bounding box to mark it, are sampled point by point.
    """
    if centres.dtype.kind in "iu" and len(centres):
        low = centres.min(axis=0) + offsets.min(axis=0)
        box = (centres.max(axis=0) + offsets.max(axis=0) - low + 1).tolist()           # x, y, z
        if math.prod(box) <= 4 * len(centres) * len(offsets):
            strides = np.array([1, box[0], box[0] * box[1]])
            place = ((centres - low) @ strides)[:, None] + offsets @ strides            # in the box, z-major
            needed = np.zeros(math.prod(box), bool)
            needed[place] = True
            distinct = np.flatnonzero(needed)
            number = np.zeros(len(needed), np.int64)
            number[distinct] = np.arange(len(distinct))
            points = np.stack(np.unravel_index(distinct, box[::-1])[::-1], axis=1) + low
            return np.asarray(sample(points), dtype=np.float64)[number[place]]
    points = (centres[:, None, :] + offsets[None, :, :]).reshape(-1, 3)
    return np.asarray(sample(points), dtype=np.float64).reshape(len(centres), len(offsets))


def _gradient_on_grid(grid, voxels, smooth, derive):
    """The gradient ``(3, N)`` at ``voxels`` (z, y, x arrays) of the values ``grid`` by a separable kernel; rows
    beyond the grid's edge in y or z are the edge's.  The same as :func:`_gradient_of_samples` with the stencil's
    kernels, which takes the few voxels whose window would run off the row's end, and no copy of the grid.

    Each voxel's sum is taken in one fixed order, whatever else is computed beside it, so the normals of a slab
    are the whole volume's to the last bit.  A band that is a large part of the grid (a porous object) takes the
    gradient of every voxel of a few slices at a time instead (:func:`_dense_sobel_at`), which for 16-bit grey
    values is exact, and so the same.
    """
    radius = len(smooth) // 2
    grid = np.ascontiguousarray(grid)
    nz, ny, nx = grid.shape
    z, y, x = voxels
    spanned = (int(z.max()) - int(z.min()) + 1) * ny * nx if len(z) else 0       # the slices the band is in
    if radius == 1 and _exact_in_float32(grid) and 8 * len(x) > spanned:
        return _dense_sobel_at(grid, voxels, smooth, derive).T.copy()
    gradient = np.empty((3, len(x)))
    inner = (x >= radius) & (x < nx - radius)
    every_inner = bool(inner.all())
    if not every_inner:
        gradient[:, ~inner] = _gradient_of_samples(_edge_sampler(grid), np.stack([x, y, z], axis=1)[~inner],
                                                   *_stencil(radius, smooth, derive)).T
        z, y, x = z[inner], y[inner], x[inner]
    if not len(x):                  # rows shorter than the stencil (a volume one or two voxels wide in x)
        return gradient
    # whole numbers with whole weights (a Sobel kernel on integers of 16 bits or fewer) are summed in int32:
    # exactly, as float64 sums them, at half the memory traffic; a chunk at a time, whose sums stay in the cache
    kind = np.int32 if radius == 1 and _exact_in_float32(grid) else np.float64
    found = gradient if every_inner else np.empty((3, len(x)))

    def sums(a, b):
        found[:, a:b] = _separable_sums(grid, z[a:b], y[a:b], x[a:b], smooth, derive, kind)

    _in_chunks(sums, len(x))
    if not every_inner:
        gradient[:, inner] = found
    return gradient


def _in_chunks(work, count, chunk=THREAD_VOXELS):
    """``[work(a, b), ...]`` over consecutive chunks ``a:b`` of ``count`` items, on threads (NumPy lets go of
    Python's lock), each thread taking the next chunk when done; each item's result is its own, so the same.
    A chunk's temporaries stay in the cache.
    """
    if count <= chunk:
        return [work(0, count)]
    return on_threads(lambda a: work(a, min(a + chunk, count)), range(0, count, chunk))


def _separable_sums(grid, z, y, x, smooth, derive, kind):
    """:func:`_gradient_on_grid`'s sums at voxels ``z, y, x`` whose rows hold the kernel's reach in x: ``(3, N)``
    of ``kind``, each voxel's taken in one fixed order.  Voxels whose stencil stays inside the grid take every
    value from one index, that of their stencil's first corner, in views of the grid shifted by each offset: no
    index is computed for each of the stencil's values.
    """
    radius = len(smooth) // 2
    nz, ny, nx = grid.shape
    flat = grid.ravel()
    found = np.zeros((3, len(x)), kind)
    inside = bool(len(x)) and bool(radius <= z.min() and z.max() < nz - radius
                                   and radius <= y.min() and y.max() < ny - radius)
    if inside:
        corner = ((z - radius) * ny + y - radius) * nx + x - radius
    for dz in range(2 * radius + 1):
        if not inside:
            plane = np.clip(z + dz - radius, 0, nz - 1) * ny
        for dy in range(2 * radius + 1):
            if inside:
                row, values_of = corner, flat[(dz * ny + dy) * nx:]
            else:
                row, values_of = (plane + np.clip(y + dy - radius, 0, ny - 1)) * nx + x - radius, flat
            along, across = np.zeros(len(x), kind), np.zeros(len(x), kind)    # the x-derivative, x-smoothed sum
            for dx in range(2 * radius + 1):
                values = values_of[dx:].take(row).astype(kind)
                _add(along, kind(derive[dx]), values)
                _add(across, kind(smooth[dx]), values)
            _add(found[0], kind(smooth[dy] * smooth[dz]), along)
            _add(found[1], kind(derive[dy] * smooth[dz]), across)
            _add(found[2], kind(smooth[dy] * derive[dz]), across)
    return found


def _add(total, weight, values):
    """``total += weight * values``, without the product for a weight of 1 or -1 (the same sums, bit for bit)."""
    if weight == 1:
        total += values
    elif weight == -1:
        total -= values
    elif weight:
        total += weight * values


def _edge_sampler(grid):
    """``sample(points)`` of the grid's values, a point beyond its edge taking the edge's."""
    top = np.array(grid.shape[::-1]) - 1

    def sample(points):
        p = np.clip(points, 0, top)
        return grid[p[:, 2], p[:, 1], p[:, 0]]

    return sample


def _exact_in_float32(grid):
    """Whether every partial sum of a Sobel gradient of ``grid`` is a whole number below 2**24: 16-bit integers
    (32 times 65535 at most), for which float32 arithmetic in any order gives the float64 result.
    """
    return grid.dtype.kind in "uib" and grid.dtype.itemsize <= 2


def _dense_sobel_at(grid, voxels, smooth, derive, voxels_at_once=1 << 23):
    """:func:`_gradient_on_grid`'s Sobel gradient at ``voxels`` (sorted by z) of a 16-bit ``grid``, from the
    gradient of every voxel of a few slices at a time (separable sums of shifted slices, float32, edges repeated).
    """
    nz, ny, nx = grid.shape
    z, y, x = voxels
    gradient = np.empty((len(x), 3))
    per = max(1, voxels_at_once // (ny * nx))
    bounds = np.searchsorted(z, np.arange(0, nz + per, per))
    (s0, s1, s2), (d0, _, d2) = np.float32(smooth), np.float32(derive)       # float32 sums: no float64 copies
    for k, first in enumerate(range(0, nz, per)):
        lo, hi = bounds[k], bounds[k + 1]
        if lo == hi:
            continue
        last = min(first + per, nz)
        rows = np.clip(np.arange(first - 1, last + 1), 0, nz - 1)            # the slices, one beside on each side
        part = np.pad(grid[rows].astype(np.float32), ((0, 0), (1, 1), (1, 1)), mode="edge")
        across_z = s0 * part[:-2] + s1 * part[1:-1] + s2 * part[2:]
        along_z = d0 * part[:-2] + d2 * part[2:]
        across_zy = s0 * across_z[:, :-2] + s1 * across_z[:, 1:-1] + s2 * across_z[:, 2:]
        along_y = d0 * across_z[:, :-2] + d2 * across_z[:, 2:]
        along_z = s0 * along_z[:, :-2] + s1 * along_z[:, 1:-1] + s2 * along_z[:, 2:]
        at = ((z[lo:hi] - first) * ny + y[lo:hi]) * nx + x[lo:hi]
        gradient[lo:hi, 0] = (d0 * across_zy[:, :, :-2] + d2 * across_zy[:, :, 2:]).take(at)
        for axis, values in ((1, along_y), (2, along_z)):
            gradient[lo:hi, axis] = (s0 * values[:, :, :-2] + s1 * values[:, :, 1:-1] + s2 * values[:, :, 2:]).take(at)
    return gradient


def kept(segments):
    """The normals kept with ``segments``; when there are none (a binary input, an old ``.vxs``), those of the
    binary mask, built now and kept with them.
    """
    if segments.normals is None:
        segments.normals = surface_normals(segments.to_mask())
    return segments.normals


def normal_image(depth, view, shape, normals, segments=None, clip=None):
    """Unit normals ``(H, W, 3)`` in image space (toward the viewer: negative Z') at each pixel's hit point;
    NaN where the ray meets nothing or no normal is known.  Where the object was cut, by the volume's edge or
    by ``clip`` (:class:`~voxrender._render.clip.Clip`, with the ``segments`` it cut), the cut face's own normal
    (:func:`cut_normals`).
    """
    height, width = depth.shape
    out = np.full((height, width, 3), np.nan, np.float32)
    covered = np.isfinite(depth)
    if not covered.any():
        return out
    rows, columns, points = view.hit_points(depth, shape, beyond=1e-4)
    found = normals.at(points) @ view.matrix.T                       # object -> image space
    cut = cut_normals(view, points, shape, segments, clip)
    on_cut = np.isfinite(cut[:, 0])
    found[on_cut] = cut[on_cut]
    out[rows, columns] = found
    return out


def cut_normals(view, points, shape, segments=None, clip=None):
    """The image-space normals of the cut faces among hit points ``(N, 3)`` (x, y, z, just inside the object):
    NaN where a hit is on the object's own surface.

    A hit is on a cut face when the voxel the ray crossed just before it lies beyond the volume's edge (where a
    scan ends inside the body) or is a voxel of ``segments`` that ``clip`` removed.  Behind a cut the grey values
    are the tissue's, not a surface's, and their gradient would speckle it: a face cut by the clip's cut plane
    faces the viewer, one cut by the volume's edge or a clip limit faces out along its axis.

    >>> from voxrender.space.view import View
    >>> view = View(size=(1, 1), scale=1.0)                        # looking along +z
    >>> cut_normals(view, np.array([[1.0, 1.0, -0.4999], [1.0, 1.0, 1.5001]]), (3, 3, 3)).tolist()
    [[0.0, 0.0, -1.0], [nan, nan, nan]]
    """
    points = np.asarray(points, np.float64)
    out = np.full(points.shape, np.nan, np.float32)
    if clip is None or not clip.active:          # only the volume's edge cuts: look at the hits in its last half voxel
        chosen = np.flatnonzero(((points < 0) | (points > np.array(shape[::-1]) - 1)).any(axis=1))
    else:
        chosen = np.arange(len(points))
    inside = points[chosen]
    here = np.floor(inside + 0.5).astype(np.int64)
    there = np.floor(inside - 1.1e-3 * view.matrix[2] + 0.5).astype(np.int64)     # a step back along the ray
    beyond_edge = ((there < 0) | (there >= np.array(shape[::-1]))).any(axis=1)
    removed = np.zeros(len(here), bool)
    by_plane = np.zeros(len(here), bool)
    if clip is not None and clip.active and segments is not None:
        x, y, z = there.T
        removed = ~beyond_edge & ~clip.keeps(x, y, z, view, shape)
        removed[removed] = label_at(segments, x[removed], y[removed], z[removed]) > 0
        if clip.cut_depth is not None:       # removed by the cut plane rather than by a clip limit
            by_plane = removed & (view.to_image(x, y, z, shape)[2] < clip.cut_depth - 1e-9)
    across = (beyond_edge | removed) & ~by_plane & (there != here).any(axis=1)
    step = (there - here)[across]
    # the face the ray came in by: of the faces between the two voxels, the one the hit lies on
    gap = np.where(step != 0, np.abs(inside[across] - (here[across] + step / 2)), np.inf)
    axis = np.argmin(gap, axis=1)
    face = np.zeros(step.shape, np.float64)
    face[np.arange(len(step)), axis] = np.sign(step[np.arange(len(step)), axis])
    out[chosen[across]] = face @ view.matrix.T
    out[chosen[by_plane]] = (0.0, 0.0, -1.0)
    return out
