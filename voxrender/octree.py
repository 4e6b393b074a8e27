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

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from .errors import InputError
from .output import atomic_output

__all__ = ["WHITE", "BLACK", "GREY", "RegionOctree", "build", "linear_octree", "code_strings", "codes_to_mask",
           "save", "load", "CHILD_OFFSETS", "morton"]

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

    def size(self, nodes):
        """Side in voxels of the node(s)."""
        return 1 << (self.n - self.level[nodes].astype(np.int64))

    def counts(self):
        """Nodes by colour, and by colour and level."""
        names = {WHITE: "white", BLACK: "black", GREY: "grey"}
        result = {names[c]: int((self.color == c).sum()) for c in names}
        result["by_level"] = {int(k): {names[c]: int(((self.level == k) & (self.color == c)).sum()) for c in names}
                              for k in range(self.n + 1)}
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
        low and high face (at its low corner) finds every pair.

        >>> tree = build(np.array([[[1, 0], [0, 0]], [[0, 0], [0, 1]]], bool))
        >>> low, high = tree.leaf_pairs[0]
        >>> sorted(zip(tree.origin[low, 0].tolist(), tree.origin[high, 0].tolist()))
        [(0, 1), (0, 1), (0, 1), (0, 1)]
        """
        leaves = np.flatnonzero(self.first_child < 0)
        codes = morton(self.origin[leaves])
        order = np.argsort(codes)
        leaves, codes = leaves[order], codes[order]
        origin, size = self.origin[leaves], self.size(leaves)
        side, count = 1 << self.n, len(self.color)
        pairs = []
        for axis in range(3):
            keys = []
            for step, from_low in ((size, True), (-1, False)):   # across the high face, then the low face
                across = origin.copy()
                across[:, axis] += step
                inside = (across[:, axis] >= 0) & (across[:, axis] < side)
                found = leaves[np.searchsorted(codes, morton(across[inside]), side="right") - 1]
                low, high = (leaves[inside], found) if from_low else (found, leaves[inside])
                keys.append(low * count + high)
            keys = np.sort(np.concatenate(keys))
            keys = keys[np.diff(keys, prepend=-1) != 0]
            pairs.append((keys // count, keys % count))
        return pairs

    @cached_property
    def white_leaves(self):
        """The white leaves, in node order: row ``k`` of :attr:`white_to_white` is node ``white_leaves[k]``."""
        return np.flatnonzero((self.color == WHITE) & (self.first_child < 0))

    @cached_property
    def white_to_white(self):
        """The steps through empty space: one sparse matrix per direction ``2 * axis + high`` (``high`` 1 for the
        neighbours on the high side), entry ``[k, m]`` 1 when white leaves ``white_leaves[k]`` and
        ``white_leaves[m]`` share part of a face that way.  One spare last row and column for graph searches to
        start from.

        >>> tree = build(np.array([[[1, 0], [0, 0]], [[0, 0], [0, 0]]], bool))   # voxel (0, 0, 0) black
        >>> corner = np.searchsorted(tree.white_leaves, 1 + 0)   # label 0: the white voxel at (1, 1, 1)
        >>> [m[corner].nnz for m in tree.white_to_white]         # one white neighbour on each low side
        [1, 0, 1, 0, 1, 0]
        """
        return self._white_rows(WHITE)

    @cached_property
    def white_to_black(self):
        """As :attr:`white_to_white`, to the black leaves across each face: entry ``[k, j]`` 1 when white leaf
        ``white_leaves[k]`` and black leaf ``j`` (a node number) share part of a face that way."""
        return self._white_rows(BLACK)

    def _white_rows(self, target_color):
        from scipy.sparse import csr_matrix   # imported here: only octree-ftb needs it, and it is slow to load

        white = self.color == WHITE
        rows = len(self.white_leaves) + 1
        number = np.full(len(self.color), -1, np.int64)       # node -> its number among the white leaves
        number[self.white_leaves] = np.arange(len(self.white_leaves))
        tables = []
        for low, high in self.leaf_pairs:
            for source, target in ((high, low), (low, high)):      # the low side first: direction 2 * axis
                keep = white[source] & (self.color[target] == target_color)
                source, target = number[source[keep]], target[keep]
                if target_color == WHITE:
                    target = number[target]
                shape = (rows, rows if target_color == WHITE else len(self.color))
                tables.append(csr_matrix((np.ones(len(source)), (source, target)), shape=shape))
        return tables

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


def morton(points):
    """Morton (Z-order) codes of integer ``(x, y, z)`` points: their bits interleaved, x lowest.

    Aligned cubes of the octree are contiguous ranges of codes, so a sorted list of leaf codes
    locates the leaf holding any voxel with one binary search.

    >>> morton(np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [3, 3, 3]])).tolist()
    [1, 2, 4, 63]
    """
    points = np.asarray(points, np.int64)
    codes = np.zeros(len(points), np.int64)
    for axis in range(3):
        spread = points[:, axis] & 0x1FFFFF                 # 21 bits, spread to every third bit
        for shift, keep in ((32, 0x1F00000000FFFF), (16, 0x1F0000FF0000FF), (8, 0x100F00F00F00F00F),
                            (4, 0x10C30C30C30C30C3), (2, 0x1249249249249249)):
            spread = (spread | (spread << shift)) & keep
        codes |= spread << axis
    return codes


def _pyramid(mask, n):
    """Per level k (0..n): which cells of side 2^(n-k) are all black and which are all white."""
    full, occupied = [None] * (n + 1), [None] * (n + 1)
    full[n], occupied[n] = mask, mask
    for k in range(n - 1, -1, -1):
        full[k] = _halve(full[k + 1], np.logical_and)
        occupied[k] = _halve(occupied[k + 1], np.logical_or)
    return full, [~cells for cells in occupied]


def _halve(cells, combine):
    """Combine each 2 x 2 x 2 block of ``cells`` into one (elementwise on strided views: much faster than a
    reduction over the axes of a 6-D reshape)."""
    cells = combine(cells[0::2], cells[1::2])
    cells = combine(cells[:, 0::2], cells[:, 1::2])
    return combine(cells[:, :, 0::2], cells[:, :, 1::2])


def build(mask):
    """The region octree of a bool mask ``[z, y, x]`` (padded with white to a ``2^n`` cube).

    Built top-down one level at a time from a pyramid of full and empty cells, so each
    level is a handful of array operations.
    """
    mask = np.asarray(mask, bool)
    if mask.ndim != 3 or not mask.size:
        raise InputError(f"an octree needs a 3-D mask, got shape {mask.shape}")
    n = max(0, int(np.ceil(np.log2(max(mask.shape)))))
    side = 1 << n
    padded = np.zeros((side, side, side), bool)
    padded[:mask.shape[0], :mask.shape[1], :mask.shape[2]] = mask
    full, empty = _pyramid(padded, n)
    colors, levels, origins, firsts = [], [], [], []
    cells = np.zeros((1, 3), np.int64)  # (x, y, z) in units of the level's cell
    start = 0
    for k in range(n + 1):
        x, y, z = cells.T
        color = np.where(full[k][z, y, x], BLACK, np.where(empty[k][z, y, x], WHITE, GREY)).astype(np.uint8)
        grey = np.flatnonzero(color == GREY)
        first = np.full(len(cells), -1, np.int64)
        first[grey] = start + len(cells) + 8 * np.arange(len(grey))
        colors.append(color)
        levels.append(np.full(len(cells), k, np.uint8))
        origins.append(cells << (n - k))
        firsts.append(first)
        start += len(cells)
        cells = (2 * cells[grey][:, None, :] + CHILD_OFFSETS[None]).reshape(-1, 3)
        if not len(cells):
            break
    return RegionOctree(n, tuple(mask.shape), np.concatenate(colors), np.concatenate(levels),
                        np.concatenate(origins), np.concatenate(firsts))


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


MAGIC = "voxrender-octree-1"


def save(tree, path):
    """Write a region octree (and its linear octree) to ``path`` (.vxo, NumPy's npz), atomically."""
    with atomic_output(path) as tmp, open(tmp, "wb") as f:
        np.savez(f, magic=np.array(MAGIC), n=tree.n, shape=np.array(tree.shape), color=tree.color,
                 level=tree.level, origin=tree.origin, first_child=tree.first_child, linear=linear_octree(tree))


def load(path):
    """Read a region octree written by :func:`save`."""
    try:
        with np.load(Path(path), allow_pickle=False) as data:
            if str(data["magic"]) != MAGIC:
                raise InputError(f"{path} is not a voxrender octree (.vxo)")
            return RegionOctree(int(data["n"]), tuple(int(v) for v in data["shape"]), data["color"], data["level"],
                                data["origin"], data["first_child"])
    except InputError:
        raise
    except (OSError, ValueError, KeyError) as exc:
        raise InputError(f"{path} is not a readable voxrender octree (.vxo): {type(exc).__name__}") from None
