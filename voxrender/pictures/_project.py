"""Projections of a grey volume along a view: the maximum (MIP), minimum (MinIP) and mean of the values along
each pixel's ray.

The picture is the one the surface renderers draw (the view contract of ``docs/design.md``): the same pixel
centres, the same object space; only the value a ray takes differs.  An input voxel is the closed unit box
(in input index units) centred on its integer index, as the surface methods see voxels; a ray takes the
maximum, minimum or path-length-weighted mean of the values of the voxels it passes through, counting only
the parts of the ray inside the volume, the clip limits and the slab.  That is the limit of sampling the ray
ever more densely with nearest-neighbour look-ups, and it is computed exactly: the ray is cut at every face
it crosses.
"""

from __future__ import annotations

import copy
import math
import os

import numpy as np

from .._shared.threads import on_threads
from ..errors import InputError

PROJECTIONS = ("mip", "minip", "mean")

# Points this close (in input voxels) to a face count as on it: a ray that starts on a clip face or a volume face
# takes the voxel inside, whatever the rounding of its start.
_ON_FACE = 1e-9
_RAYS_PER_CHUNK = 1 << 16   # rays gathered at once in a layer: their temporaries stay in the cache
_THREADS = min(2, os.cpu_count() or 1)
_SKIP = True              # skip the blocks of faces that cannot change a ray's maximum (minimum); False: every face
_BLOCK_FACES = 16         # faces per block
_TILE = 4                 # the blocks' bounds are per tile of _TILE x _TILE voxels across the main axis
# a block's rays are read straight from the volume when fewer than a slice's pixels over this: (slices read in
# place, slices read in blocks, which cost more a pixel)
_PAIRS_PER_PIXEL = (200, 10)


def project(values, view, mode="mip", *, shape=None, step=(1.0, 1.0, 1.0), clip=None, slab=None, progress=None):
    """The maximum, minimum or mean of the grey values along each pixel's ray.

    Parameters
    ----------
    values : (nz, ny, nx) array
        Grey values on their own grid (int or float; a read-only memory map is fine: it is read, never copied).
        NaN and infinite voxels are ignored.
    view : voxrender.space.view.View
        The view, with its ``scale`` set (e.g. the fitted view of the surface picture).
    mode : {"mip", "minip", "mean"}
        Maximum intensity projection, minimum intensity projection, or the path-length-weighted mean.
    shape : (nz, ny, nx), optional
        The object grid the view is of (cubic voxels; default ``values.shape``): image space and the volume
        centre are this grid's, as for the surface picture.
    step : (sx, sy, sz)
        The object voxel over the input spacing, per axis: object point ``(x, y, z)`` lies at continuous input
        index ``(x * sx, y * sy, z * sz)``; ``(1, 1, 1)`` when the object grid is the input's.
    clip : voxrender._render.Clip, optional
        Clip limits (object voxel indices, half-open: object points with ``lo - 1/2 <= x < hi - 1/2`` are kept)
        and the cut depth (points with ``Z' >= cut_depth`` are kept).
    slab : (z_lo, z_hi), optional
        Keep only the part of each ray with ``z_lo <= Z' <= z_hi`` (object voxels).
    progress : callable, optional
        ``progress(iterable, length, label)`` wraps the loop over layers of voxels.

    Returns
    -------
    (H, W) float32 array
        Each pixel's ray value; NaN where the ray meets no (finite) voxel within the limits.

    Notes
    -----
    What a ray counts (cube semantics, as the surface methods see voxels): an input voxel is the closed box of
    side 1 (input index units) centred on its integer index; the ray takes the values of the voxels whose boxes
    it passes through for a positive length, counting only the parts of it inside the volume, the clip limits and
    the slab.  The maximum and minimum are those of these values; the mean weights each by the length of the ray
    within its box.  That is the limit of sampling the ray ever more densely with the nearest voxel
    (``round(q)``) at each sample, the mean of uniform samples included.  A ray running exactly along a face
    between voxels (a tie of that rounding) takes the voxels on one side of it.

    How: the voxels a ray passes through are its 6-connected discrete line [1]_.  All rays are parallel: in input
    index space they share one direction ``d``.  They are followed through the layers of voxels across the axis
    ``d`` runs most along, one face between layers at a time and all rays at once (NumPy passes over them, in
    runs of faces on two threads): within a layer a ray moves at most one voxel along each of the other two
    axes, so it passes through at most three voxels, the one where it enters the layer, the one where it leaves
    it and, when it crosses a face along both other axes, the one between the two crossings (see
    :func:`_fold_whole_layers`).  A ray's first and last layers, which it may enter or leave through a limit, are
    cut at every face one by one.  Views along an axis (the presets) take one reduction of the kept box along
    that axis instead.

    The maximum and minimum skip what cannot change a ray's answer, as maximum intensity ray casters leap over
    space [2]_: the faces are cut into blocks, each ray gets a bound of the voxels it can meet in each block (from
    the block's maximum over tiles of voxels, :func:`_block_bounds`), takes its exact value over its most
    promising block first, and then follows only the blocks whose bound beats what it holds
    (:func:`_fold_skipping`).  The answer is the one every face gives, bit for bit; the mean follows every face.

    References
    ----------
    .. [1] D. Cohen-Or, A. Kaufman, "3D line voxelization and connectivity control", IEEE Computer Graphics and
       Applications 17(6), 1997: the 6-connected line, which holds every voxel a line passes through.
    .. [2] L. Mroz, H. Hauser, E. Groeller, "Interactive high-quality maximum intensity projection", Computer
       Graphics Forum 19(3), 2000: voxels that cannot be a ray's maximum are left out of its projection.

    Examples
    --------
    >>> from voxrender.space.view import View
    >>> values = np.arange(24).reshape(2, 3, 4)
    >>> project(values, View.preset("anterior", size=(2, 4), scale=1.0)).tolist()   # max over y; z up
    [[20.0, 21.0, 22.0, 23.0], [8.0, 9.0, 10.0, 11.0]]
    """
    if mode not in PROJECTIONS:
        raise InputError(f"unknown projection {mode!r}; choose one of {', '.join(PROJECTIONS)}",
                         parameter="projection")
    if view.scale is None:
        raise InputError("the view has no scale: give it one, or fit it to the volume first (View.fitted)",
                         parameter="scale")
    values = _volume(values)
    shape = values.shape if shape is None else _shape(shape)
    step = _step(step)
    slab = _slab(slab)
    height, width = view.size
    rays = _Rays(values.shape, view, shape, step, clip, slab)
    picture = np.full(height * width, np.nan, np.float32)
    if rays.count:
        axis_aligned = np.count_nonzero(rays.direction) == 1
        fold = _project_along_axis if axis_aligned else _project_through_layers
        picture[rays.pixels] = fold(values, rays, mode, progress)
    return picture.reshape(height, width)


