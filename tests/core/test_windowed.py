"""The analysis a window of samples at a time (simbench.core.windowed, analysis.analyse's `window`): a long run's
analysis holds a window's arrays, and must say what the analysis of the whole run at once says. The truths: the
whole arrays' own reductions (brute force), and the same run analysed as one window."""

import copy
import json
import math

import numpy as np
import pytest

from simbench.analysis import along_path, analyse
from simbench.analysis.tangents import Tangents
from simbench.core import windowed
from simbench.core.windowed import Departure, Rises, Spans, Sums, spans
from simbench.outputs.report import plain
from simbench.robots import Tolerance

_RNG = np.random.default_rng(20261123)


def _cuts(n: int, rng: np.random.Generator) -> list[tuple[int, int]]:
    """n samples cut into random windows (some of one sample)."""
    edges = np.unique(np.concatenate([[0, n], rng.integers(1, max(n, 2), rng.integers(0, 12))]))
    return list(zip(edges[:-1].tolist(), edges[1:].tolist()))


@pytest.mark.parametrize("seed", range(40))
def test_spans_seen_a_window_at_a_time_are_the_whole_masks(seed):
    """Runs of True cut by windows are joined again, each with the least value over it and where (the first)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 300))
    mask = rng.random(n) < rng.choice([0.1, 0.5, 0.9])
    x = rng.integers(0, 5, n).astype(float)  # ties: the first least value is the one kept
    found = Spans(lambda a, b: b if b[0] < a[0] else a)
    for lo, hi in _cuts(n, rng):
        found.add(mask[lo:hi], lo, lambda a, b, lo=lo: (float(x[lo + a:lo + b + 1].min()),
                                                         lo + a + int(np.argmin(x[lo + a:lo + b + 1]))))
    truth = [(a, b, (float(x[a:b + 1].min()), a + int(np.argmin(x[a:b + 1])))) for a, b in spans(mask)]
    assert found.finish() == truth


@pytest.mark.parametrize("seed", range(20))
def test_the_first_sample_beyond_a_level_from_the_rises(seed):
    """Rises.first_beyond is np.argmax(x > level) where some sample is beyond it, and None where none is."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 400))
    x = np.cumsum(rng.normal(size=n)) * rng.choice([0.1, 1.0])
    rises = Rises()
    for lo, hi in _cuts(n, rng):
        rises.add(x[lo:hi], lo)
    for level in np.concatenate([rng.uniform(x.min() - 1, x.max() + 1, 20), x[rng.integers(0, n, 5)]]):
        beyond = x > level
        assert rises.first_beyond(level) == (int(np.argmax(beyond)) if beyond.any() else None)


@pytest.mark.parametrize("seed", range(30))
def test_a_departure_from_the_path_is_the_whole_deviations(seed):
    """How far and how long the tool left the path after a jump: the deviation's largest after the jump (its first
    sample) and the first sample from there within 1 mm, as the whole series gives them."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 300))
    deviation = np.abs(rng.normal(size=n)) * 1e-3 * rng.choice([0.5, 2.0, 5.0])
    deviation[rng.integers(0, n, 3)] = deviation.max()  # ties for the largest
    start = int(rng.integers(0, n))
    away = Departure(start, 1e-3)
    for lo, hi in _cuts(n, rng):
        away.add(deviation[lo:hi], lo)
    after = deviation[start:]
    peak = int(np.argmax(after))
    back = np.flatnonzero(after[peak:] < 1e-3)
    assert (away.peak, away.peak_at) == (float(after.max()), start + peak)
    assert away.back_at == (start + peak + int(back[0]) if back.size else None)


def test_sums_a_window_at_a_time_are_the_whole_series():
    """RMS, largest absolute value and last row of a column and of columns, to rounding."""
    x, y = _RNG.normal(size=(1000, 3)), _RNG.normal(size=1000)
    sums = Sums()
    for lo, hi in _cuts(1000, _RNG):
        sums.add(x=x[lo:hi], y=y[lo:hi])
    assert np.allclose(sums.rms("x"), np.sqrt(np.mean(x**2, axis=0)), rtol=1e-13, atol=0)
    assert np.allclose(sums.rms("y"), np.sqrt(np.mean(y**2)), rtol=1e-13, atol=0)
    assert np.array_equal(sums.largest["x"], np.abs(x).max(axis=0)) and sums.largest["y"] == np.abs(y).max()
    assert np.array_equal(sums.last["x"], x[-1])


def test_tangents_a_window_at_a_time_are_along_paths():
    """The tangents of a path that rests at its start, in its middle and at its end, a window at a time, are
    along_path's of the whole path, bit for bit (the rests take the direction moved in before, or first after)."""
    path = np.concatenate([np.zeros((40, 3)), np.cumsum(_RNG.normal(size=(100, 3)), axis=0)])
    path = np.concatenate([path, np.repeat(path[-1:], 50, axis=0), path[-1] + np.cumsum(_RNG.normal(size=(60, 3)),
                                                                                         axis=0)])
    path = np.concatenate([path, np.repeat(path[-1:], 30, axis=0)])
    whole = along_path(path)
    assert np.all(np.isclose(np.linalg.norm(whole, axis=1), 1.0))
    for cuts in ([(0, len(path))], _cuts(len(path), _RNG), [(k, k + 1) for k in range(len(path))]):
        tangents = Tangents(path)
        assert np.array_equal(np.concatenate([tangents.rows(lo, hi) for lo, hi in cuts]), whole)
    assert np.array_equal(along_path(np.zeros((5, 3))), np.zeros((5, 3)))


