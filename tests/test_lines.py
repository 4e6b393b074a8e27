import numpy as np
import pytest

from voxrender.space import lines


def pierced(start, end):
    """Exact reference: every voxel whose closed cube the segment crosses with positive length.

    The segment is cut at every parameter where it crosses a plane k + 1/2; the voxel holding
    the middle of each piece is pierced.
    """
    start, end = np.asarray(start, float), np.asarray(end, float)
    delta = end - start
    cuts = [0.0, 1.0]
    for k in range(3):
        if delta[k]:
            lo, hi = sorted((start[k], end[k]))
            planes = np.arange(np.ceil(lo - 0.5), np.floor(hi - 0.5) + 1) + 0.5
            cuts += list((planes - start[k]) / delta[k])
    cuts = np.unique(np.clip(cuts, 0, 1))
    middles = (cuts[:-1] + cuts[1:]) / 2
    return {tuple(v) for v in np.floor(start + middles[:, None] * delta + 0.5).astype(int)}


def random_segments(count, seed, integer=False):
    rng = np.random.default_rng(seed)
    starts = rng.uniform(-20, 20, (count, 3))
    ends = starts + rng.uniform(-15, 15, (count, 3))
    if integer:
        return np.rint(starts).astype(int), np.rint(ends).astype(int)
    return starts, ends


def test_metrics():
    delta = np.array([[3, -1, 2], [0, 0, 5], [2, 2, 2]])
    assert lines.d6(delta).tolist() == [6, 5, 6]
    assert lines.d26(delta).tolist() == [3, 5, 2]
    assert lines.d18(delta).tolist() == [3, 5, 3]
    # 1 <= d6 / d26 <= 3 (Eq. 4)
    rng = np.random.default_rng(0)
    many = rng.integers(-50, 50, (1000, 3))
    many = many[lines.d26(many) > 0]
    ratio = lines.d6(many) / lines.d26(many)
    assert ratio.min() >= 1 and ratio.max() <= 3


def test_d18_triangle_inequality():
    rng = np.random.default_rng(1)
    p, q, r = (rng.integers(-9, 9, (3000, 3)) for _ in range(3))
    assert np.all(lines.d18(p - r) <= lines.d18(p - q) + lines.d18(q - r))


@pytest.mark.parametrize("make", [lines.line26, lines.line26_symmetric])
def test_26_lines_are_shortest_26_paths(make):
    starts, ends = random_segments(200, 2, integer=True)
    for s, e in zip(starts, ends, strict=True):
        path = make(s, e)
        assert path[0].tolist() == s.tolist() and path[-1].tolist() == e.tolist()
        assert lines.is_connected(path, 26)
        assert len(path) - 1 == lines.d26(e - s)  # best approximation length = d26


def test_26_line_stays_within_half_a_voxel():
    starts, ends = random_segments(100, 3, integer=True)
    for s, e in zip(starts, ends, strict=True):
        path = lines.line26(s, e)
        major = int(np.argmax(np.abs(e - s)))
        t = (path[:, major] - s[major]) / (e[major] - s[major]) if e[major] != s[major] else np.zeros(len(path))
        exact = s + t[:, None] * (e - s)
        assert np.all(np.abs(path - exact) <= 0.5 + 1e-9)  # so the line pierces each of its voxels


@pytest.mark.parametrize("make", [lines.line6_tripod, lines.line6_parametric])
def test_6_lines_have_the_containment_property(make):
    starts, ends = random_segments(300, 4)
    for s, e in zip(starts, ends, strict=True):
        path = make(s, e)
        assert lines.is_connected(path, 6)
        voxels = {tuple(v) for v in path}
        assert pierced(s, e) <= voxels
        assert len(path) - 1 == lines.d6(np.floor(e + 0.5) - np.floor(s + 0.5))  # length = d6


def test_tripod_and_parametric_agree():
    starts, ends = random_segments(300, 5)
    for s, e in zip(starts, ends, strict=True):
        assert np.array_equal(lines.line6_tripod(s, e), lines.line6_parametric(s, e))


def test_18_line_example_of_fig_2():
    path = lines.line18((0, 0, 0), (2, 2, 2))
    assert lines.is_connected(path, 18)
    assert [1, 1, 1] in path.tolist()             # the voxel on the continuous line
    assert len(path) - 1 == 4 > lines.d18([2, 2, 2]) == 3  # best approximation is not shortest


def test_18_lines_connect_their_end_points():
    starts, ends = random_segments(60, 6, integer=True)
    for s, e in zip(starts, ends, strict=True):
        path = lines.line18(s, e)
        assert path[-1].tolist() == e.tolist() and lines.is_connected(path, 18)
        assert len(path) - 1 >= lines.d18(e - s)