def depth_range(view, shape):
    """``(Z'min, Z'max)``: the depths the box of a ``shape = (nz, ny, nx)`` volume's voxels spans in this view.

    >>> from voxrender.space.view import View
    >>> depth_range(View(), (4, 6, 8))
    (-2.0, 2.0)
    >>> [round(z, 3) for z in depth_range(View(alpha=45), (4, 4, 4))]
    [-2.828, 2.828]
    """
    nz, ny, nx = shape
    corners = np.array(np.meshgrid((-0.5, nx - 0.5), (-0.5, ny - 0.5), (-0.5, nz - 0.5))).reshape(3, -1)
    depths = view.to_image(*corners, shape)[2]
    return float(depths.min()), float(depths.max())


def _volume(values):
    if not hasattr(values, "ndim") or values.ndim != 3 or min(values.shape) < 1:
        raise InputError(f"values must be a 3-D array [z, y, x] of at least one voxel, not "
                         f"{getattr(values, 'shape', type(values).__name__)}", parameter="values")
    if values.dtype.kind not in "biuf":
        raise InputError(f"values must be numbers (int or float), not {values.dtype}", parameter="values")
    return values


def _shape(shape):
    try:
        shape = tuple(int(n) for n in shape)
    except (TypeError, ValueError):
        shape = ()
    if len(shape) != 3 or min(shape) < 1:
        raise InputError("the object grid must be three positive sizes (nz, ny, nx)", parameter="shape")
    return shape


def _step(step):
    try:
        step = np.array(step, dtype=float)
    except (TypeError, ValueError):
        step = np.zeros(0)
    if step.shape != (3,) or not np.all(np.isfinite(step) & (step > 0)):
        raise InputError(f"{step!r}: the step must be three positive numbers (sx, sy, sz), the object voxel over "
                         "the input spacing per axis", parameter="step")
    return step


def _slab(slab):
    if slab is None:
        return None
    try:
        low, high = (float(z) for z in slab)
    except (TypeError, ValueError):
        low, high = math.nan, math.nan
    if not (math.isfinite(low) and math.isfinite(high)) or low > high:
        raise InputError(f"{slab!r} must be two finite depths (z_lo, z_hi) in voxels with z_lo <= z_hi",
                         parameter="slab")
    return low, high


class _Rays:
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


def _ignored(mode, dtype):
    """The value that leaves a fold unchanged: below every value for the maximum, above every value for the
    minimum (what NaN, infinite and absent voxels become).
    """
    if dtype.kind == "f":
        return -np.inf if mode == "mip" else np.inf
    if dtype.kind == "b":
        return False if mode == "mip" else True
    info = np.iinfo(dtype)
    return info.min if mode == "mip" else info.max


def _finished(mode, best, found):
    """The fold's result as float32, NaN where no finite voxel was met."""
    out = best.astype(np.float32)
    out[~found] = np.nan
    return out


