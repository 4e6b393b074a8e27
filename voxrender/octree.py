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
from pathlib import Path

import numpy as np

from .errors import InputError
from .io import atomic_output

__all__ = ["WHITE", "BLACK", "GREY", "RegionOctree", "build", "linear_octree", "code_strings", "codes_to_mask",
           "save", "load", "CHILD_OFFSETS"]

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


def _pyramid(mask, n):
    """Per level k (0..n): which cells of side 2^(n-k) are all black and which are all white."""
    full, empty = [None] * (n + 1), [None] * (n + 1)
    full[n], empty[n] = mask, ~mask
    for k in range(n - 1, -1, -1):
        side = 1 << k
        full[k] = full[k + 1].reshape(side, 2, side, 2, side, 2).all(axis=(1, 3, 5))
        empty[k] = empty[k + 1].reshape(side, 2, side, 2, side, 2).all(axis=(1, 3, 5))
    return full, empty


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
