"""Octrees from a binary mask: the region octree and the linear octree of Gargantini.

The mask ``[z, y, x]`` is padded to a ``2^n`` cube.  Octants are labelled as in the
linear-octree paper's Table 1 (Chandran, Gupta and Patgawkar): east is +x, north is +y,
forward is +z, and

    label = 4 * backward + 2 * south + west        (0 = forward-north-east, 7 = backward-south-west)

so the label of a child is ``7 - (4 z_high + 2 y_high + x_high)`` with ``*_high`` its half.

:class:`RegionOctree` holds every node in flat arrays, level by level (no Python object per
node): colour (white, black, grey), level, origin and the index of the first of its eight
children (grey nodes only), children in label order.  :func:`linear_octree` lists the black
leaves as Gargantini codes: one octal digit per level, the marker X (> 7) for the levels
below a full octant, sorted.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import numpy as np

from .._shared.threads import on_threads
from ..errors import InputError
from .segments import expand_runs, ranges

WHITE, BLACK, GREY = 0, 1, 2
X_MARKER = 8  # the digit X, which sorts after 0..7


def _child_offsets():
    """``(x, y, z)`` half (0 low, 1 high) of each child label 0..7 (Table 1)."""
    offsets = np.zeros((8, 3), np.int64)
    for label in range(8):
        backward, south, west = (label >> 2) & 1, (label >> 1) & 1, label & 1
        offsets[label] = (1 - west, 1 - south, 1 - backward)
    return offsets


CHILD_OFFSETS = _child_offsets()


class Adjacency(NamedTuple):
    """Rows of neighbours, compressed (as CSR without values): row ``k`` is ``indices[indptr[k]:indptr[k + 1]]``.

    >>> table = Adjacency.from_pairs(np.array([2, 0, 2]), np.array([5, 7, 6]), rows=3)
    >>> table.row(2).tolist(), table.neighbours(np.array([0, 2])).tolist()
    ([5, 6], [7, 5, 6])
    """

    indptr: np.ndarray
    indices: np.ndarray

    @classmethod
    def from_pairs(cls, source, target, rows):
        """The table of ``rows`` rows holding, in row ``source[i]``, ``target[i]`` (in the pairs' order)."""
        index = np.int32 if max(rows, len(target)) < 2 ** 31 else np.int64
        order = np.argsort(source, kind="stable")
        indptr = np.zeros(rows + 1, index)
        np.cumsum(np.bincount(source, minlength=rows), out=indptr[1:])
        return cls(indptr, np.asarray(target, index)[order])

    def row(self, k):
        """The neighbours of row ``k``."""
        return self.indices[self.indptr[k]:self.indptr[k + 1]]

    def neighbours(self, rows):
        """The neighbours of every one of ``rows``, one after another."""
        return self.indices[ranges(self.indptr[rows], self.indptr[np.asarray(rows) + 1] - self.indptr[rows])]


@dataclass
class RegionOctree:
    """A region octree of a ``2^n`` cube in flat arrays (see the module docstring).

    Examples
    --------
    >>> tree = build(np.ones((2, 2, 2), bool))
    >>> tree.n, tree.color.tolist(), tree.counts()["black"]
    (1, [1], 1)
    """

    n: int
    shape: tuple                 # the mask's shape before padding
    color: np.ndarray            # WHITE, BLACK or GREY per node
    level: np.ndarray            # 0 for the root, n for single voxels
    origin: np.ndarray           # (x, y, z) of the node's low corner, in voxels
    first_child: np.ndarray      # index of the first of the eight children; -1 for leaves
    meta: dict = field(default_factory=dict)
    stored: dict = field(default_factory=dict, repr=False, compare=False)   # derived arrays read from a file

    def size(self, nodes):
        """Side in voxels of the node(s)."""
        return 1 << (self.n - self.level[nodes].astype(np.int64))

    def counts(self):
        """Nodes by colour, and by colour and level."""
        names = {WHITE: "white", BLACK: "black", GREY: "grey"}
        table = np.bincount(np.asarray(self.level, np.int64) * 3 + self.color,
                            minlength=3 * (self.n + 1)).reshape(self.n + 1, 3)      # one pass, not one per cell
        result = {names[c]: int(table[:, c].sum()) for c in names}
        result["by_level"] = {k: {names[c]: int(table[k, c]) for c in names} for k in range(self.n + 1)}
        return result

    @cached_property
    def parent(self):
        """Index of each node's parent (-1 for the root)."""
        parent = np.full(len(self.color), -1, np.int64)
        grey = np.flatnonzero(self.first_child >= 0)
        parent[self.first_child[grey][:, None] + np.arange(8)] = grey[:, None]
        return parent

    @cached_property
    def level_starts(self):
        """``level_starts[k]:level_starts[k + 1]`` are the nodes of level ``k`` (stored level by level)."""
        return np.searchsorted(self.level, np.arange(self.n + 2))

    @cached_property
    def leaf_pairs(self):
        """Face-adjacent leaves: for each axis (x, y, z), ``(low, high)`` arrays of leaf pairs that share part
        of a face perpendicular to the axis, ``low`` on its low side.

        Of two adjacent leaves, one face holds the other's, so looking up the leaf just across each leaf's
        low and high face (at its low corner) finds every pair: from the smaller of the two (from the low one
        when they are the same size), which is how each pair is kept once.

        >>> tree = build(np.array([[[1, 0], [0, 0]], [[0, 0], [0, 1]]], bool))
        >>> low, high = tree.leaf_pairs[0]
        >>> sorted(zip(tree.origin[low, 0].tolist(), tree.origin[high, 0].tolist()))
        [(0, 1), (0, 1), (0, 1), (0, 1)]
        """
        leaves, codes = self.leaves_by_code
        origin, size = self.origin[leaves], self.size(leaves)
        side = 1 << self.n

        def axis_pairs(axis):
            low, high = [], []
            bits = _SPREAD[-1] << axis                           # the code bits of this axis
            for from_low in (True, False):                       # across the high face, then the low face
                # the code of the point across: add to this axis's bits alone (a dilated integer sum); off the
                # cube's side it wraps round, and is dropped below
                if from_low:
                    inside = origin[:, axis] + size < side
                    moved = ((codes | ~bits) + (_SPREAD[size] << axis)) & bits
                else:
                    inside = origin[:, axis] > 0
                    moved = ((codes & bits) - (1 << axis)) & bits
                found = np.searchsorted(codes, (codes & ~bits) | moved, side="right") - 1
                # the face of the smaller leaf lies in the other's; a pair of equals is kept from the low one
                kept = np.flatnonzero(inside & ((size[found] >= size) if from_low else (size[found] > size)))
                mine, theirs = leaves[kept], leaves[found[kept]]
                low.append(mine if from_low else theirs)
                high.append(theirs if from_low else mine)
            return np.concatenate(low), np.concatenate(high)

        return on_threads(axis_pairs, range(3))

    @cached_property
    def leaves_by_code(self):
        """The leaves in ascending Morton order of their low corners, and those codes."""
        side = 1 << self.n
        if side > len(_SPREAD):
            raise InputError(f"an octree of side {side} is beyond the {len(_SPREAD)} voxels voxrender can index")
        # each level is stored in descending Morton order: reversed, the leaves are ascending runs, which a
        # merge sort joins in a pass or two (a quicksort takes 15 times as long)
        leaves = np.flatnonzero(self.first_child < 0)[::-1]
        codes = _morton(self.origin[leaves])
        order = np.argsort(codes, kind="stable")
        return leaves[order], codes[order]

    @cached_property
    def linear(self):
        """The linear octree (:func:`linear_octree`), as kept in a file or made now.

        Made from the Morton codes of the leaves, without a sort of its own: a digit of a code is 7 minus the
        Morton digit at that depth, and two disjoint leaves differ in a digit both have, so the codes' order
        is the black leaves' descending Morton order.
        """
        if "octree_linear" in self.stored:
            return self.stored["octree_linear"].reshape(-1, self.n)
        leaves, codes = self.leaves_by_code
        black = self.color[leaves] == BLACK
        codes, level = codes[black][::-1], self.level[leaves[black]][::-1]
        digits = np.empty((len(codes), self.n), np.uint8)
        for d in range(self.n):
            digits[:, d] = np.where(level > d, 7 - ((codes >> 3 * (self.n - 1 - d)) & 7), X_MARKER)
        return digits

    @cached_property
    def white_leaves(self):
        """The white leaves, in node order: row ``k`` of :attr:`white_to_white` is node ``white_leaves[k]``."""
        return np.flatnonzero((self.color == WHITE) & (self.first_child < 0))

    @cached_property
    def white_to_white(self):
        """The steps through empty space: one :class:`Adjacency` per direction ``2 * axis + high`` (``high`` 1
        for the neighbours on the high side); row ``k`` lists the numbers ``m`` of the white leaves
        ``white_leaves[m]`` that share part of a face with ``white_leaves[k]`` that way.

        >>> tree = build(np.array([[[1, 0], [0, 0]], [[0, 0], [0, 0]]], bool))   # voxel (0, 0, 0) black
        >>> corner = np.searchsorted(tree.white_leaves, 1 + 0)   # label 0: the white voxel at (1, 1, 1)
        >>> [len(a.row(corner)) for a in tree.white_to_white]   # one white neighbour on each low side
        [1, 0, 1, 0, 1, 0]
        """
        return self._white_rows(WHITE)

    @cached_property
    def white_to_black(self):
        """As :attr:`white_to_white`, to the black leaves across each face: row ``k`` lists the node numbers of
        the black leaves that share part of a face with white leaf ``white_leaves[k]`` that way.
        """
        return self._white_rows(BLACK)

    def _white_rows(self, target_color):
        kind = "white" if target_color == WHITE else "black"
        if f"octree_{kind}0_indptr" in self.stored:                 # kept in the file: no search
            return [Adjacency(*(self.stored[f"octree_{kind}{direction}_{part}"] for part in ("indptr", "indices")))
                    for direction in range(6)]
        return self._white_tables[target_color]

    @cached_property
    def _white_tables(self):
        """Both :attr:`white_to_white` and :attr:`white_to_black`, made in one pass over the leaf pairs."""
        white = self.color == WHITE
        number = np.full(len(self.color), -1, np.int64)       # node -> its number among the white leaves
        number[self.white_leaves] = np.arange(len(self.white_leaves))
        # the low side first: direction 2 * axis
        directions = [pair for low, high in self.leaf_pairs for pair in ((high, low), (low, high))]

        def tables(pair):
            source, target = pair
            source, target = source[white[source]], target[white[source]]
            found = {}
            for color in (WHITE, BLACK):
                keep = self.color[target] == color
                ends = number[target[keep]] if color == WHITE else target[keep]
                found[color] = Adjacency.from_pairs(number[source[keep]], ends, len(self.white_leaves))
            return found

        made = on_threads(tables, directions)
        return {color: [table[color] for table in made] for color in (WHITE, BLACK)}

    def to_mask(self):
        """The (unpadded) mask ``[z, y, x]`` again."""
        side = 1 << self.n
        mask = np.zeros((side, side, side), bool)
        for node in np.flatnonzero(self.color == BLACK):
            x, y, z = self.origin[node]
            s = 1 << (self.n - int(self.level[node]))
            mask[z:z + s, y:y + s, x:x + s] = True
        nz, ny, nx = self.shape
        return mask[:nz, :ny, :nx]


def _spread_table(bits=11):
    """The numbers ``0 .. 2^bits - 1`` with their bits spread to every third bit."""
    values = np.arange(1 << bits, dtype=np.int64)
    spread = np.zeros_like(values)
    for bit in range(bits):
        spread |= ((values >> bit) & 1) << (3 * bit)
    return spread


_SPREAD = _spread_table()


def _morton(points):
    """Morton (Z-order) codes of integer ``(x, y, z)`` points (below 2^21): their bits interleaved, x lowest.

    Aligned cubes of the octree are contiguous ranges of codes, so a sorted list of leaf codes
    locates the leaf holding any voxel with one binary search.

    >>> _morton(np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [3, 3, 3]])).tolist()
    [1, 2, 4, 63]
    """
    points = np.asarray(points)
    return _interleave(*(points[:, axis] for axis in range(3))) if len(points) else np.zeros(0, np.int64)


def _interleave(x, y, z):
    """:func:`_morton` of the points with coordinate arrays ``x, y, z``."""
    codes = np.zeros(len(x), np.int64)
    for axis, value in enumerate((x, y, z)):          # 11 bits at a time, from a table
        value = np.asarray(value, np.int64)
        spread = _SPREAD[value & 0x7FF]
        if len(value) and int(value.max()) >= 0x800:
            spread |= _SPREAD[(value >> 11) & 0x3FF] << 33
        codes |= spread << axis
    return codes


def _unmorton(codes):
    """The integer ``(x, y, z)`` points of Morton codes: the inverse of :func:`_morton`.

    >>> _unmorton(_morton(np.array([[5, 3, 9]]))).tolist()
    [[5, 3, 9]]
    """
    codes = np.asarray(codes, np.int64)
    points = np.empty((len(codes), 3), np.int32)                 # below 2^21: half the memory of int64
    for axis in range(3):
        bits = (codes >> axis) & 0x1249249249249249
        for shift, keep in ((2, 0x10C30C30C30C30C3), (4, 0x100F00F00F00F00F), (8, 0x1F0000FF0000FF),
                            (16, 0x1F00000000FFFF), (32, 0x1FFFFF)):
            bits = (bits | (bits >> shift)) & keep
        points[:, axis] = bits
    return points


def build(mask):
    """The region octree of a bool mask ``[z, y, x]`` (padded with white to a ``2^n`` cube).

    >>> tree = build(np.array([[[1, 1], [1, 1]], [[1, 1], [1, 0]]], bool))
    >>> tree.color.tolist()     # the root is grey; its children in label order, the missing voxel first
    [2, 0, 1, 1, 1, 1, 1, 1, 1]
    """
    mask = np.asarray(mask, bool)
    if mask.ndim != 3 or not mask.size:
        raise InputError(f"an octree needs a 3-D mask, got shape {mask.shape}")
    z, y, x = np.nonzero(mask)
    return build_from_voxels(np.stack([x, y, z], axis=1), mask.shape)


def build_from_segments(segments):
    """The region octree of run-length :class:`~voxrender.object.segments.Segments`, without making their mask: the
    work and memory grow with the object, not with the octree's cube.
    """
    segments.check()
    ny = segments.shape[1]
    row, x = expand_runs(segments.run_rows(), segments.starts, segments.ends)
    return _build(_interleave(x, row % ny, row // ny), segments.shape)


# What the build of an octree takes (build_bytes), measured with tracemalloc on spheres, boxes, smooth porous,
# gyroid and random objects of 32^3 to 256^3, gyroids of 384^3 and 512^3 and the CT head's bone and skin: the
# Morton codes of the voxels and their sort take about 64 bytes a voxel (72 counted, for a margin); the nodes, the
# leaf pairs and the adjacency tables about 800 bytes a run on two threads (each thread of the face search holds
# its own temporaries: 150 bytes a run each, up to the six directions), more for scattered short runs, each at the
# end of its own path of grey nodes: a factor 1 + 2.8 log8(grid / voxels) / (voxels per run).  The estimate is 1.05
# to 2.3 times the measured peak on all of them.
_BUILD_BYTES_PER_VOXEL = 72
_BUILD_BYTES_PER_RUN = 500
_BUILD_BYTES_PER_RUN_AND_THREAD = 150
_BUILD_SCATTER_FACTOR = 2.8
_BUILD_BYTES_FIXED = 1_000_000


def build_bytes(segments, threads=None):
    """An estimate of the peak memory, in bytes, that building the region octree of ``segments``, its linear
    octree and the face adjacency of its leaves takes (:func:`build_from_segments`, :func:`sections`), from the
    object's counts and grid alone: nothing is built.

    Measured as an upper bound, within a factor of about 2, for objects whose runs are not much longer than their
    features are wide (bone, porous solids, organs, noise).  An object of thin layers across its rows (plates one
    voxel thick, parallel to x) has far more octree nodes than runs, and may need several times the estimate.

    Parameters
    ----------
    segments : Segments
        The object.
    threads : int, optional
        The threads the face search runs on (default: this machine's cores, as :func:`on_threads` takes).

    Examples
    --------
    >>> from voxrender.object.segments import encode
    >>> ball = encode(np.ones((32, 32, 32), bool))
    >>> build_bytes(ball, threads=2) > 64 * ball.voxel_count
    True
    """
    nz, ny, nx = segments.shape
    runs = segments.segment_count
    # the voxels without Segments.voxel_count's two int64 copies of the runs (sums in NumPy's small buffers)
    voxels = int(np.sum(segments.ends, dtype=np.int64)) - int(np.sum(segments.starts, dtype=np.int64)) + runs
    threads = min(threads or os.cpu_count() or 1, 6)
    per_run = _BUILD_BYTES_PER_RUN + _BUILD_BYTES_PER_RUN_AND_THREAD * threads
    scattered = 1 + _BUILD_SCATTER_FACTOR * math.log(nz * ny * nx / voxels, 8) * runs / voxels if voxels else 1
    return int(_BUILD_BYTES_FIXED + 16 * nz * ny + _BUILD_BYTES_PER_VOXEL * voxels + per_run * scattered * runs)


def check_build_memory(segments, max_memory):
    """Refuse to build the octree of ``segments`` when its estimate (:func:`build_bytes`) is over ``max_memory``
    bytes: an :class:`InputError` naming both and what to do instead, before anything is allocated.

    Examples
    --------
    >>> from voxrender.object.segments import encode
    >>> check_build_memory(encode(np.ones((4, 4, 4), bool)), 2 ** 30)
    >>> try:
    ...     check_build_memory(encode(np.ones((4, 4, 4), bool)), 1000)
    ... except InputError as refusal:
    ...     print(refusal.parameter, refusal.message[:73])
    max_memory the region octree of this object (4x4x4 voxels, 16 runs) would take about
    """
    from .._shared.text import in_words

    needed = build_bytes(segments)
    if needed > max_memory:
        grid = "x".join(str(n) for n in segments.shape)
        raise InputError(f"the region octree of this object ({grid} voxels, {segments.segment_count:,} runs) would "
                         f"take about {in_words(needed)} to build, more than the {in_words(int(max_memory))} of "
                         "memory allowed; encode the stack binned by 2 (a quarter of the runs), or render it with a "
                         "method that needs no octree (ftb, btf, raycast), or allow more memory",
                         parameter="max_memory")


def build_from_voxels(points, shape):
    """The region octree of the voxels ``points`` (``(N, 3)`` x, y, z) of a ``shape = (nz, ny, nx)`` grid.

    Bottom-up over Morton codes: a cell is black when its eight children are, grey when it holds a black voxel
    but is not black; a node is kept when its parent is grey.  Nodes are stored level by level, each grey
    node's children together in label order (label = 7 - the child's Morton digit), so a level is its cells in
    descending Morton order.
    """
    return _build(_morton(points), shape)


def _build(codes, shape):
    """:func:`build_from_voxels` from the voxels' Morton codes."""
    n = max(0, int(np.ceil(np.log2(max(shape)))))
    codes = _distinct(np.sort(codes, kind="stable"))   # raster order holds long sorted runs
    full, occupied = [None] * (n + 1), [None] * (n + 1)
    full[n] = occupied[n] = codes
    for k in range(n, 0, -1):                       # cells of level k - 1: full when all 8 children are
        parents = full[k] >> 3
        first = np.flatnonzero(np.r_[True, parents[1:] != parents[:-1]]) if len(parents) else parents
        full[k - 1] = parents[first][np.diff(np.r_[first, len(parents)]) == 8]
        occupied[k - 1] = _distinct(occupied[k] >> 3)
    colors, levels, origins, firsts = [], [], [], []
    cells = np.zeros(1, np.int64)                   # this level's cells, Morton codes at its resolution
    start = 0
    for k in range(n + 1):
        black = _member(cells, full[k])
        grey = _member(cells, occupied[k]) & ~black
        color = np.where(black, BLACK, np.where(grey, GREY, WHITE)).astype(np.uint8)
        grey = np.flatnonzero(grey)
        first = np.full(len(cells), -1, np.int64)
        first[grey] = start + len(cells) + 8 * np.arange(len(grey))
        colors.append(color)
        levels.append(np.full(len(cells), k, np.uint8))
        origins.append(_unmorton(cells) << (n - k))
        firsts.append(first)
        start += len(cells)
        cells = ((cells[grey] << 3)[:, None] + np.arange(7, -1, -1)).ravel()
        if not len(cells):
            break
    return RegionOctree(n, tuple(shape), np.concatenate(colors), np.concatenate(levels),
                        np.concatenate(origins), np.concatenate(firsts))


def _distinct(sorted_values):
    """The distinct values of a sorted array."""
    return sorted_values[np.r_[True, sorted_values[1:] != sorted_values[:-1]]] if len(sorted_values) else \
        sorted_values


def _member(values, sorted_set):
    """Which of ``values`` are in the sorted array ``sorted_set``."""
    if not len(sorted_set):
        return np.zeros(len(values), bool)
    found = np.minimum(np.searchsorted(sorted_set, values), len(sorted_set) - 1)
    return sorted_set[found] == values


def _codes_of(tree, nodes):
    """Gargantini codes (one digit per level, X below the node's level) of ``nodes``, as digit arrays."""
    digits = np.full((len(nodes), tree.n), X_MARKER, np.int64)
    origin, level = tree.origin[nodes], tree.level[nodes].astype(np.int64)
    for d in range(tree.n):
        bit = tree.n - 1 - d                 # the origin bit that chooses the child at depth d + 1
        high = (origin >> bit) & 1
        label = 7 - (4 * high[:, 2] + 2 * high[:, 1] + high[:, 0])
        digits[:, d] = np.where(level > d, label, X_MARKER)
    return digits


def linear_octree(tree):
    """The sorted Gargantini codes of the black leaves, as an array ``(m, n)`` of digits (X = 8).

    >>> from voxrender.samples import STAIRCASE_VOXELS
    >>> mask = np.zeros((4, 4, 4), bool)
    >>> for x, y, z in STAIRCASE_VOXELS: mask[z, y, x] = True
    >>> code_strings(linear_octree(build(mask)))
    ['0X', '10', '24', '40']
    """
    digits = _codes_of(tree, np.flatnonzero(tree.color == BLACK))
    if tree.n == 0:  # a single voxel: its code has no digits
        return digits
    if tree.n <= 19:                  # the codes as base-9 numbers fit 63 bits: one sort, not n
        key = np.zeros(len(digits), np.int64)
        for column in np.ascontiguousarray(digits.T):      # Horner's rule (an integer matmul has no BLAS)
            key = key * 9 + column
        return digits[np.argsort(key)]
    return digits[np.lexsort(digits.T[::-1])]


def code_strings(codes):
    """Digit arrays as the paper writes codes (``'0X'``)."""
    return ["".join("X" if d == X_MARKER else str(int(d)) for d in row) for row in codes]


def codes_to_mask(codes, n):
    """The ``2^n`` cube that a list of codes describes (black where a code covers)."""
    side = 1 << n
    mask = np.zeros((side, side, side), bool)
    for row in np.asarray(codes):
        low = np.zeros(3, np.int64)
        size = side
        for d in row:
            if d == X_MARKER:
                break
            size //= 2
            low += CHILD_OFFSETS[int(d)] * size
        x, y, z = low
        mask[z:z + size, y:y + size, x:x + size] = True
    return mask


def sections(tree):
    """The region octree, its linear octree and the face adjacency of its white leaves as named arrays, for a
    ``.vxs`` file (:func:`voxrender.object.vxs.save`); :func:`from_sections` maps them back without copying.
    """
    index = "<i4" if 8 * len(tree.color) < 2 ** 31 else "<i8"     # node numbers and counts of neighbours
    arrays = {"octree_n": np.array([tree.n], "<i8"), "octree_color": np.asarray(tree.color, "u1"),
              "octree_level": np.asarray(tree.level, "u1"), "octree_origin": np.asarray(tree.origin, "<i4"),
              "octree_first_child": np.asarray(tree.first_child, index),
              "octree_linear": np.asarray(tree.linear, "u1")}
    for kind, tables in (("white", tree.white_to_white), ("black", tree.white_to_black)):
        for direction, table in enumerate(tables):
            arrays[f"octree_{kind}{direction}_indptr"] = np.asarray(table.indptr, index)
            arrays[f"octree_{kind}{direction}_indices"] = np.asarray(table.indices, index)
    return arrays


_SECTIONS = ("octree_n", "octree_color", "octree_level", "octree_origin", "octree_first_child", "octree_linear",
             *(f"octree_{kind}{direction}_{part}" for kind in ("white", "black") for direction in range(6)
               for part in ("indptr", "indices")))


def from_sections(arrays, shape, source="the file"):
    """The :class:`RegionOctree` kept in a ``.vxs`` file's ``arrays`` (see :func:`sections`), or ``None`` when it
    holds none; ``shape`` is the object's grid, ``source`` names the file in the error a damaged one gets.
    """
    if not any(name in arrays for name in _SECTIONS):
        return None
    missing = [name for name in _SECTIONS if name not in arrays]
    nodes = len(arrays["octree_color"]) if "octree_color" in arrays else -1
    n = int(arrays["octree_n"][0]) if "octree_n" in arrays and len(arrays["octree_n"]) == 1 else -1
    if (missing or not 0 <= n <= 31 or 2 ** n < max(shape) or arrays["octree_origin"].size != 3 * nodes
            or not len(arrays["octree_level"]) == len(arrays["octree_first_child"]) == nodes
            or arrays["octree_linear"].size % max(n, 1)):
        what = f"its section {missing[0]} is missing" if missing else "its octree sections do not fit together"
        raise InputError(f"{source} is a damaged .vxo file: {what}; encode the object again")
    if not _values_fit(arrays, n, nodes):
        raise InputError(f"{source} is a damaged .vxo file: its octree holds values out of range; "
                         "encode the object again")
    return RegionOctree(n, tuple(shape), arrays["octree_color"], arrays["octree_level"],
                        arrays["octree_origin"].reshape(-1, 3), arrays["octree_first_child"], stored=arrays)


def _values_fit(arrays, n, nodes):
    """Whether a file's octree sections hold only values a renderer can index by: colours and levels in range,
    children within the node table (a grey node's, none for a leaf), origins in the cube, Gargantini digits, and
    adjacency rows within their tables.  A few passes over each array, so that a damaged file gets a line, not
    an index error in a renderer; an octree that is whole but of another object is not found this way.
    """
    color, level, first = arrays["octree_color"], arrays["octree_level"], arrays["octree_first_child"]
    origin, linear = arrays["octree_origin"], arrays["octree_linear"]
    if nodes and (color.max() > GREY or level.max() > n or np.any(level[1:] < level[:-1])
                  or first.min() < -1 or first.max() > nodes - 8 or np.any((first >= 0) != (color == GREY))
                  or origin.min() < 0 or origin.max() >= 1 << n):
        return False
    if linear.size and linear.max() > X_MARKER:
        return False
    whites = int(np.count_nonzero((color == WHITE) & (first < 0))) if nodes else 0
    for kind, bound in (("white", whites), ("black", nodes)):
        for direction in range(6):
            indptr, indices = (arrays[f"octree_{kind}{direction}_{part}"] for part in ("indptr", "indices"))
            if (indptr.size != whites + 1 or indptr[0] != 0 or indptr[-1] != indices.size
                    or np.any(indptr[1:] < indptr[:-1])
                    or indices.size and (indices.min() < 0 or indices.max() >= bound)):
                return False
    return True