def _project_along_axis(values, rays, mode, progress):
    """Views along an axis: every ray runs along one column of voxels over the same range of layers, so the
    projection is one reduction of the kept sub-box along that axis, looked up at each ray's column.
    """
    a = int(np.flatnonzero(rays.direction)[0])              # object axis index (x, y, z) = (0, 1, 2)
    axis = 2 - a                                            # its array axis in values[z, y, x]
    n = values.shape[axis]
    # all rays keep the same stretch of the axis: q_a = q0_a + t d_a, q0_a the same for every ray
    ends = rays.q0[a][0] + np.array([rays.t0[0], rays.t1[0]]) * rays.direction[a]
    low, high = float(ends.min()), float(ends.max())
    first = int(np.clip(math.floor(low + 0.5 + _ON_FACE), 0, n - 1))
    last = int(np.clip(math.ceil(high + 0.5 - _ON_FACE) - 1, first, n - 1))
    # each ray's column: its nearest voxel along the two other axes (it stays within that voxel's box)
    minor = [k for k in range(3) if k != a]
    columns = [np.clip(np.floor(rays.q0[k] + 0.5).astype(np.intp), 0, values.shape[2 - k] - 1) for k in minor]
    layers = range(first, last + 1)
    centres = np.arange(first, last + 1)
    weights = np.minimum(centres + 0.5, high) - np.maximum(centres - 0.5, low)   # the length within each layer
    float_values = values.dtype.kind == "f"
    block = 16
    chunks = range(0, len(layers), block)
    if progress is not None:
        chunks = progress(chunks, len(chunks), mode)
    total = found = best = None
    for start in chunks:
        index = [slice(None)] * 3
        index[axis] = slice(first + start, first + min(start + block, len(layers)))
        part = values[tuple(index)]
        finite = np.isfinite(part) if float_values else None
        if mode == "mean":
            w = weights[start:start + block].reshape([-1 if k == axis else 1 for k in range(3)])
            if finite is not None:
                w = np.where(finite, w, 0.0)
                part = np.where(finite, part, 0)
            else:
                w = np.broadcast_to(w, part.shape)
            s, c = (part * w).sum(axis=axis), w.sum(axis=axis)
            total, found = (s, c) if total is None else (total + s, found + c)
        else:
            if finite is not None:
                part = np.where(finite, part, _ignored(mode, values.dtype))
                any_finite = finite.any(axis=axis)
                found = any_finite if found is None else found | any_finite
            folded = part.max(axis=axis) if mode == "mip" else part.min(axis=axis)
            best = folded if best is None else (np.maximum if mode == "mip" else np.minimum)(best, folded)
    # the reduced image's axes are the two minor axes, in array order (z before y before x)
    lookup = tuple(columns[::-1])
    if mode == "mean":
        with np.errstate(invalid="ignore", divide="ignore"):
            return (total[lookup] / found[lookup]).astype(np.float32)
    found = np.ones(best.shape, bool) if found is None else found
    return _finished(mode, best[lookup], found[lookup])


def _flat(values):
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


class _Layers:
    """What following the rays through the layers across axis ``a`` needs: the axes, the volume's flat memory and
    the rays' layers.
    """

    def __init__(self, values, rays):
        d = rays.direction
        self.a = int(np.argmax(np.abs(d)))
        self.b, self.c = (k for k in range(3) if k != self.a)      # c's voxels are further apart in memory
        self.sizes = values.shape[::-1]                              # (nx, ny, nz)
        self.flat, self.origin, self.strides = _flat(values)
        ends = np.stack([rays.q0[self.a] + rays.t0 * d[self.a], rays.q0[self.a] + rays.t1 * d[self.a]])
        n = self.sizes[self.a]
        # the layers each ray passes through for a positive length
        self.first = np.clip(np.floor(ends.min(axis=0) + 0.5 + _ON_FACE), 0, n - 1).astype(np.intp)
        self.last = np.clip(np.ceil(ends.max(axis=0) + 0.5 - _ON_FACE) - 1, self.first, n - 1).astype(np.intp)

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
        return np.where(np.isfinite(found), found, _ignored(mode, dtype))


def _project_through_layers(values, rays, mode, progress):
    """Any view: the rays followed through the layers of voxels across their main axis (see :func:`project`)."""
    layers = _Layers(values, rays)
    # rays side by side that start and end in the same layers: most runs of them then cross every face between
    order = np.lexsort((layers.last, layers.first))
    rays = rays.reordered(order)
    layers.first, layers.last = layers.first[order], layers.last[order]
    floats = values.dtype.kind == "f"
    if mode == "mean":
        result = (np.zeros(rays.count), np.zeros(rays.count))      # the integral of the values, and the length
    else:
        result = np.full(rays.count, _ignored(mode, values.dtype), values.dtype)

    def fold_ends():
        # the first and last layer of each ray, which it may enter or leave through the limits, one by one ...
        ends = ((layers.first, np.arange(rays.count)), (layers.last, np.flatnonzero(layers.last > layers.first)))
        for end, its_rays in ends:
            for start in range(0, its_rays.size, _RAYS_PER_CHUNK):
                chosen = its_rays[start:start + _RAYS_PER_CHUNK]
                cells, weights = _layer_cells(rays, chosen, end[chosen], layers)
                _fold_in(result, chosen, cells, weights, layers, mode, values.dtype)

    # ... and the layers between, which it passes through whole, all together
    faces = range(int(layers.first.min()) + 1, int(layers.last.max()) + 1)
    if mode != "mean" and _SKIP and len(faces) > 2 * _BLOCK_FACES:
        _fold_skipping(values, rays, layers, mode, result, faces, progress, fold_ends)
    else:
        fold_ends()
        _fold_all_faces(values, rays, layers, mode, result, faces, progress)
    out = np.empty(rays.count, np.float32)
    if mode == "mean":
        # every voxel counts, and the length is the ray's, unless some are NaN or infinite
        length = result[1] if floats else rays.t1 - rays.t0
        with np.errstate(invalid="ignore", divide="ignore"):
            out[order] = result[0] / np.where(length > 0, length, np.nan)
        return out
    out[order] = result
    if floats:
        out[order[result == _ignored(mode, values.dtype)]] = np.nan
    return out