def _close(a, b, rtol: float) -> bool:
    """The same nested figures, floats within rtol of each other."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k], rtol) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_close(x, y, rtol) for x, y in zip(a, b))
    if isinstance(a, float):
        return bool(np.isclose(a, b, rtol=rtol, atol=1e-300))
    return a == b


_CASES = [("rsmg", "three_turns"), ("agile_eye", "through_singularity"), ("spherical_arm", "case2"),
          ("puma600", "wrist_singularity"), ("spherical_arm", "case4")]


@pytest.mark.parametrize("robot, name", _CASES)
def test_an_analysis_by_windows_is_the_analysis_at_once(evaluated, monkeypatch, peak_speed, robot, name):
    """A run analysed in windows of the path search's blocks (a block a group) has the series of the run analysed
    at once, bit for bit, and its figures and events (RMS to rounding); in windows of odd lengths, that cut blocks,
    re-grips and spans, every series but the path deviation bit for bit (its blocks are searched on other
    stretches of path), and the figures and events to 1e-9. An outside metric's figures (conftest.PEAK_SPEED) are
    the recording's own, however the run is cut."""
    scenario, ev = evaluated(robot, name)
    a = scenario.analysis
    near, margin = Tolerance(a.near_angle, a.near_length), Tolerance(a.limit_angle, a.limit_length)
    block = windowed.near_reference(ev.trajectory.dt)
    monkeypatch.setattr(windowed, "GROUP", block)
    n = ev.recording.t.size
    once = analyse(scenario.robot_def, ev.trajectory, ev.recording, near, margin, window=n)
    truth = np.abs(ev.recording.qd).max(axis=0)
    assert once.metrics["peak_speed"] == {"qd0_max": truth[0], "qd_max": truth.tolist(), "samples": n}
    for window, exact in ((block, True), (2 * block, True), (997, False), (3001, False)):
        if window >= n:
            continue
        cut = analyse(scenario.robot_def, ev.trajectory, ev.recording, near, margin, window=window)
        for key, values in once.series.items():
            if exact or key != "path_deviation":
                assert np.array_equal(cut.series[key], values), (window, key)
            else:
                assert np.allclose(cut.series[key], values, rtol=1e-9, atol=1e-12), (window, key)
        assert cut.metrics == once.metrics
        for part in ("tracking", "singularity_events", "limit_events", "extra"):
            assert _close(plain(getattr(once, part)), plain(getattr(cut, part)), 1e-12 if exact else 1e-9), part
        for key, rises in once.rises.items():
            if not exact and key == "path_deviation":
                continue
            for level in np.quantile(once.series[key], [0.0, 0.5, 0.9, 0.999]):
                assert cut.rises[key].first_beyond(level) == rises.first_beyond(level)