def test_2d_switch_from_8_to_4_connectivity():
    grid = np.zeros((12, 20), bool)
    grid[5:, 9:] = True
    path, switched = lines.line2d_switch((0, 0), (19, 11), grid)
    steps = np.abs(np.diff(path, axis=0))
    assert (steps.sum(axis=1)[:switched] <= 2).all() and (steps.sum(axis=1)[switched:] == 1).all()
    assert grid[path[switched][1], path[switched][0]]
    assert path[-1].tolist() == [19, 11]
    no_switch, never = lines.line2d_switch((0, 0), (19, 11), np.zeros_like(grid))
    assert never is None and len(no_switch) == 20


def _stepped_paths(starts, ends, steps, six):
    """The voxels a Stepper visits on each line, ``steps[i]`` steps in one mode (``six``: 6-steps)."""
    stepper = lines.Stepper(starts, ends)
    paths = [[v] for v in stepper.voxels]
    for k in range(int(steps.max())):
        stepper.step(k < steps, np.full(len(steps), six))
        for i, v in enumerate(stepper.voxels):
            if k < steps[i]:
                paths[i].append(v)
    return [np.array(path) for path in paths]


def test_stepper_26_and_6_modes_match_the_single_line_algorithms():
    starts, ends = random_segments(50, 7, integer=True)
    for s, e, path in zip(starts, ends, _stepped_paths(starts, ends, lines.d26(ends - starts), six=False), strict=True):
        assert np.array_equal(path, lines.line26(s, e))
    starts, ends = random_segments(50, 8)
    steps = lines.d6(np.floor(ends + 0.5) - np.floor(starts + 0.5))
    for s, e, path in zip(starts, ends, _stepped_paths(starts, ends, steps, six=True), strict=True):
        assert np.array_equal(path, lines.line6_tripod(s, e))


def test_switching_keeps_the_decision_variables_consistent():
    """After any mix of 26- and 6-steps, Eqs. 9-13 give the values the definitions give."""
    starts, ends = random_segments(40, 9)
    stepper = lines.Stepper(starts, ends)
    rng = np.random.default_rng(10)
    for _ in range(12):
        six = rng.random(len(starts)) < 0.5
        stepper.step(np.ones(len(starts), bool), six)
        stepper.switch(~six)
        stepper.switch(six)
    a, b, c = stepper.extent.T
    ox, oy, oz = stepper.offset.T
    qx, qy, qz = stepper.q.T
    if stepper.six.any():
        m = stepper.six
        assert np.allclose(stepper.e_xy[m], (b * (qx + 0.5 - ox) - a * (qy + 0.5 - oy))[m])
        assert np.allclose(stepper.e_zy[m], (b * (qz + 0.5 - oz) - c * (qy + 0.5 - oy))[m])
    m = ~stepper.six
    assert np.allclose(stepper.e_y[m], (b * (qx + 1 - ox) - a * (qy + 0.5 - oy))[m])


def test_adaptive_lines_keep_containment_in_6_mode():
    """A line switched to 6 mode anywhere still visits every pierced voxel from there on."""
    starts, ends = random_segments(60, 11)
    stepper = lines.Stepper(starts, ends)
    n26 = 4
    for _ in range(n26):
        stepper.step(lines.d26(np.floor(ends + 0.5) - stepper.voxels) > 0, np.zeros(len(starts), bool))
    here = stepper.voxels.copy()
    remaining = lines.d6(np.floor(ends + 0.5) - here)
    visited = [{tuple(v)} for v in here]
    for k in range(int(remaining.max())):
        stepper.step(k < remaining, np.ones(len(starts), bool))
        for i, v in enumerate(stepper.voxels):
            visited[i].add(tuple(v))
    for i, (s, e) in enumerate(zip(starts, ends, strict=True)):
        # from the switch on, the path contains every voxel the rest of the segment pierces
        along = here[i] - s
        t = np.clip(along @ (e - s) / ((e - s) @ (e - s)), 0, 1)
        tail = pierced(s + t * (e - s), e)
        assert {v for v in tail if lines.d6(np.array(v) - here[i]) > 1} <= visited[i]


def test_table_1_ratios_within_0_02():
    table = lines.metrics_table(200_000, seed=3)
    for pair, analytical in lines.TABLE1_ANALYTICAL.items():
        assert abs(table["mean_ratio"][pair] - analytical) <= 0.02, pair
    assert abs(table["mean_length"]["d26"] - 19 / 35 * 100) < 1.0  # Table 2: 54.34
    assert abs(table["mean_length"]["d6"] - 100) < 1.0
