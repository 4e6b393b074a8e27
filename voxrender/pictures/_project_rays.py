"""What following parallel rays through a grey volume needs, for every projection (:mod:`._project`): the rays
within their limits (:class:`Rays`), the layers of voxels across their main axis and the volume's flat memory
(:class:`Layers`), slices read in place or in blocks (:class:`Slices`), and the value that leaves a fold unchanged.
"""

from __future__ import annotations

import copy
import os

import numpy as np

# Points this close (in input voxels) to a face count as on it: a ray that starts on a clip face or a volume face
# takes the voxel inside, whatever the rounding of its start.
ON_FACE = 1e-9
RAYS_PER_CHUNK = 1 << 16   # rays gathered at once in a layer: their temporaries stay in the cache
THREADS = min(2, os.cpu_count() or 1)


class Rays:
    """The rays that meet the volume within the limits: their pixels, start ``q0`` (input index of the point at
    ``Z' = 0``), the shared direction ``d`` (input index per unit of ``Z'``) and the interval ``[t0, t1]`` of
    ``Z'`` each keeps.
    """

    def __init__(self, input_shape, view, shape, step, clip, slab):
        xs, ys = view.pixel_centres()
        xs, ys = np.meshgrid(xs, ys)
        origin = view.to_object(xs.ravel(), ys.ravel(), 0.0, shape)          # object (x, y, z) at Z' = 0
        self.direction = view.matrix[2] * step
        q0 = [o * s for o, s in zip(origin, step, strict=True)]
        t0 = np.full(xs.size, -np.inf)
        t1 = np.full(xs.size, np.inf)
        # the volume's box, and the clip limits (object voxel indices, half-open) mapped to input indices
        limits = [[-0.5, n - 0.5] for n in input_shape[::-1]]
        for k, bounds in enumerate((clip.x, clip.y, clip.z) if clip is not None else ()):
            if bounds is not None:
                if bounds[0] is not None:
                    limits[k][0] = max(limits[k][0], (bounds[0] - 0.5) * step[k])
                if bounds[1] is not None:
                    limits[k][1] = min(limits[k][1], (bounds[1] - 0.5) * step[k])
        for k, (low, high) in enumerate(limits):
            if self.direction[k] == 0:
                inside = (q0[k] >= low) & (q0[k] <= high)
                t1[~inside] = -np.inf
            else:
                enter, leave = (low - q0[k]) / self.direction[k], (high - q0[k]) / self.direction[k]
                np.maximum(t0, np.minimum(enter, leave), out=t0)
                np.minimum(t1, np.maximum(enter, leave), out=t1)
        if clip is not None and clip.cut_depth is not None:
            np.maximum(t0, clip.cut_depth, out=t0)
        if slab is not None:
            np.maximum(t0, slab[0], out=t0)
            np.minimum(t1, slab[1], out=t1)
        self.pixels = np.flatnonzero(t1 > t0)
        self.count = self.pixels.size
        self.q0 = [q[self.pixels] for q in q0]
        self.t0, self.t1 = t0[self.pixels], t1[self.pixels]

    def reordered(self, order):
        """The same rays in another ``order`` (or some of them)."""
        rays = copy.copy(self)
        rays.count = len(order)
        rays.pixels, rays.t0, rays.t1 = self.pixels[order], self.t0[order], self.t1[order]
        rays.q0 = [q[order] for q in self.q0]
        return rays



def ignored(mode, dtype):
    """The value that leaves a fold unchanged: below every value for the maximum, above every value for the
    minimum (what NaN, infinite and absent voxels become).
    """
    if dtype.kind == "f":
        return -np.inf if mode == "mip" else np.inf
    if dtype.kind == "b":
        return False if mode == "mip" else True
    info = np.iinfo(dtype)
    return info.min if mode == "mip" else info.max



def finite(values, neutral):
    """A slice with its NaN and infinite voxels set to ``neutral`` (a copy only for float slices that have some)."""
    if values.dtype.kind == "f" and not np.isfinite(values).all():
        return np.where(np.isfinite(values), values, neutral)
    return values



