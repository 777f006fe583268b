"""Time laws: boundary conditions, monotonicity, and derivatives against finite differences."""

import numpy as np
import pytest

from simbench.maths.timing import LAWS, TimeLaw

T = 2.5


@pytest.mark.parametrize("name", LAWS)
def test_law_starts_and_ends_at_rest(name):
    law = TimeLaw(name, T)
    s, ds, dds = law(np.array([0.0, T]))
    assert s.tolist() == pytest.approx([0.0, 1.0], abs=1e-12)
    assert ds.tolist() == pytest.approx([0.0, 0.0], abs=1e-12)


@pytest.mark.parametrize("name", LAWS)
def test_law_is_monotone_and_held_outside_its_duration(name):
    t = np.linspace(-0.5, T + 0.5, 3001)
    s, ds, _ = TimeLaw(name, T)(t)
    assert np.all(np.diff(s) >= -1e-15)
    assert np.all(s[t <= 0] == 0) and np.all(s[t >= T] == 1)
    assert np.all(ds[(t <= 0) | (t >= T)] == 0)


@pytest.mark.parametrize("name", LAWS)
def test_derivatives_match_finite_differences(name):
    t = np.linspace(0.01, T - 0.01, 20001)
    s, ds, dds = TimeLaw(name, T)(t)
    h = t[1] - t[0]
    smooth = np.ones_like(t, bool)
    if name == "trapezoidal":  # acceleration jumps at the two switching times
        f = 0.25 * T
        smooth = (np.abs(t - f) > 3 * h) & (np.abs(t - (T - f)) > 3 * h)
    assert np.allclose(np.gradient(s, h)[smooth][1:-1], ds[smooth][1:-1], atol=1e-6)
    assert np.allclose(np.gradient(ds, h)[smooth][1:-1], dds[smooth][1:-1], atol=1e-4)


def test_quintic_and_4567_start_and_end_with_zero_acceleration():
    for name in ("quintic", "4567"):
        assert TimeLaw(name, T)(np.array([0.0, T]))[2] == pytest.approx([0, 0], abs=1e-12)


def test_4567_has_zero_jerk_at_both_ends_and_matches_paper_003():
    law = TimeLaw("4567", T)
    tau = np.linspace(0, 1, 11)
    s = law(tau * T, order=0)[0]
    assert np.allclose(s, 35 * tau**4 - 84 * tau**5 + 70 * tau**6 - 20 * tau**7)
    jerk = law(np.array([1e-9, T - 1e-9]), order=3)[3]
    assert jerk == pytest.approx([0, 0], abs=1e-6)


def test_cubic_is_papers_corrected_cubic():
    tau = np.linspace(0, 1, 11)
    assert np.allclose(TimeLaw("cubic", T)(tau * T, order=0)[0], 3 * tau**2 - 2 * tau**3)


@pytest.mark.parametrize("f", [0.1, 0.25, 0.5])
def test_trapezoid_peak_rate_and_acceleration(f):
    law = TimeLaw("trapezoidal", T, accel_fraction=f)
    _, ds, dds = law(np.linspace(0, T, 10001))
    assert ds.max() == pytest.approx(1 / ((1 - f) * T), rel=1e-9)
    assert dds.max() == pytest.approx(1 / (f * (1 - f) * T**2), rel=1e-9)


@pytest.mark.parametrize("kwargs", [{"name": "sine", "duration": 1.0}, {"name": "cubic", "duration": 0.0},
                                    {"name": "trapezoidal", "duration": 1.0, "accel_fraction": 0.6}])
def test_bad_law_settings_are_rejected(kwargs):
    with pytest.raises(ValueError):
        TimeLaw(**kwargs)
