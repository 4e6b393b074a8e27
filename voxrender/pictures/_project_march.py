"""The march of a projection through the layers its rays pass through whole: all rays at once, one face between
layers at a time (:func:`fold_whole_layers`), in runs of faces on threads (:func:`fold_all_faces`); for the mean,
the fractions of a layer between a ray's face crossings (:func:`crossing_fraction`) weight its voxels.
"""

from __future__ import annotations

import numpy as np

from . import _project_rays
from ._project_rays import RAYS_PER_CHUNK, Slices, face_crossings, finite, ignored


def fold_all_faces(values, rays, layers, mode, result, faces, progress):
    """Fold every face of ``faces`` for every ray into ``result``: in as many runs of faces as there are threads
    (NumPy lets go of Python's lock in its passes), each into its own copy of the result.
    """
    runs = max(1, min(_project_rays.THREADS, len(faces) // 32))
    bounds = np.linspace(faces.start, faces.stop, runs + 1).astype(int)
    parts = [range(max(low - 1, faces.start), high) for low, high in zip(bounds[:-1], bounds[1:], strict=True)]
    if mode == "mean":
        results = [result] + [(np.zeros(rays.count), np.zeros(rays.count)) for _ in parts[1:]]
    else:
        results = [result] + [result.copy() for _ in parts[1:]]
    work = [(values, rays, layers, mode, out, part, progress if k == 0 else None)
            for k, (out, part) in enumerate(zip(results, parts, strict=True))]
    if runs == 1:
        fold_whole_layers(*work[0])
    else:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(runs) as pool:
            list(pool.map(lambda args: fold_whole_layers(*args), work))
        for other in results[1:]:
            if mode == "mean":
                result[0][:] += other[0]
                result[1][:] += other[1]
            else:
                (np.maximum if mode == "mip" else np.minimum)(result, other, out=result)



def fold_whole_layers(values, rays, layers, mode, result, faces, progress, buffers=None):
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
    minimum only); its ``"block"`` is how many slices to read at once.
    """
    a, b, c = layers.a, layers.b, layers.c
    d = rays.direction
    axis = 2 - a                                       # the array axis of the layers
    nb, nc = layers.sizes[b], layers.sizes[c]
    mean = mode == "mean"
    fold = np.maximum if mode == "mip" else np.minimum
    neutral = 0.0 if mean else ignored(mode, values.dtype)
    layer_length = 1 / abs(d[a])                       # in Z', of a layer passed through whole
    rb, rc, whole_b, whole_c, part_b, part_c, side = face_crossings(rays, layers)
    # Slices are copied into (nc + 2, nb + 2) buffers whose rim holds the neutral value: a ray that is out of its
    # limits at a face reads the corner (index 0) there, and one running exactly along the volume's side, where
    # rounding may take it a voxel out, reads the rim.
    row = np.intp(nb + 2)
    base = ((whole_c + 1) * row + whole_b + 1).astype(np.intp)
    # the carries compare in single precision (twice the numbers a pass): only rays within 1e-7 voxel of a face,
    # which pass through its two voxels' boxes alike to that precision, can come out the other way
    part_b32, part_c32 = part_b.astype(np.float32), part_c.astype(np.float32)
    after_first = (layers.first + 1).astype(np.uint64)
    span = (layers.last - layers.first).astype(np.uint64)
    chunks = [slice(k, k + RAYS_PER_CHUNK) for k in range(0, rays.count, RAYS_PER_CHUNK)]
    # the faces every ray of a chunk crosses (first < j <= last for all of them): no need to ask there
    crosses_all = [(int(after_first[chosen].max()), int(layers.last[chosen].min())) for chosen in chunks]
    if progress is not None:
        faces = progress(faces, len(faces), mode)
    single, here, pair, slices = _slice_buffers(values, axis, (nc + 2, row), neutral,
                                                np.float64 if mean else values.dtype, None if mean else buffers)
    # for the mean of a float volume the length counts only finite voxels: 1 where finite, looked up alike
    counted = [np.zeros((nc + 2, row)) for _ in range(2)] if mean and values.dtype.kind == "f" else None
    previous = [None] * len(chunks)
    before = None
    for j in faces:
        # single: layer j - 1, here: layer j, each slice read once
        single, here = here, single
        if before is None:
            np.copyto(single[1:-1, 1:-1], finite(slices[j - 1], neutral))
        np.copyto(here[1:-1, 1:-1], finite(slices[j], neutral))
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
                    middle = middle_voxels(previous[n][:3], both, side[chosen], edge, rb, rc, row)
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
                crossing = [crossing_fraction(part[chosen], phase, carry, r, moves) for part, phase, carry, r, moves in
                            ((part_b, before[2], previous[n][1], rb, moves_b),
                             (part_c, before[3], previous[n][2], rc, moves_c))]
                _add_layer_mean(result, chosen, sources, cells, crossed, previous[n],
                                (np.minimum(*crossing), np.maximum(*crossing)), middle, both, layer_length)
            previous[n] = (cells, carry_b, carry_c, crossed, entering)
        before = (steps_b, steps_c, phase_b, phase_c)


def _slice_buffers(values, axis, shape, neutral, kind, buffers):
    """The three slice buffers of :func:`fold_whole_layers` (layer ``j - 1``, layer ``j``, their fold), each of
    ``shape`` with a rim of ``neutral`` (a ray out of its limits, or a voxel out along the volume's side, reads the
    rim), and the reader of the slices; kept in ``buffers`` for the next call when it is given.
    """
    if buffers is None:
        return (*(np.full(shape, neutral, kind) for _ in range(3)), Slices(values, axis))
    if "pair" not in buffers:
        buffers["pair"] = [np.full(shape, neutral, kind) for _ in range(3)]   # the rims stay neutral
        buffers["slices"] = Slices(values, axis, buffers["block"])
    buffers["slices"].start = None          # a block of slices read from the first this call asks for
    return (*buffers["pair"], buffers["slices"])


def _add_layer_mean(result, chosen, sources, cells, crossed, earlier, crossings, middle, both, layer_length):
    """Add to the mean's ``result`` (integral, and length counted) the layer the rays ``chosen`` left at ``cells``:
    the voxel each entered it by (``earlier``'s), the one between its crossings (``middle``, for the rays ``both``)
    and the one it leaves by, weighted by the fractions of the layer between its ``crossings`` of the minor axes'
    faces; ``sources`` are the slice buffers (of the values, and of the finite voxels when counted).
    """
    first_crossing, second_crossing = crossings
    whole = earlier[3] & crossed if crossed is not True else earlier[3]
    for (last, _), entered, total in zip(sources, earlier[4], result, strict=False):
        leaving = last.ravel().take(cells, mode="clip")
        integral = leaving + (entered - leaving) * first_crossing
        if middle is not None:
            integral[both] += ((last.ravel().take(middle, mode="clip") - leaving[both]) *
                               (second_crossing[both] - first_crossing[both]))
        if whole is not True:
            integral *= whole
        total[chosen] += integral * layer_length


def middle_voxels(entering, both, side, edge, rb, rc, row):
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



def crossing_fraction(part, phase, carry, r, moves):
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