def flat_memory(values):
    """A 1-D view of the memory holding ``values`` (no copy, whatever its strides: a cropped, transposed or
    flipped view of a volume) and the flat index of voxel ``(x, y, z)``: ``origin + x * ex + y * ey + z * ez``.
    """
    itemsize = values.itemsize
    if any(s % itemsize for s in values.strides):
        values = np.ascontiguousarray(values)                # odd strides (rare): a copy is the only way
    strides = [s // itemsize for s in values.strides]         # per array axis (z, y, x)
    low = [n - 1 if s < 0 else 0 for n, s in zip(values.shape, strides, strict=True)]
    span = sum(abs(s) * (n - 1) for n, s in zip(values.shape, strides, strict=True)) + 1
    start = values[tuple(slice(i, i + 1) for i in low)]
    flat = np.lib.stride_tricks.as_strided(start, shape=(span,), strides=(itemsize,), writeable=False)
    origin = -sum(i * s for i, s in zip(low, strides, strict=True))
    return flat, origin, tuple(strides[::-1])



class Layers:
    """What following the rays through the layers across axis ``a`` needs: the axes, the volume's flat memory and
    the rays' layers.
    """

    def __init__(self, values, rays):
        d = rays.direction
        self.a = int(np.argmax(np.abs(d)))
        self.b, self.c = (k for k in range(3) if k != self.a)      # c's voxels are further apart in memory
        self.sizes = values.shape[::-1]                              # (nx, ny, nz)
        self.flat, self.origin, self.strides = flat_memory(values)
        ends = np.stack([rays.q0[self.a] + rays.t0 * d[self.a], rays.q0[self.a] + rays.t1 * d[self.a]])
        n = self.sizes[self.a]
        # the layers each ray passes through for a positive length
        self.first = np.clip(np.floor(ends.min(axis=0) + 0.5 + ON_FACE), 0, n - 1).astype(np.intp)
        self.last = np.clip(np.ceil(ends.max(axis=0) + 0.5 - ON_FACE) - 1, self.first, n - 1).astype(np.intp)

    def gather(self, cells, mode, dtype):
        """The values of voxels ``cells`` (flat indices), NaN and infinite ones replaced by the fold's neutral value
        (for the maximum and minimum) or returned with a mask of the finite ones (for the mean).
        """
        found = self.flat.take(cells)
        if dtype.kind != "f":
            return found
        if mode == "mean":
            finite = np.isfinite(found)
            return np.where(finite, found, 0), finite
        return np.where(np.isfinite(found), found, ignored(mode, dtype))



def along(array, axis, index):
    """``array[..., index, ...]`` with ``index`` on ``axis``."""
    at = [slice(None)] * array.ndim
    at[axis] = index
    return array[tuple(at)]



class Slices:
    """The slices ``values[..., j, ...]`` across array ``axis``, asked for in increasing ``j``.  When the axis is the
    one along which voxels are next to each other in memory, a slice's voxels are each in a cache line (and a
    disk page) of their own: blocks of slices are then read at once, each line once, into a small array.
    """

    BLOCK = 16

    def __init__(self, values, axis, block=BLOCK):
        self.values, self.axis, self.BLOCK = values, axis, block
        others = [abs(s) for k, s in enumerate(values.strides) if k != axis]
        self.blocks = abs(values.strides[axis]) < min(others)
        self.start, self.block, self.memory = None, None, None

    def __getitem__(self, j):
        if not self.blocks:
            return along(self.values, self.axis, j)
        if self.start is None or not self.start <= j < self.start + self.BLOCK:
            self.start = j
            part = along(self.values, self.axis, slice(j, j + self.BLOCK))
            if self.memory is None:          # one array, filled again for each block (new memory is slow to touch)
                self.memory = np.empty(along(self.values, self.axis, slice(0, self.BLOCK)).shape, self.values.dtype)
            self.block = along(self.memory, self.axis, slice(0, part.shape[self.axis]))
            np.copyto(self.block, part)
        return along(self.block, self.axis, j - self.start)


def face_crossings(rays, layers):
    """Where each ray crosses the faces ``q_a = j - 1/2`` across the main axis: its minor indices + 1/2 there are
    ``A + j r`` (``A = q0 + 1/2 - (q0_a + 1/2) r`` per ray, ``r = d_b / d_a``, ``d_c / d_a``); ``(r_b, r_c,
    whole_b, whole_c, part_b, part_c, side)``, ``A``'s whole and fractional parts along b and c, and the side of the
    edges along a the ray passes on, ``F = f_b r_c - f_c r_b`` (compared with each edge's own).
    """
    a, b, c = layers.a, layers.b, layers.c
    d = rays.direction
    rb, rc = d[b] / d[a], d[c] / d[a]
    start_b = rays.q0[b] + 0.5 - (rays.q0[a] + 0.5) * rb
    start_c = rays.q0[c] + 0.5 - (rays.q0[a] + 0.5) * rc
    whole_b, whole_c = np.floor(start_b), np.floor(start_c)
    part_b, part_c = start_b - whole_b, start_c - whole_c
    return rb, rc, whole_b, whole_c, part_b, part_c, part_b * rc - part_c * rb
