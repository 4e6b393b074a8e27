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

import math

import numpy as np

from ..errors import InputError
from . import _project_skip
from ._project_march import fold_all_faces
from ._project_rays import ON_FACE, RAYS_PER_CHUNK, Layers, Rays, ignored
from .kinds import PROJECTIONS

_SKIP = True              # skip the blocks of faces that cannot change a ray's maximum (minimum); False: every face


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
    :func:`fold_whole_layers`).  A ray's first and last layers, which it may enter or leave through a limit, are
    cut at every face one by one.  Views along an axis (the presets) take one reduction of the kept box along
    that axis instead.

    The maximum and minimum skip what cannot change a ray's answer, as maximum intensity ray casters leap over
    space [2]_: the faces are cut into blocks, each ray gets a bound of the voxels it can meet in each block (from
    the block's maximum over tiles of voxels, :func:`block_bounds`), takes its exact value over its most
    promising block first, and then follows only the blocks whose bound beats what it holds
    (:func:`fold_skipping`).  The answer is the one every face gives, bit for bit; the mean follows every face.

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
    rays = Rays(values.shape, view, shape, step, clip, slab)
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
    first = int(np.clip(math.floor(low + 0.5 + ON_FACE), 0, n - 1))
    last = int(np.clip(math.ceil(high + 0.5 - ON_FACE) - 1, first, n - 1))
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
                part = np.where(finite, part, ignored(mode, values.dtype))
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



def _project_through_layers(values, rays, mode, progress):
    """Any view: the rays followed through the layers of voxels across their main axis (see :func:`project`)."""
    layers = Layers(values, rays)
    # rays side by side that start and end in the same layers: most runs of them then cross every face between
    order = np.lexsort((layers.last, layers.first))
    rays = rays.reordered(order)
    layers.first, layers.last = layers.first[order], layers.last[order]
    floats = values.dtype.kind == "f"
    if mode == "mean":
        result = (np.zeros(rays.count), np.zeros(rays.count))      # the integral of the values, and the length
    else:
        result = np.full(rays.count, ignored(mode, values.dtype), values.dtype)

    def fold_ends():
        # the first and last layer of each ray, which it may enter or leave through the limits, one by one ...
        ends = ((layers.first, np.arange(rays.count)), (layers.last, np.flatnonzero(layers.last > layers.first)))
        for end, its_rays in ends:
            for start in range(0, its_rays.size, RAYS_PER_CHUNK):
                chosen = its_rays[start:start + RAYS_PER_CHUNK]
                cells, weights = _layer_cells(rays, chosen, end[chosen], layers)
                _fold_in(result, chosen, cells, weights, layers, mode, values.dtype)

    # ... and the layers between, which it passes through whole, all together
    faces = range(int(layers.first.min()) + 1, int(layers.last.max()) + 1)
    if mode != "mean" and _SKIP and len(faces) > 2 * _project_skip.BLOCK_FACES:
        _project_skip.fold_skipping(values, rays, layers, mode, result, faces, progress, fold_ends)
    else:
        fold_ends()
        fold_all_faces(values, rays, layers, mode, result, faces, progress)
    out = np.empty(rays.count, np.float32)
    if mode == "mean":
        # every voxel counts, and the length is the ray's, unless some are NaN or infinite
        length = result[1] if floats else rays.t1 - rays.t0
        with np.errstate(invalid="ignore", divide="ignore"):
            out[order] = result[0] / np.where(length > 0, length, np.nan)
        return out
    out[order] = result
    if floats:
        out[order[result == ignored(mode, values.dtype)]] = np.nan
    return out



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
            i_in, i_out = np.floor(q_in + 0.5 + ON_FACE), np.ceil(q_out + 0.5 - ON_FACE) - 1
        elif d[k] < 0:
            i_in, i_out = np.ceil(q_in + 0.5 - ON_FACE) - 1, np.floor(q_out + 0.5 + ON_FACE)
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
