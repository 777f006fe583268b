"""Analysis building blocks against closed-form geometry."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from simbench.analysis import along_path, deviation_near_reference, path_deviation, spans
from simbench.render import simplify

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
    half = 0.5 * np.linalg.norm(b - a) / 2000
    # Exact near the path; beyond 100 half-segments the nearest vertex, within half^2 / (2 r) (the docstring).
    allowed = 1e-9 if exact < 99 * half else half**2 / (2 * exact) + 1e-12
    assert exact - 1e-12 <= dist[0] <= exact + allowed


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
