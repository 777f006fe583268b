"""Analysis building blocks against closed-form geometry."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from simbench.analysis import along_path, deviation_near_reference, path_deviation
from simbench.analysis.limit_events import PlanLimits
from simbench.core import windowed
from simbench.core.windowed import spans
from simbench.maths.path_distance import _capsules, _nearest
from simbench.outputs.render import simplify

coords = st.floats(-1.0, 1.0, allow_nan=False)
point = st.tuples(coords, coords, coords).map(np.array)


@settings(max_examples=60, deadline=None)
@given(a=point, b=point, p=point)
def test_distance_from_a_sampled_segment_is_the_segment_distance(a, b, p):
    if np.linalg.norm(b - a) < 1e-3:
        return
    path = a + np.linspace(0, 1, 2001)[:, None] * (b - a)
    dist = path_deviation(path, p[None])
    u = np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
    exact = np.linalg.norm(a + u * (b - a) - p)
    assert abs(dist[0] - exact) <= 1e-12


def test_distance_from_a_circle():
    theta = np.linspace(0, 1.5 * np.pi, 20001)
    circle = np.stack([0.2 * np.cos(theta), 0.2 * np.sin(theta), np.zeros_like(theta)], axis=1)
    probe = np.array([[0.25 * np.cos(0.7), 0.25 * np.sin(0.7), 0.03]])
    dist = path_deviation(circle, probe)
    assert abs(dist[0] - np.hypot(0.05, 0.03)) < 1e-6


def test_a_path_that_comes_back_does_not_hide_a_point_off_its_own_stretch():
    """A circle traced twice, 1000 samples a turn; the points follow it 0.01 off the plane, except that during
    the first turn they sit where the second turn will be a quarter turn later. Near the reference the distance
    is the true one; against the whole path the first turn's points would look on it."""
    theta = np.linspace(0, 4 * np.pi, 2001)
    path = np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], axis=1)
    points = path + [0.0, 0.0, 0.01]
    early = slice(200, 300)
    points[early] = path[np.arange(200, 300) + 1250]
    near = deviation_near_reference(path, points, window=100)
    whole = path_deviation(path, points)
    assert np.allclose(near[300:], 0.01, atol=1e-9) and np.allclose(whole[300:], 0.01, atol=1e-9)
    # Their block (samples 200-299) is searched on samples 100-399: each point, at angle phi past that stretch's
    # end, is a chord 2 sin((phi - end) / 2) from it.
    step = 2 * np.pi / 1000
    phi = np.mod((np.arange(200, 300) + 1250) * step, 2 * np.pi)
    assert np.allclose(near[early], 2 * np.sin((phi - 399 * step) / 2), atol=1e-9)
    assert np.all(whole[early] < 1e-9)


def test_lag_is_the_error_along_the_tangent_even_where_the_path_closes():
    theta = np.linspace(0, 2 * np.pi, 4001)
    circle = np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], axis=1)
    tangent = along_path(np.vstack([circle, np.repeat(circle[-1:], 50, axis=0)]))
    assert np.allclose(np.linalg.norm(tangent, axis=1), 1.0)
    assert np.allclose(tangent[:4001], np.stack([-np.sin(theta), np.cos(theta), 0 * theta], axis=1), atol=1e-3)
    assert np.allclose(tangent[4001:], tangent[4000])


def test_row_norms_are_numpys_to_the_bit():
    """windowed.norms adds the squares in np.linalg.norm's order: the same numbers, on rows of any scale and on a
    strided view (a recording's columns)."""
    rng = np.random.default_rng(14)
    rows = rng.normal(size=(5000, 7)) * 10.0 ** rng.integers(-150, 150, (5000, 1))
    for v in (rows[:, :3], rows[:, 4:], np.diff(rows[:, 2:5], axis=0), np.zeros((0, 3))):
        assert np.array_equal(windowed.norms(v), np.linalg.norm(v, axis=1))


def test_spans_of_a_mask():
    mask = np.array([0, 1, 1, 0, 0, 1, 0, 1, 1, 1], bool)
    assert spans(mask) == [(1, 2), (5, 5), (7, 9)]
    assert spans(np.zeros(4, bool)) == []
    assert spans(np.ones(3, bool)) == [(0, 2)]


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10**6), tol=st.floats(1e-4, 1e-2))
def test_simplified_polyline_stays_within_tolerance(seed, tol):
    rng = np.random.default_rng(seed)
    pts = np.cumsum(rng.normal(scale=0.01, size=(300, 3)), axis=0)
    kept = simplify(pts, tol)
    assert kept[0] == 0 and kept[-1] == len(pts) - 1
    dist = path_deviation(pts[kept], pts)
    assert dist.max() <= tol + 1e-12