@pytest.mark.parametrize("robot, name", [("rsmg", "three_turns"), ("agile_eye", "through_singularity")])
def test_a_summariser_cut_at_every_event_is_the_whole_runs_summary(evaluated, robot, name):
    """The RSMG's and the Agile Eye's Summarisers fed windows that end one sample before, at, and one and two
    samples after each re-grip (whose snap reads the samples either side of the grip) and each assembly-mode
    change (det A's sign between two samples): the report entries, events and series of the whole run's
    `summary`, bit for bit."""
    scenario, ev = evaluated(robot, name)
    traj, rec, series, sut = ev.trajectory, ev.recording, ev.analysis.series, scenario.robot_def
    whole = sut.summary(traj, rec, series)
    times = [e["t_end"] for e in whole.entries.get("switch_events", [])] + [e["t_start"] for e in whole.events]
    assert times, "the run has re-grips or assembly-mode changes to cut at"
    k = np.searchsorted(traj.t, np.array(times) - 1e-9)
    edges = np.unique(np.clip(np.concatenate([k - 1, k, k + 1, k + 2, [0, traj.t.size]]), 0, traj.t.size))
    summariser, parts = sut.summariser(traj), []
    for lo, hi in zip(edges[:-1], edges[1:]):
        parts.append(summariser.add(traj.rows(slice(lo, hi)), rec.rows(lo, hi),
                                    {key: v[lo:hi] for key, v in series.items()}))
    entries, events = summariser.finish()
    assert json.dumps(entries, default=str) == json.dumps(whole.entries, default=str)
    assert events == whole.events
    for key, values in whole.series.items():
        assert np.array_equal(np.concatenate([p[key] for p in parts]), values), key


def test_a_block_sum_is_the_same_float_however_the_series_is_cut():
    """BlockSum over a series cut into windows at 60 random sets of places equals it over the series as one window,
    bit for bit, and the exact sum (math.fsum) to 1e-13; adding the windows' own sums does not (the rounding moves
    with the cut)."""
    rng = np.random.default_rng(7)
    x = rng.lognormal(0.0, 3.0, 20_001) * rng.choice([-1.0, 1.0], 20_001)
    whole = windowed.BlockSum()
    whole.add(x)
    naive = set()
    for _ in range(60):
        cuts = np.sort(rng.integers(0, x.size, rng.integers(1, 40)))
        parts = windowed.BlockSum()
        for piece in np.split(x, cuts):
            parts.add(piece)
        assert parts.value() == whole.value()
        naive.add(sum(float(np.sum(piece)) for piece in np.split(x, cuts)))
    assert abs(whole.value() - math.fsum(x)) <= 1e-13 * math.fsum(np.abs(x))
    assert len(naive) > 1


def test_a_robot_whose_summary_needs_the_whole_run_gives_its_metrics_the_whole_run(evaluated, peak_speed):
    """The Agile Eye made to summarise only the whole run (its `summary` overridden without a Summariser): analysed
    in windows, its metrics get the whole run at the end, and their figures, the orientation's among tracking's,
    are those of the Agile Eye analysed as it streams."""
    scenario, ev = evaluated("agile_eye", "through_singularity")
    eye = scenario.robot_def

    class WholeRun(type(eye)):
        def summary(self, traj, rec, series):
            return super().summary(traj, rec, series)

    whole = copy.copy(eye)
    whole.__class__ = WholeRun
    assert eye.streams and not whole.streams
    a = scenario.analysis
    near, margin = Tolerance(a.near_angle, a.near_length), Tolerance(a.limit_angle, a.limit_length)
    streamed = analyse(eye, ev.trajectory, ev.recording, near, margin)
    at_the_end = analyse(whole, ev.trajectory, ev.recording, near, margin, window=997)
    assert "orientation_max" in at_the_end.tracking
    assert _close(plain(at_the_end.tracking), plain(streamed.tracking), 1e-12)
    assert at_the_end.metrics == streamed.metrics and streamed.metrics["peak_speed"]["samples"] == ev.recording.t.size
