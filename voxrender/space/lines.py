"""3-D line voxelization and discrete metrics (Cohen-Or and Kaufman, IEEE CG&A 1997).

A voxel is the closed unit cube centred on its grid point.  An N-line is an
N-connected path of voxels that the continuous line pierces (N = 6, 18, 26).

* :func:`d6`, :func:`d18`, :func:`d26`: the discrete metrics (Eqs. 1-3).
* :func:`line26`: the asymmetric 26-line of Fig. 4; :func:`line26_symmetric`: every
  coordinate rounded independently; :func:`line18`: the best-approximation 18-line.
* :func:`line6_tripod`: the tripod 6-line of Fig. 6; :func:`line6_parametric`: the
  parametric 6-line of Amanatides and Woo (Fig. 7).  Both take sub-voxel end points
  and have the containment property.
* :func:`line2d_switch`: Fig. 8, an 8-connected 2-D line that slows to 4-connectivity
  at the first nonempty pixel.
* :class:`Stepper`: many lines stepped at once, each as a 26-line or a 6-line, switching
  between the two with Eqs. 9-13.  The discrete ray caster uses it.
* :func:`metrics_table`: Tables 1 and 2 by experiment.

All lines work in a *canonical frame*: axes reflected so the direction is positive and
permuted so ``A >= B >= C >= 0``; :class:`Frame` maps back.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def d6(delta):
    """6-distance (Eq. 1): ``|dx| + |dy| + |dz|``, the length of the shortest 6-path.

    >>> int(d6([2, -3, 1]))
    6
    """
    return np.abs(np.asarray(delta)).sum(axis=-1)


def d26(delta):
    """26-distance (Eq. 2): ``max(|dx|, |dy|, |dz|)``.

    >>> int(d26([2, -3, 1]))
    3
    """
    return np.abs(np.asarray(delta)).max(axis=-1)


def d18(delta):
    """18-distance (Eq. 3): ``max(d26, ceil(d6 / 2))``.

    >>> int(d18([2, 2, 2]))
    3
    """
    return np.maximum(d26(delta), -(-d6(delta) // 2))


def is_connected(path, n):
    """Whether consecutive voxels of ``path`` are ``n``-adjacent (n = 6, 18, 26) and distinct.

    >>> is_connected(np.array([[0, 0, 0], [1, 1, 0], [1, 1, 1]]), 18)
    True
    """
    steps = np.abs(np.diff(np.asarray(path), axis=0))
    if not len(steps):
        return True
    changed = (steps > 0).sum(axis=1)
    return bool(np.all(steps <= 1) and np.all(changed >= 1) and np.all(changed <= {6: 1, 18: 2, 26: 3}[n]))


@dataclass(frozen=True)
class Frame:
    """The canonical frame of a line from ``start`` to ``end`` (real points, voxel units).

    ``sign`` reflects each axis so the direction is non-negative, ``order`` lists the
    axes from the largest extent to the smallest, so that in the frame the line runs
    from ``offset`` (the start point relative to its voxel's centre) along ``(A, B, C)``
    with ``A >= B >= C >= 0``.
    """

    origin: np.ndarray   # the start voxel (integer grid point)
    sign: np.ndarray     # +1 or -1 per object axis
    order: np.ndarray    # frame axis k is object axis order[k]
    offset: np.ndarray   # start point minus origin, in the frame (each in [-1/2, 1/2])
    extent: np.ndarray   # (A, B, C)

    @classmethod
    def of(cls, start, end):
        """The frame of one line (arrays of 3) or of many (arrays ``(n, 3)``)."""
        start, end = np.asarray(start, float), np.asarray(end, float)
        origin = np.floor(start + 0.5).astype(np.int64)
        delta = end - start
        sign = np.where(delta < 0, -1, 1)
        order = np.argsort(-np.abs(delta), axis=-1, kind="stable")
        return cls(origin, sign, order, np.take_along_axis(sign * (start - origin), order, axis=-1),
                   np.take_along_axis(np.abs(delta), order, axis=-1))

    def to_object(self, q):
        """Frame voxel offsets ``q`` (..., 3) to object voxels."""
        q = np.asarray(q)
        out = np.empty_like(q)
        out[..., self.order] = q
        return self.origin + self.sign * out

    def steps_to(self, end):
        """Frame offset of the voxel that holds ``end``."""
        return (self.sign * (np.floor(np.asarray(end, float) + 0.5).astype(np.int64) - self.origin))[self.order]

    def f_xy(self, x, y):
        """Implicit equation of the line's projection on the frame's xy plane (zero on the line)."""
        a, b, _ = self.extent
        return b * (x - self.offset[0]) - a * (y - self.offset[1])

    def f_xz(self, x, z):
        """Implicit equation of the line's projection on the frame's xz plane."""
        a, _, c = self.extent
        return c * (x - self.offset[0]) - a * (z - self.offset[2])

    def f_zy(self, z, y):
        """Implicit equation of the line's projection on the frame's zy plane."""
        _, b, c = self.extent
        return b * (z - self.offset[2]) - c * (y - self.offset[1])


def line26(start, end):
    """The asymmetric 26-line of Fig. 4 between two voxels (integer points).

    Integer decision variables, doubled to avoid fractions: ``e_y`` and ``e_z`` are the
    midpoint errors of the xy and xz projections at ``(x + 1, y + 1/2)`` and ``(x + 1, z + 1/2)``.
    The line has ``d26 + 1`` voxels (it is a shortest 26-path).

    >>> line26((0, 0, 0), (4, 2, 1)).tolist()
    [[0, 0, 0], [1, 1, 0], [2, 1, 1], [3, 2, 1], [4, 2, 1]]
    """
    frame = Frame.of(start, end)
    a, b, c = (int(round(v)) for v in frame.extent)
    e_y, e_z = 2 * b - a, 2 * c - a
    q = [0, 0, 0]
    path = [tuple(q)]
    for _ in range(a):
        q[0] += 1
        if e_y < 0:
            e_y += 2 * b
        else:
            e_y += 2 * b - 2 * a
            q[1] += 1
        if e_z < 0:
            e_z += 2 * c
        else:
            e_z += 2 * c - 2 * a
            q[2] += 1
        path.append(tuple(q))
    return frame.to_object(np.array(path))


def line26_symmetric(start, end):
    """A symmetric 26-line: step ``k`` of ``n = d26`` rounds each coordinate of ``start + k/n (end - start)``.

    Every coordinate is treated alike (no major axis), as in the paper's symmetric form.

    >>> line26_symmetric((0, 0, 0), (4, -2, 1)).tolist()
    [[0, 0, 0], [1, -1, 0], [2, -1, 1], [3, -2, 1], [4, -2, 1]]
    """
    start, end = np.asarray(start, np.int64), np.asarray(end, np.int64)
    n = int(d26(end - start))
    if n == 0:
        return start[None]
    k = np.arange(n + 1)[:, None]
    delta = end - start
    # round half away from zero, in integers: floor((2 k d + n) / 2n) for d >= 0, mirrored for d < 0
    return start + np.sign(delta) * ((2 * k * np.abs(delta) + n) // (2 * n))


def line18(start, end):
    """The best-approximation 18-line: from each voxel, the 18-neighbour toward ``end`` nearest to the line.

    Ties (equally near) go to the move that advances farther along the line, then to the
    lower axes.  As the paper's Fig. 2 shows, it can be longer than the shortest 18-path:

    >>> path = line18((0, 0, 0), (2, 2, 2))
    >>> path.tolist(), len(path) - 1, int(d18([2, 2, 2]))
    ([[0, 0, 0], [1, 1, 0], [1, 1, 1], [2, 2, 1], [2, 2, 2]], 4, 3)
    """
    start, end = np.asarray(start, np.int64), np.asarray(end, np.int64)
    delta = (end - start).astype(float)
    length = np.linalg.norm(delta)
    unit = delta / length if length else delta
    step_sign = np.where(delta < 0, -1, 1)
    moves = np.array([m for m in np.ndindex(2, 2, 2) if 1 <= sum(m) <= 2][::-1]) * step_sign  # x, y first
    path = [start]
    current = start
    while np.any(current != end):
        candidates = current + moves
        within = np.all((candidates - start) * step_sign <= (end - start) * step_sign, axis=1)
        relative = (candidates - start).astype(float)
        along = relative @ unit
        distance = np.linalg.norm(relative - along[:, None] * unit, axis=1)
        key = np.lexsort((np.arange(len(moves)), -along.round(12), distance.round(12)))
        current = candidates[[k for k in key if within[k]][0]]
        path.append(current)
    return np.array(path)


def line6_tripod(start, end):
    """The tripod 6-line of Fig. 6, from the voxel holding ``start`` to the voxel holding ``end``.

    Sub-voxel end points are allowed: the decision variables are the three projections'
    implicit equations at the current voxel's exit corner ``(x + 1/2, y + 1/2, z + 1/2)``;
    each test rules out one face of the tripod.  Every voxel the segment pierces is on the
    path (containment), and the path has ``d6 + 1`` voxels.

    >>> line6_tripod((0, 0, 0), (2, 1, 0)).tolist()
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [2, 1, 0]]
    """
    frame = Frame.of(start, end)
    a, b, c = frame.extent
    target = frame.steps_to(end)
    e_xy, e_xz, e_zy = frame.f_xy(0.5, 0.5), frame.f_xz(0.5, 0.5), frame.f_zy(0.5, 0.5)
    q = np.zeros(3, np.int64)
    path = [q.copy()]
    for _ in range(int(target.sum())):
        if e_xy < 0:                 # not y
            if e_xz < 0:             # not z: x
                q[0] += 1
                e_xy += b
                e_xz += c
            else:                    # z
                q[2] += 1
                e_xz -= a
                e_zy += b
        elif e_zy < 0:               # not x, not y: z
            q[2] += 1
            e_xz -= a
            e_zy += b
        else:                        # y
            q[1] += 1
            e_xy -= a
            e_zy -= c
        path.append(q.copy())
    return frame.to_object(np.array(path))


def line6_parametric(start, end):
    """The parametric 6-line of Amanatides and Woo (Fig. 7): step across whichever face the line meets first.

    >>> line6_parametric((0, 0, 0), (2, 1, 0)).tolist()
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [2, 1, 0]]
    """
    start, end = np.asarray(start, float), np.asarray(end, float)
    voxel = np.floor(start + 0.5).astype(np.int64)
    last = np.floor(end + 0.5).astype(np.int64)
    delta = end - start
    step = np.where(delta < 0, -1, 1)
    with np.errstate(divide="ignore"):
        t_delta = np.where(delta != 0, 1 / np.abs(delta), np.inf)
        t_max = np.where(delta != 0, (voxel + 0.5 * step - start) / np.where(delta != 0, delta, 1), np.inf)
    path = [voxel.copy()]
    for _ in range(int(np.abs(last - voxel).sum())):
        k = int(np.argmin(t_max))
        voxel[k] += step[k]
        t_max[k] += t_delta[k]
        path.append(voxel.copy())
    return np.array(path)


def line2d_switch(start, end, occupied):
    """Fig. 8: an 8-connected 2-D line from ``start`` to ``end`` (integer pixels) that switches to
    4-connectivity at the first nonempty pixel (``occupied[y, x]``), using ``e4 = e8 - B`` (Eq. 8, doubled).

    Returns the pixel path ``(n, 2)`` as (x, y) and the index where it switched (or ``None``).

    >>> grid = np.zeros((4, 6), bool); grid[1, 2] = True
    >>> path, switched = line2d_switch((0, 0), (5, 3), grid)
    >>> path.tolist(), switched
    ([[0, 0], [1, 1], [2, 1], [2, 2], [3, 2], [4, 2], [4, 3], [5, 3]], 2)
    """
    (x0, y0), (x1, y1) = start, end
    sx, sy = (1 if x1 >= x0 else -1), (1 if y1 >= y0 else -1)
    swap = abs(y1 - y0) > abs(x1 - x0)
    a, b = (abs(y1 - y0), abs(x1 - x0)) if swap else (abs(x1 - x0), abs(y1 - y0))
    u = v = 0
    path, switched = [(u, v)], None

    def pixel(u, v):
        du, dv = (v, u) if swap else (u, v)
        return x0 + sx * du, y0 + sy * dv

    e8 = 2 * b - a             # midpoint (u + 1, v + 1/2), doubled
    while u < a:
        x, y = pixel(u, v)
        if occupied[y, x]:
            switched = len(path) - 1
            break
        if e8 < 0:
            e8 += 2 * b
            u += 1
        else:
            e8 += 2 * b - 2 * a
            u += 1
            v += 1
        path.append((u, v))
    if switched is not None:
        e4 = e8 - b            # midpoint (u + 1/2, v + 1/2), doubled (Eq. 8)
        while (u, v) != (a, b):
            if e4 < 0:
                e4 += 2 * b
                u += 1
            else:
                e4 -= 2 * a
                v += 1
            path.append((u, v))
    return np.array([pixel(u, v) for u, v in path]), switched


class Stepper:
    """Many lines stepped together, each as a 26-line or a 6-line, switching with Eqs. 9-13.

    Lines run from real ``starts`` toward real ``ends`` (arrays ``(n, 3)``).  In 26 mode the
    decision variables are ``e_y, e_z`` (midpoints at ``x + 1``, Fig. 4); in 6 mode they are
    ``e_xy, e_xz, e_zy`` (the tripod's exit corner, Fig. 6).  :meth:`step` advances the
    lines selected by ``active``, those in ``six`` as 6-lines and the others as 26-lines.

    Examples
    --------
    >>> lines = Stepper(np.array([[0.0, 0.0, 0.0]]), np.array([[4.0, 2.0, 1.0]]))
    >>> for _ in range(4):
    ...     _ = lines.step(np.array([True]), np.array([False]))
    >>> lines.voxels.tolist()
    [[4, 2, 1]]
    """

    def __init__(self, starts, ends):
        frame = Frame.of(starts, ends)
        self.origin, self.sign, self.order, self.offset, self.extent = (
            frame.origin, frame.sign, frame.order, frame.offset, frame.extent)
        self.unorder = np.argsort(self.order, axis=1)  # frame axis -> object axis, for voxels
        self.q = np.zeros_like(self.origin)
        self.six = np.zeros(len(starts), bool)
        a, b, c = self.extent.T
        ox, oy, oz = self.offset.T
        # 26 mode at q = 0: e_y = f_xy(1, 1/2), e_z = f_xz(1, 1/2)
        self.e_y = b * (1 - ox) - a * (0.5 - oy)
        self.e_z = c * (1 - ox) - a * (0.5 - oz)
        self.e_xy = self.e_y - 0.5 * b
        self.e_xz = self.e_z - 0.5 * c
        self.e_zy = b * (0.5 - oz) - c * (0.5 - oy)

    def subset(self, keep):
        """The lines selected by ``keep`` (bool or index array), as a new stepper in the same state."""
        other = object.__new__(Stepper)
        for name in ("origin", "sign", "order", "unorder", "offset", "extent", "q", "six", "e_y", "e_z", "e_xy",
                     "e_xz", "e_zy"):
            setattr(other, name, getattr(self, name)[keep])
        return other

    @property
    def voxels(self):
        """Current voxel of every line, in object coordinates."""
        return self.origin + self.sign * np.take_along_axis(self.q, self.unorder, axis=1)

    def switch(self, six):
        """Set each line's connectivity: Eqs. 9-11 into 6 mode, Eqs. 12-13 back to 26 mode."""
        a, b, c = self.extent.T
        to_six = six & ~self.six
        to_26 = ~six & self.six
        qx, qy, qz = self.q.T
        ox, oy, oz = self.offset.T
        self.e_xy = np.where(to_six, self.e_y - 0.5 * b, self.e_xy)                       # Eq. 9
        self.e_xz = np.where(to_six, self.e_z - 0.5 * c, self.e_xz)                       # Eq. 10
        self.e_zy = np.where(to_six, b * (qz + 0.5 - oz) - c * (qy + 0.5 - oy), self.e_zy)  # Eq. 11
        self.e_y = np.where(to_26, self.e_xy + 0.5 * b, self.e_y)                         # Eq. 12
        self.e_z = np.where(to_26, self.e_xz + 0.5 * c, self.e_z)                         # Eq. 13
        self.six = six.copy()

    def jump(self, count, within=None):
        """Take ``count[i]`` 26-steps at once on line ``i`` (0 for none), in closed form.

        In 26 mode the midpoint error of each minor axis runs ``e <- e + b``, less ``a`` when ``e >= 0`` (a step
        up that axis).  From the interval ``[b - a, b)``, which those steps keep, ``k`` steps go up
        ``floor((e + k b - b + a) / a)`` times: the voxel that ``k`` calls of :meth:`step` reach.  A line whose
        error lies outside that interval (just after 6 mode), or whose landing voxel would lie outside the box
        ``within`` (``(nx, ny, nz)``, voxels ``0 .. n - 1``), is not moved.  Returns how many steps each took.
        """
        count = np.asarray(count, np.int64)
        a, b, c = self.extent.T
        k = np.where((count > 0) & ~self.six & (self.e_y >= b - a) & (self.e_y < b) & (self.e_z >= c - a) &
                     (self.e_z < c) & (a > 0), count, 0)
        safe_a = np.where(a > 0, a, 1.0)
        moves = []
        for e, minor in ((self.e_y, b), (self.e_z, c)):
            ups = np.floor((e + (k - 1) * minor + a) / safe_a).astype(np.int64)
            after = e + k * minor - ups * a
            ups += (after >= minor).astype(np.int64) - (after < minor - a).astype(np.int64)   # rounding at the edges
            moves.append(np.where(k > 0, ups, 0))
        q = self.q + np.stack([k, *moves], axis=1)
        if within is not None:             # the path is monotone along every axis: inside when its landing is
            landing = self.origin + self.sign * np.take_along_axis(q, self.unorder, axis=1)
            k = np.where(np.any((landing < 0) | (landing >= np.asarray(within)), axis=1), 0, k)
            q = np.where((k > 0)[:, None], q, self.q)
            moves = [np.where(k > 0, m, 0) for m in moves]
        self.e_y = self.e_y + k * b - moves[0] * a
        self.e_z = self.e_z + k * c - moves[1] * a
        self.q = q
        return k

    def step(self, active, six):
        """Advance the ``active`` lines one voxel; return the number of 26-steps and 6-steps taken."""
        self.switch(six)
        a, b, c = self.extent.T
        move = np.zeros_like(self.q)
        # 26 mode (Fig. 4): x always; y and z when their midpoint errors are not negative.
        long = active & ~six
        up_y, up_z = long & (self.e_y >= 0), long & (self.e_z >= 0)
        move[long, 0] = 1
        move[up_y, 1] = 1
        move[up_z, 2] = 1
        self.e_y = np.where(long, self.e_y + b - np.where(up_y, a, 0), self.e_y)
        self.e_z = np.where(long, self.e_z + c - np.where(up_z, a, 0), self.e_z)
        # 6 mode (Fig. 6): the tripod's three tests pick one face.
        short = active & six
        not_y = self.e_xy < 0
        go_x = short & not_y & (self.e_xz < 0)
        go_z = short & ((not_y & (self.e_xz >= 0)) | (~not_y & (self.e_zy < 0)))
        go_y = short & ~not_y & (self.e_zy >= 0)
        move[go_x, 0] = 1
        move[go_y, 1] = 1
        move[go_z, 2] = 1
        self.e_xy = self.e_xy + np.where(go_x, b, 0) - np.where(go_y, a, 0)
        self.e_xz = self.e_xz + np.where(go_x, c, 0) - np.where(go_z, a, 0)
        self.e_zy = self.e_zy + np.where(go_z, b, 0) - np.where(go_y, c, 0)
        self.q += move
        return int(long.sum()), int(short.sum())


# Table 1's analytical row: the mean ratio of the distances between random end points
# (row metric over column metric).  Its printed d26/d6 entry, 0.526, is read here as a
# swap of the digits of 0.562, which is E[d26/d6] (see metrics_table and the README).
TABLE1_ANALYTICAL = {("d6", "d18"): 1.76, ("d6", "d26"): 1.866, ("d18", "d6"): 0.58, ("d18", "d26"): 1.053,
                     ("d26", "d6"): 0.562, ("d26", "d18"): 0.956}
TABLE1_PRINTED = {("d26", "d6"): 0.526}  # as the paper prints it


def metrics_table(trials=100_000, seed=0, side=100):
    """Tables 1 and 2 by experiment: random end points in a ``side``^3 voxel space.

    Returns the mean lengths (Table 2), the mean of each ratio and the ratio of the means
    (the paper's experimental row), the analytical values and their differences.

    >>> table = metrics_table(20000, seed=1)
    >>> abs(table["mean_ratio"][("d6", "d26")] - 1.866) < 0.02
    True
    """
    rng = np.random.default_rng(seed)
    delta = rng.integers(0, side, (trials, 3)) - rng.integers(0, side, (trials, 3))
    delta = delta[np.any(delta != 0, axis=1)]
    lengths = {"d6": d6(delta).astype(float), "d18": d18(delta).astype(float), "d26": d26(delta).astype(float)}
    means = {k: float(v.mean()) for k, v in lengths.items()}
    pairs = list(TABLE1_ANALYTICAL)
    return {"trials": len(delta), "side": side, "seed": seed, "mean_length": means,
            "analytical_length": {"d6": float(side), "d26": 19 / 35 * side},
            "mean_ratio": {p: float((lengths[p[0]] / lengths[p[1]]).mean()) for p in pairs},
            "ratio_of_means": {p: means[p[0]] / means[p[1]] for p in pairs},
            "analytical_ratio": dict(TABLE1_ANALYTICAL)}