# --- the search of the planned path (path_distance._nearest, ._deviation) against brute force -------------------------

def _segment_distances(path: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Distance of p from every segment of path, one by one."""
    a, ab = path[:-1], np.diff(path, axis=0)
    length2 = np.einsum("ij,ij->i", ab, ab)
    u = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
    return np.linalg.norm(a + u[:, None] * ab - p, axis=1)


def _within(got: np.ndarray, points: np.ndarray, want: np.ndarray) -> bool:
    """Whether each distance found is the true one to 1e-12 m, or 1e-13 of the point's coordinates beyond 10 m."""
    return bool(np.all(np.abs(got - want) <= np.maximum(1e-12, 1e-13 * np.abs(points).max(axis=1))))


def _brute_force(path: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Each point's least distance from every segment of path (from its one vertex if it has no segment)."""
    if len(path) == 1:
        return np.linalg.norm(points - path[0], axis=1)
    return np.array([_segment_distances(path, p).min() for p in points])


def _random_path(rng: np.random.Generator, n: int) -> np.ndarray:
    """A wandering path with what the planned paths have: stretches that crawl (steps of 1e-9 of the others, as a
    4-5-6-7 law's ends), samples repeated (a hold), a jump, and a return near where it has been."""
    steps = rng.normal(scale=0.01, size=(n - 1, 3))
    steps[: n // 6] *= 1e-9
    steps[n // 3: n // 3 + n // 10] = 0.0
    steps[n // 2] *= 200
    path = np.concatenate([[np.zeros(3)], np.cumsum(steps, axis=0)])
    back = n // 8
    path[n - back:] = path[n // 4: n // 4 + back][::-1] + 1e-4
    return path


def _offsets(rng: np.random.Generator, m: int) -> np.ndarray:
    """Offsets (m, 3) that put points on, near, off and far from a path: 0 to about 100 m."""
    return rng.normal(size=(m, 3)) * rng.choice([0.0, 1e-7, 1e-3, 0.05, 2.0, 100.0], (m, 1))


def test_the_distance_from_a_path_is_the_least_over_every_segment():
    """path_deviation against brute force over every segment, on 48 paths at random (fixed seed): wandering ones
    with crawls, holds and jumps, a few vertices at random, a path of one point and a circle with its centre (every
    segment equally near), to 1e-12 m (1e-13 of the point's coordinates beyond 10 m: `_within`)."""
    rng = np.random.default_rng(14)
    theta = np.linspace(0, 2 * np.pi, 400)
    paths = [_random_path(rng, n) for n in rng.integers(17, 1500, 40)]
    paths += [rng.normal(size=(n, 3)) for n in (1, 2, 3, 5, 9, 16)]
    paths += [np.stack([np.cos(theta), np.sin(theta), 0 * theta], axis=1), np.repeat(rng.normal(size=(1, 3)), 5, 0)]
    for path in paths:
        points = path[rng.integers(0, len(path), 200)] + _offsets(rng, 200)
        if len(path) == 400:
            points[0] = 0.0
        assert _within(path_deviation(path, points), points, _brute_force(path, points)), len(path)


def test_the_branch_and_bound_finds_every_points_nearest_segment_in_its_range():
    """_nearest against every segment of each point's range, ranges and paths at random (fixed seed): the distance
    within its tolerance (1e-12 of the scale)."""
    rng = np.random.default_rng(14)
    for n in (2, 3, 5, 17, 300, 1000):
        path = _random_path(rng, n) if n > 16 else rng.normal(size=(n, 3))
        tree = _capsules(path)
        m = 200
        points = path[rng.integers(0, n, m)] + rng.normal(size=(m, 3)) * rng.choice([1e-6, 1e-3, 0.1, 3.0], (m, 1))
        first = rng.integers(0, n - 1, m)
        last = np.minimum(first + rng.integers(0, n, m), n - 2)
        order = np.lexsort((last, first))  # runs of equal ranges, as _deviation's blocks give them
        points, first, last = points[order], first[order], last[order]
        guess = np.minimum(first + rng.integers(0, 3, m), last)
        exact = np.array([_segment_distances(path[f:l + 2], p).min() for p, f, l in zip(points, first, last)])
        tol = 1e-12 * (1 + np.abs(path).max() + np.abs(points).max())
        found = _nearest(tree, points, first, last, guess)
        assert np.all(np.abs(found - exact) <= 2 * tol), n


@pytest.mark.parametrize("group", [1 << 17, 1, 500])
def test_deviation_near_reference_is_the_distance_from_each_blocks_stretch(group, monkeypatch):
    """deviation_near_reference against brute force over every segment of each block's stretch of path (the block
    and the blocks either side), on random paths (fixed seed) with points on, near, off and far from them, to
    1e-12 m (`_within`): searched whole (one group of blocks, as every shipped scenario is), a block at a time and
    in groups of blocks (a long run's: each group on its own stretch of path); the same given the points a window
    of the analysis at a time (`start`)."""
    monkeypatch.setattr(windowed, "GROUP", group)
    rng = np.random.default_rng(140)
    for n, window in ((400, 60), (700, 250), (90, 200), (450, 300), (2000, 170)):
        path = _random_path(rng, n)
        points = path[np.clip(np.arange(n) - rng.integers(0, 5, n), 0, n - 1)] + _offsets(rng, n)  # at or behind
        got = deviation_near_reference(path, points, window)
        for start in range(0, n, window):
            stop = min(start + window, n)
            want = _brute_force(path[max(start - window, 0):stop + window], points[start:stop])
            assert _within(got[start:stop], points[start:stop], want), (n, window, start)
        for size in (window, 97):
            cut = np.concatenate([deviation_near_reference(path, points[lo:lo + size], window, lo)
                                  for lo in range(0, n, size)])
            assert _within(cut, points, got), (n, window, size)


@pytest.mark.parametrize("seed", range(4))
def test_the_plans_limit_events_a_window_at_a_time_are_those_of_the_whole_plan(seed):
    """A random plan whose references pass the joints' ranges and speed limits in spans, many of them across
    window edges (windows of 1 to 40 rows): `joint_limit` and `velocity_limit` events found a window at a time are
    those found from the whole plan at once, and each is a span of the references beyond the bound, with its worst
    value, checked here sample by sample."""
    from simbench.api import registry
    from simbench.api.trajectory import JointTrajectory

    robot = registry.robots()["spherical_arm"]
    rng = np.random.default_rng(seed)
    n, dof = 600, robot.dof
    t = np.arange(n) * 0.01
    lower, upper = np.maximum(robot.lower, -np.pi), np.minimum(robot.upper, np.pi)  # a range for every joint
    middle, half = (lower + upper) / 2, (upper - lower) / 2
    q = middle + 1.2 * half * np.sin(np.cumsum(rng.normal(scale=0.08, size=(n, dof)), axis=0))
    qd = robot.qd_max * 1.3 * np.sin(np.cumsum(rng.normal(scale=0.1, size=(n, dof)), axis=0))
    traj = JointTrajectory(t=t, s=t / t[-1], q_ref=q, qd_ref=qd, tool_ref=np.zeros((n, 3)))
    whole = PlanLimits(robot)
    whole.add(traj, 0)
    windows = PlanLimits(robot)
    lo = 0
    while lo < n:
        hi = min(lo + int(rng.integers(1, 41)), n)
        windows.add(traj.rows(slice(lo, hi)), lo)
        lo = hi
    events = whole.events(t)
    assert windows.events(t) == events
    kinds = {e["kind"] for e in events}
    assert kinds == {"joint_limit", "velocity_limit"}
    for e in events:
        j = robot.joints.index(e["detail"]["joint"])
        a, b = np.searchsorted(t, [e["t_start"], e["t_end"]])
        if e["kind"] == "joint_limit":
            values, bound = q[:, j], e["detail"]["bound"]
            beyond = values < robot.lower[j] - 1e-9 if bound == "lower" else values > robot.upper[j] + 1e-9
            worst = values[a:b + 1].min() if bound == "lower" else values[a:b + 1].max()
        else:
            values = np.abs(qd[:, j])
            beyond, worst = values > robot.qd_max[j], values[a:b + 1].max()
        assert beyond[a:b + 1].all() and not beyond[max(a - 1, 0):a].any() and not beyond[b + 1:b + 2].any()
        assert e["detail"]["worst"] == worst