def _fold_all_faces(values, rays, layers, mode, result, faces, progress):
    """Fold every face of ``faces`` for every ray into ``result``: in as many runs of faces as there are threads
    (NumPy lets go of Python's lock in its passes), each into its own copy of the result.
    """
    runs = max(1, min(_THREADS, len(faces) // 32))
    bounds = np.linspace(faces.start, faces.stop, runs + 1).astype(int)
    parts = [range(max(low - 1, faces.start), high) for low, high in zip(bounds[:-1], bounds[1:], strict=True)]
    if mode == "mean":
        results = [result] + [(np.zeros(rays.count), np.zeros(rays.count)) for _ in parts[1:]]
    else:
        results = [result] + [result.copy() for _ in parts[1:]]
    work = [(values, rays, layers, mode, out, part, progress if k == 0 else None)
            for k, (out, part) in enumerate(zip(results, parts, strict=True))]
    if runs == 1:
        _fold_whole_layers(*work[0])
    else:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(runs) as pool:
            list(pool.map(lambda args: _fold_whole_layers(*args), work))
        for other in results[1:]:
            if mode == "mean":
                result[0][:] += other[0]
                result[1][:] += other[1]
            else:
                (np.maximum if mode == "mip" else np.minimum)(result, other, out=result)


def _fold_in(result, chosen, cells, weights, layers, mode, dtype):
    """Fold the voxels ``cells`` (and their lengths ``weights``) of rays ``chosen`` into ``result``."""
    for c, w in zip(cells, weights, strict=True):
        found = layers.gather(c, mode, dtype)
        if mode == "mean":
            if dtype.kind == "f":
                found, finite = found
                w = np.where(finite, w, 0.0)
            result[0][chosen] += found * w
            result[1][chosen] += w
        else:
            result[chosen] = (np.maximum if mode == "mip" else np.minimum)(result[chosen], found)


def _fold_whole_layers(values, rays, layers, mode, result, faces, progress, buffers=None):
    """Fold into ``result`` the voxels of the layers each ray passes through whole (between its first and last)
    and that lie between ``faces`` (a range of faces ``q_a = j - 1/2``).

    The face between layers ``j - 1`` and ``j`` is crossed by every ray at a point whose voxel indices along the
    other two axes b, c are ``floor(A + j r)`` (``r = d_b / d_a``, ``A`` per ray): with ``A = I + f`` (whole and
    fractional parts) and ``j r = K + phi``, that is ``I + K + (f >= 1 - phi)``, one comparison per ray.  The two
    voxels on either side of that point, in layers ``j - 1`` and ``j``, are the one where the ray leaves layer
    ``j - 1`` and the one where it enters layer ``j``: for the maximum (minimum) the larger (smaller) of the two
    slices, taken once per face, is looked up there.  A ray that crosses a face along both b and c within a layer
    passes through a third voxel between the crossings; the side of the edge between them it passes on tells
    which, and only the rays that do are looked up again.  For the mean, the fractions of the layer at which a
    ray crosses b's and c's faces (``lambda_1 <= lambda_2``, 1 for none) weight the voxels where it enters, the
    one between and the one where it leaves.

    ``buffers``, a dictionary kept by the caller, keeps the slice buffers for its next call (the maximum and
    minimum only).
    """
    a, b, c = layers.a, layers.b, layers.c
    d = rays.direction
    axis = 2 - a                                       # the array axis of the layers
    nb, nc = layers.sizes[b], layers.sizes[c]
    mean = mode == "mean"
    fold = np.maximum if mode == "mip" else np.minimum
    neutral = 0.0 if mean else _ignored(mode, values.dtype)
    rb, rc = d[b] / d[a], d[c] / d[a]
    layer_length = 1 / abs(d[a])                       # in Z', of a layer passed through whole
    # minor index + 1/2 at the face q_a = j - 1/2: A + j r, A = q0 + 1/2 - (q0_a + 1/2) r
    start_b = rays.q0[b] + 0.5 - (rays.q0[a] + 0.5) * rb
    start_c = rays.q0[c] + 0.5 - (rays.q0[a] + 0.5) * rc
    whole_b, whole_c = np.floor(start_b), np.floor(start_c)
    part_b, part_c = start_b - whole_b, start_c - whole_c
    # Slices are copied into (nc + 2, nb + 2) buffers whose rim holds the neutral value: a ray that is out of its
    # limits at a face reads the corner (index 0) there, and one running exactly along the volume's side, where
    # rounding may take it a voxel out, reads the rim.
    row = np.intp(nb + 2)
    base = ((whole_c + 1) * row + whole_b + 1).astype(np.intp)
    # the side of an edge along a a ray passes on: by F = f_b r_c - f_c r_b against the edge's own (see _middle)
    side = part_b * rc - part_c * rb
    # the carries compare in single precision (twice the numbers a pass): only rays within 1e-7 voxel of a face,
    # which pass through its two voxels' boxes alike to that precision, can come out the other way
    part_b32, part_c32 = part_b.astype(np.float32), part_c.astype(np.float32)
    after_first = (layers.first + 1).astype(np.uint64)
    span = (layers.last - layers.first).astype(np.uint64)
    chunks = [slice(k, k + _RAYS_PER_CHUNK) for k in range(0, rays.count, _RAYS_PER_CHUNK)]
    # the faces every ray of a chunk crosses (first < j <= last for all of them): no need to ask there
    crosses_all = [(int(after_first[chosen].max()), int(layers.last[chosen].min())) for chosen in chunks]
    if progress is not None:
        faces = progress(faces, len(faces), mode)
    kind = np.float64 if mean else values.dtype
    if buffers is not None and not mean:
        if not buffers:
            buffers["pair"] = [np.full((nc + 2, row), neutral, kind) for _ in range(3)]   # the rims stay neutral
            buffers["slices"] = _Slices(values, axis, _BLOCK_FACES + 2)
        single, here, pair = buffers["pair"]
        slices = buffers["slices"]
        slices.start = None                 # a block of slices read from the first this call asks for
    else:
        single, here, pair = (np.full((nc + 2, row), neutral, kind) for _ in range(3))
        slices = _Slices(values, axis)
    # for the mean of a float volume the length counts only finite voxels: 1 where finite, looked up alike
    counted = [np.zeros((nc + 2, row)) for _ in range(2)] if mean and values.dtype.kind == "f" else None
    previous = [None] * len(chunks)
    before = None
    for j in faces:
        # single: layer j - 1, here: layer j, each slice read once
        single, here = here, single
        if before is None:
            np.copyto(single[1:-1, 1:-1], _finite(slices[j - 1], neutral))
        np.copyto(here[1:-1, 1:-1], _finite(slices[j], neutral))
        if counted is not None:
            counted.reverse()
            if before is None:
                np.copyto(counted[0][1:-1, 1:-1], np.isfinite(slices[j - 1]))
            np.copyto(counted[1][1:-1, 1:-1], np.isfinite(slices[j]))
        if not mean:
            fold(single, here, out=pair)
        steps_b, phase_b = divmod(j * rb, 1.0)
        steps_c, phase_c = divmod(j * rc, 1.0)
        shift = int(steps_c * row + steps_b)
        for n, chosen in enumerate(chunks):
            carry_b = part_b32[chosen] >= 1 - phase_b
            carry_c = part_c32[chosen] >= 1 - phase_c
            cells = base[chosen] + shift
            cells += carry_b
            cells += carry_c * row              # (np.where would be several times slower)
            # the face lies within the ray's limits: first < j <= last
            if crosses_all[n][0] <= j <= crosses_all[n][1]:
                crossed = True
            else:
                crossed = (np.uint64(j) - after_first[chosen]) < span[chosen]
                cells *= crossed
            if not mean:
                fold(result[chosen], pair.ravel().take(cells, mode="clip"), out=result[chosen])
            both = middle = None
            if previous[n] is not None:
                # the voxel index along b changes across the layer when the carries differ, or K grew and the
                # carry went
                moves_b = np.not_equal(previous[n][1], carry_b) if steps_b == before[0] else \
                    np.equal(previous[n][1], carry_b)
                moves_c = np.not_equal(previous[n][2], carry_c) if steps_c == before[1] else \
                    np.equal(previous[n][2], carry_c)
                # (a ray in a plane of the voxel grid crosses the faces of one minor axis alone)
                both = np.flatnonzero(moves_b & moves_c & crossed) if rb and rc else ()
                if len(both):
                    edge = (before[0] + (rb > 0)) * rc - (before[1] + (rc > 0)) * rb
                    middle = _middle(previous[n][:3], both, side[chosen], edge, rb, rc, row)
                    if not mean:
                        offset = chosen.start
                        result[offset + both] = fold(result[offset + both], single.ravel().take(middle, mode="clip"))
            if not mean:
                previous[n] = (cells, carry_b, carry_c)
                continue
            sources = [(single, here)] + ([tuple(counted)] if counted is not None else [])
            entering = [now.ravel().take(cells, mode="clip") for _, now in sources]
            if previous[n] is not None:
                # layer j - 1, entered at face j - 1 and left at face j: where along it the ray crosses b's and
                # c's faces
                crossing = [_fraction(part[chosen], phase, carry, r, moves) for part, phase, carry, r, moves in
                            ((part_b, before[2], previous[n][1], rb, moves_b),
                             (part_c, before[3], previous[n][2], rc, moves_c))]
                first_crossing, second_crossing = np.minimum(*crossing), np.maximum(*crossing)
                whole = previous[n][3] & crossed if crossed is not True else previous[n][3]
                for (last, _), entered, total in zip(sources, previous[n][4], result, strict=False):
                    leaving = last.ravel().take(cells, mode="clip")
                    integral = leaving + (entered - leaving) * first_crossing
                    if middle is not None:
                        integral[both] += ((last.ravel().take(middle, mode="clip") - leaving[both]) *
                                           (second_crossing[both] - first_crossing[both]))
                    if whole is not True:
                        integral *= whole
                    total[chosen] += integral * layer_length
            previous[n] = (cells, carry_b, carry_c, crossed, entering)
        before = (steps_b, steps_c, phase_b, phase_c)


def _fold_skipping(values, rays, layers, mode, result, faces, progress, fold_ends):
    """Fold the layers the rays pass through whole into ``result`` (the maximum or minimum), skipping, for each
    ray, the blocks of faces that cannot change its answer.

    The faces are cut into blocks of ``_BLOCK_FACES``; :func:`_block_bounds` gives every ray an upper bound (for
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
    neutral = _ignored(mode, values.dtype)
    blocks = [range(max(j - 1, faces.start), min(j + _BLOCK_FACES, faces.stop))   # the face before: its layer's
              for j in range(faces.start, faces.stop, _BLOCK_FACES)]               # middle voxels
    bounds = _block_bounds(values, rays, layers, mode, blocks)
    paths = _Paths(values, rays, layers)
    buffers = [{} for _ in range(_THREADS)]          # each thread's slice buffers, kept from block to block
    best, highest = np.zeros(rays.count, np.intp), bounds[0].copy()
    for k in range(1, len(blocks)):
        higher = beats(bounds[k], highest)
        best[higher] = k
        np.copyto(highest, bounds[k], where=higher)
    ends_done.result()
    ends.shutdown()
    runs = max(1, min(_THREADS, len(blocks) // 2))

    def first(k, out, buffers):
        mine = best == k
        _fold_rays(values, rays, layers, mode, out, blocks[k], np.flatnonzero(mine & beats(bounds[k], out)),
                   paths, buffers)
        bounds[k][mine] = neutral                                                   # done

    def then(k, out, buffers):
        _fold_rays(values, rays, layers, mode, out, blocks[k], np.flatnonzero(beats(bounds[k], out)), paths,
                   buffers)

    # first into the result (each ray in one block only), then each thread into its own copy of it; the blocks
    # handed out one at a time, as the threads come for them (their work differs much)
    on_threads(lambda k, state: first(k, *state), range(len(blocks)), [(result, b) for b in buffers[:runs]])
    results = [result] + [result.copy() for _ in range(runs - 1)]
    numbers = range(len(blocks)) if progress is None else progress(range(len(blocks)), len(blocks), mode)
    on_threads(lambda k, state: then(k, *state), numbers, list(zip(results, buffers[:runs], strict=False)))
    for other in results[1:]:
        (np.maximum if mode == "mip" else np.minimum)(result, other, out=result)


def _fold_rays(values, rays, layers, mode, result, faces, chosen, paths, buffers):
    """:func:`_fold_whole_layers` for the rays ``chosen`` (indices, increasing) alone: a few rays straight from the
    volume (:func:`_fold_pairs`), many through the slices.
    """
    if not chosen.size:
        return
    if chosen.size * _PAIRS_PER_PIXEL[paths.blocked] < paths.nb * paths.nc:
        _fold_pairs(paths, mode, result, faces, chosen)
        return
    some = copy.copy(layers)
    some.first, some.last = layers.first[chosen], layers.last[chosen]
    part = result[chosen]
    _fold_whole_layers(values, rays.reordered(chosen), some, mode, part, faces, None, buffers)
    result[chosen] = part


class _Paths:
    """What :func:`_fold_pairs` needs of every ray, worked out once, as :func:`_fold_whole_layers` works it out:
    where it crosses the faces along the main axis (the whole and fractional parts of its minor indices + 1/2 at
    face 0, ``A``, and the steps ``r`` per face) and the side of the edges it passes on.
    """

    def __init__(self, values, rays, layers):
        a, b, c = layers.a, layers.b, layers.c
        d = rays.direction
        self.rb, self.rc = d[b] / d[a], d[c] / d[a]
        start_b = rays.q0[b] + 0.5 - (rays.q0[a] + 0.5) * self.rb
        start_c = rays.q0[c] + 0.5 - (rays.q0[a] + 0.5) * self.rc
        whole_b, whole_c = np.floor(start_b), np.floor(start_c)
        part_b, part_c = start_b - whole_b, start_c - whole_c
        self.whole_b, self.whole_c = whole_b.astype(np.intp), whole_c.astype(np.intp)
        self.part_b32, self.part_c32 = part_b.astype(np.float32), part_c.astype(np.float32)
        self.side = part_b * self.rc - part_c * self.rb
        self.first, self.last = layers.first, layers.last
        self.flat, self.origin = layers.flat, layers.origin
        self.stride_a, self.stride_b, self.stride_c = (layers.strides[k] for k in (a, b, c))
        self.nb, self.nc = layers.sizes[b], layers.sizes[c]
        self.floats = values.dtype.kind == "f"
        self.blocked = _Slices(values, 2 - a).blocks


def _fold_pairs(paths, mode, result, faces, chosen, chunk=4096):
    """What :func:`_fold_whole_layers` folds into ``result`` at ``faces`` for the rays ``chosen``, the same voxels
    (the same arithmetic), read straight from the volume for every (ray, face) pair at once: no slice is copied,
    so it pays for the rays alone.
    """
    fold = np.maximum if mode == "mip" else np.minimum
    neutral = _ignored(mode, paths.flat.dtype)
    rb, rc = paths.rb, paths.rc
    js = np.arange(faces.start, faces.stop)
    # per face, as _fold_whole_layers works them out (the carries compare float32 parts with float64 thresholds)
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
        inside = _inside(paths, ib, ic)
        inside &= crossed
        cells = ib * paths.stride_b
        cells += ic * paths.stride_c
        cells += layer_before
        found = fold(_finite_take(paths, cells, neutral), _finite_take(paths, cells + paths.stride_a, neutral))
        found = np.where(inside, found, neutral)
        if rb and rc and len(js) > 1:
            # the voxel between two crossings, in the layer between faces j - 1 and j, as _middle finds it (for
            # all pairs at once: most rays cross both minor axes' faces in most layers)
            moves_b = (carry_b[:, 1:] != carry_b[:, :-1]) != grew_b
            moves_c = (carry_c[:, 1:] != carry_c[:, :-1]) != grew_c
            both = moves_b & moves_c & crossed[:, 1:] & crossed[:, :-1]
            z = edge + carry_b[:, :-1] * rc - carry_c[:, :-1] * rb - paths.side[rays, None]
            b_first = z < 0 if rb * rc > 0 else z > 0
            ib, ic = ib[:, :-1] + b_first * along_b, ic[:, :-1] + ~b_first * along_c
            both &= _inside(paths, ib, ic)
            middle = cells[:, :-1] + paths.stride_a
            middle += np.where(b_first, along_b * paths.stride_b, along_c * paths.stride_c)
            middle = np.where(both, _finite_take(paths, middle, neutral), neutral)
            fold(found[:, 1:], middle, out=found[:, 1:])
        result[rays] = fold(result[rays], fold.reduce(found, axis=1))


def _inside(paths, ib, ic):
    """Whether minor indices ``ib, ic`` lie in the volume (a negative index is a large unsigned one)."""
    inside = ib.view(np.uintp) < paths.nb
    inside &= ic.view(np.uintp) < paths.nc
    return inside


def _finite_take(paths, cells, neutral):
    """The voxels at flat indices ``cells`` (any, outside the volume too: the caller masks them), NaN and
    infinite ones ``neutral``.
    """
    found = paths.flat.take(cells, mode="clip")
    if paths.floats:
        found[~np.isfinite(found)] = neutral
    return found


def _block_bounds(values, rays, layers, mode, blocks):
    """For every block of faces (a range of them) and every ray, a bound of the values of the voxels the ray can
    meet at those faces in :func:`_fold_whole_layers`: above all of them for the maximum (below, for the minimum),
    ignoring NaN; the fold's neutral value where the ray crosses none of the block's faces.  ``(len(blocks),
    rays.count)``, of the values' type.

    The layers beside a block's faces are folded along the main axis, then over tiles of ``_TILE`` x ``_TILE``
    voxels of the other two axes (the axis next to itself in memory last, on the least data), and each tile takes
    the tiles a ray's path across the block can reach from it (how far it moves along each minor axis over the
    block's faces, and a voxel each side for rounding).  A ray looks the bound up at the tile where it starts.
    """
    reduce = np.fmax if mode == "mip" else np.fmin
    neutral = _ignored(mode, values.dtype)
    a, b, c = layers.a, layers.b, layers.c
    axis, tile = 2 - a, _TILE
    strides = [abs(s) for s in values.strides]
    # the minor axes in the order they are folded: the larger stride first
    minor = sorted((2 - b, 2 - c), key=lambda k: -strides[k])
    spans = [slice(block.start - 1, block.stop) for block in blocks]      # face j reads layers j - 1 and j
    if strides[axis] < min(strides[k] for k in minor):
        # the main axis is next to itself in memory: the tiles first (each a fold across slices), then blocks
        small = values
        for k in minor:
            small = _fold_tiles(small, k, tile, reduce)
        folded = [reduce.reduce(_along(small, axis, span), axis=axis) for span in spans]
    else:
        folded = []
        for span in spans:
            plane = reduce.reduce(_along(values, axis, span), axis=axis)   # (c, b): c's array axis comes first
            for k in (0, 1) if strides[minor[0]] == strides[2 - c] else (1, 0):
                plane = _fold_tiles(plane, k, tile, reduce)
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
        # (rounding, and the carries of _fold_whole_layers) and one after
        reach = (math.ceil(abs(r) * faces) + 3) // tile + 2
        window = bound.copy()
        n = tiles[array_axis - 1]
        for s in range(1, min(reach, n)):
            reduce(_along(window, array_axis, slice(0, n - s)), _along(bound, array_axis, slice(s, n)),
                   out=_along(window, array_axis, slice(0, n - s)))
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


def _along(array, axis, index):
    """``array[..., index, ...]`` with ``index`` on ``axis``."""
    at = [slice(None)] * array.ndim
    at[axis] = index
    return array[tuple(at)]


def _fold_tiles(array, axis, tile, reduce):
    """``array`` folded by ``reduce`` over runs of ``tile`` along ``axis`` (the last run may be shorter), read in
    place whatever its strides.
    """
    out = _along(array, axis, slice(0, None, tile)).copy()
    for s in range(1, tile):
        part = _along(array, axis, slice(s, None, tile))
        head = _along(out, axis, slice(0, part.shape[axis]))
        reduce(head, part, out=head)
    return out


def _fraction(part, phase, carry, r, moves):
    """Where along a layer (0 at the face it is entered by, 1 at the other) a ray crosses a face along a minor
    axis: ``part + phase - carry`` is the fractional part of its index + 1/2 at the entry face; 1 where it
    ``moves`` to no other voxel along that axis.
    """
    if r == 0:
        return np.ones(part.shape)
    inside = part + phase - carry
    fraction = (1 - inside) / r if r > 0 else inside / -r
    np.clip(fraction, 0.0, 1.0, out=fraction)
    fraction[~moves] = 1.0
    return fraction


class _Slices:
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
            return _along(self.values, self.axis, j)
        if self.start is None or not self.start <= j < self.start + self.BLOCK:
            self.start = j
            part = _along(self.values, self.axis, slice(j, j + self.BLOCK))
            if self.memory is None:          # one array, filled again for each block (new memory is slow to touch)
                self.memory = np.empty(_along(self.values, self.axis, slice(0, self.BLOCK)).shape, self.values.dtype)
            self.block = _along(self.memory, self.axis, slice(0, part.shape[self.axis]))
            np.copyto(self.block, part)
        return _along(self.block, self.axis, j - self.start)


def _middle(entering, both, side, edge, rb, rc, row):
    """The voxel between the two crossings, in the slice buffer, of the rays ``both`` (entering the layer at
    ``entering = (cells, carry_b, carry_c)``).

    The ray crosses b's face first when it passes the edge between the two faces on one side: with ``E`` the
    edge and ``m`` the ray at the entry face, ``(E_b - m_b) r_c - (E_c - m_c) r_b`` has the sign of ``r_b r_c``
    there, and it is ``edge + carry_b r_c - carry_c r_b - side``.
    """
    cells, carry_b, carry_c = (e[both] for e in entering)
    z = edge + carry_b * rc - carry_c * rb - side[both]
    b_first = z < 0 if rb * rc > 0 else z > 0
    along_b, along_c = (1 if rb > 0 else -1), (row if rc > 0 else -row)
    cells += b_first * (along_b - along_c) + along_c
    return cells


def _finite(values, neutral):
    """A slice with its NaN and infinite voxels set to ``neutral`` (a copy only for float slices that have some)."""
    if values.dtype.kind == "f" and not np.isfinite(values).all():
        return np.where(np.isfinite(values), values, neutral)
    return values


def _layer_cells(rays, chosen, layer, layers):
    """The (up to) three voxels the ``chosen`` rays pass through in ``layer`` (a number, or one per ray) along the
    main axis: flat indices of the voxel where each enters the layer, the one between its crossings of the other
    axes' faces, and the one where it leaves; and the length (in ``Z'``) each is passed through for.
    """
    a, d = layers.a, rays.direction
    q0 = [q[chosen] for q in rays.q0]
    # the part of the ray within the layer's faces q_a = layer -+ 1/2 and within its limits
    faces = ((layer - 0.5 - q0[a]) / d[a], (layer + 0.5 - q0[a]) / d[a])
    near, far = faces if d[a] > 0 else faces[::-1]
    enter = np.maximum(rays.t0[chosen], near)
    leave = np.minimum(rays.t1[chosen], far)
    cell_in, cell_out, crossing = [], [], []
    for k in (layers.b, layers.c):
        q_in, q_out = q0[k] + enter * d[k], q0[k] + leave * d[k]
        size = layers.sizes[k]
        if d[k] > 0:           # the voxel just after entering and just before leaving: a face point goes inward
            i_in, i_out = np.floor(q_in + 0.5 + _ON_FACE), np.ceil(q_out + 0.5 - _ON_FACE) - 1
        elif d[k] < 0:
            i_in, i_out = np.ceil(q_in + 0.5 - _ON_FACE) - 1, np.floor(q_out + 0.5 + _ON_FACE)
        else:
            i_in = i_out = np.floor(q_in + 0.5)
        np.clip(i_in, 0, size - 1, out=i_in)
        np.clip(i_out, 0, size - 1, out=i_out)
        crosses = i_in != i_out
        # the face between the two voxels, and when the ray crosses it (at the end of the part when it does not)
        face = np.maximum(i_in, i_out) - 0.5
        with np.errstate(divide="ignore", invalid="ignore"):
            when = np.where(crosses, (face - q0[k]) / (d[k] if d[k] else 1.0), leave)
        cell_in.append(i_in.astype(np.intp))
        cell_out.append(i_out.astype(np.intp))
        crossing.append(when)
    first_crossing = np.minimum(crossing[0], crossing[1])
    second_crossing = np.maximum(crossing[0], crossing[1])
    b_first = crossing[0] < crossing[1]                 # the middle voxel has b's new index and c's old one
    base = layers.origin + layer * layers.strides[a]
    (sb, sc), (bin_, cin), (bout, cout) = (layers.strides[k] for k in (layers.b, layers.c)), cell_in, cell_out
    entry = base + bin_ * sb + cin * sc
    leaving = base + bout * sb + cout * sc
    middle = np.where(b_first, base + bout * sb + cin * sc, base + bin_ * sb + cout * sc)
    weights = (first_crossing - enter, second_crossing - first_crossing, leave - second_crossing)
    return (entry, middle, leaving), weights
