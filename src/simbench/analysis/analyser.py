"""The analysis of a run (`Analysis`): whole (`analyse`) or a window of samples at a time as it is simulated
(`Analyser`)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from simbench.analysis.limit_events import Bounds, Jump, PlanLimits, event, jump_events, plan_jumps
from simbench.analysis.tangents import Tangents
from simbench.api import Event, Metric
from simbench.api.recording import Recording
from simbench.api.registry import metrics_for
from simbench.api.trajectory import JointTrajectory, joined
from simbench.core import windowed
from simbench.core.windowed import Departure, Rises, Spans, norms
from simbench.maths.path_distance import deviation_near_reference
from simbench.robots import Robot, Tolerance

if TYPE_CHECKING:
    from simbench.scenario import Scenario

_BACK_ON_PATH = 1e-3  # m: after a jump, the tool counts as back on the path within this distance


@dataclass(frozen=True)
class Analysis:
    """A run's analysis: the tracking figures (the shipped metric `tracking`) and every other metric's by name,
    the events, the per-sample series behind them (at the recording's kept rows), the names of the robot's
    singularity measures among them, what the robot adds to the report, the samples analysed, and where the path
    deviation and the orientation error rose above every sample before them (windowed.Rises, for the verdict).
    `extremes`: what the kept rows of a strided run may miss: "qd_ref_peak", each joint's largest planned rate
    (dof,), and "singular_min", each singular set's least distance (in multiples of the near tolerance)."""

    tracking: dict
    singularity_events: list[Event]
    limit_events: list[Event]
    series: dict[str, np.ndarray]
    measures: tuple[str, ...] = ()
    extra: dict = field(default_factory=dict)
    samples: int = 0
    rises: dict[str, Rises] = field(default_factory=dict)
    extremes: dict = field(default_factory=dict)
    metrics: dict[str, dict] = field(default_factory=dict)


def _closest(a: tuple, b: tuple) -> tuple:
    """Of two pieces of a span near a singular set, (distance, sample, gaps, detail) at the closest sample: the
    first."""
    return b if b[0] < a[0] else a


def analyse(robot: Robot, traj: JointTrajectory, rec: Recording, near: Tolerance, margin: Tolerance,
            window: int | None = None, scenario: Scenario | None = None) -> Analysis:
    """Everything the report says about a run, from every recorded sample, `window` samples at a time (default
    `windowed.window_size`), so that a long run's analysis holds a window of per-sample arrays at a time.
    `scenario` (or None) is what the metrics are made for (Metric.for_run)."""
    run = Analyser(robot, traj, near, margin, window, scenario)
    for lo in range(0, rec.t.size, run.window):
        run.add(rec.rows(lo, min(lo + run.window, rec.t.size)))
    return run.finish(rec)


class Analyser:
    """The analysis of a run, fed its samples a window at a time, in order (as simbench.physics.sim simulates them). A
    window's plan is final: the plan's feedback revises the references of samples still to come only.

    Tracking series: joint errors; the tool's distance from the planned path near its reference (within
    windowed.NEAR_REFERENCE s: `deviation_near_reference`); its lag, the error's component along the path's tangent
    at the reference point (positive when the tool trails); and its error against the time-indexed reference.
    Then the robot's measures, singular sets and summary (a Summariser's windows, or with none the whole run's
    `summary` at the end), and every registered metric (registry.metrics_for) given the same windows. Spans of
    events that reach a window's edge go on into the next (windowed.Spans)."""

    def __init__(self, robot: Robot, traj: JointTrajectory, near: Tolerance, margin: Tolerance,
                 window: int | None = None, scenario: Scenario | None = None):
        self.robot, self.traj, self.near = robot, traj, near
        self.window = window or windowed.window_size(traj.dt, len(traj.t))  # samples a window (`analyse`, sim)
        self.samples, self.seconds = 0, 0.0  # analysed so far, and the time `add` took
        self.tangents = Tangents(traj.tool_ref)
        self.metrics: list[Metric] = metrics_for(robot, traj, scenario)
        self.rises = {"path_deviation": Rises(), robot.orientation_error: Rises()}
        self.kept: dict[str, list[np.ndarray]] = {}  # each series' kept rows, window by window
        self.measures: tuple[str, ...] = ()
        self.summariser = robot.summariser(traj) if robot.streams else None
        self.singular: list[Spans] = []
        self.sets: list = []  # each singular set's name, family and condition
        self.least: dict[str, float] = {}  # each singular set's least distance so far
        margins = np.array([margin.of(kind) for kind in robot.kinds])
        self.at_limit = Bounds(robot.lower + margins, robot.upper - margins)
        self.saturated = [Spans(lambda first, _: first) for _ in range(robot.dof)]
        self.plan_limits = PlanLimits(robot)
        self.plan_kept: list[JointTrajectory] = []  # the plan at the recording's kept rows, window by window
        self.jumps: list[Jump] = []
        self.departures: dict[int, Departure] = {}
        self.force_limit, self.timestep = np.zeros(0), 0.0

    @property
    def streams(self) -> bool:
        """Whether the robot's summary comes a window at a time (a Summariser): else it needs the whole run."""
        return self.summariser is not None

    def add(self, rec: Recording) -> None:
        """The next window: the recording of samples lo..hi-1 (Recording.rows), lo the samples so far."""
        start = time.perf_counter()
        self._add(rec)
        self.seconds += time.perf_counter() - start

    def _add(self, rec: Recording) -> None:
        lo = self.samples
        hi = self.samples = lo + rec.t.size
        traj = self.traj.rows(slice(lo, hi))
        if rec.kept is not None:
            self.plan_kept.append(traj.rows(rec.kept))
        self.force_limit, self.timestep = rec.force_limit, rec.timestep
        self.plan_limits.add(traj, lo)
        for jump in plan_jumps(self.robot, self.traj, max(lo - 1, 0), hi - 1):  # each step once its rows are final
            self.jumps.append(jump)
            self.departures[jump.k] = Departure(jump.k + 1, _BACK_ON_PATH)
        series = self._tracking(traj, rec, lo, hi)
        measures = self.robot.measures(rec)
        self.measures = tuple(measures)
        series.update(measures)
        self._singular(self.robot.singular_sets_from(rec, self.near, measures), lo)
        if self.summariser is not None:
            series.update(self.summariser.add(traj, rec, series))
            self._orientation(series, lo)
            self._measure(traj, rec, series)
        self._limits(rec, lo)
        keep = slice(None) if self.summariser is None or rec.kept is None else rec.kept
        for name, values in series.items():
            self.kept.setdefault(name, []).append(values[keep])

    def _tracking(self, traj: JointTrajectory, rec: Recording, lo: int, hi: int) -> dict[str, np.ndarray]:
        """The tracking series of samples lo..hi-1."""
        joint_error = rec.q - traj.q_ref
        deviation = deviation_near_reference(self.traj.tool_ref, rec.tool, windowed.near_reference(self.traj.dt), lo)
        behind = traj.tool_ref - rec.tool  # the tool to its reference: its error, and along the tangent its lag
        lag = np.einsum("ij,ij->i", behind, self.tangents.rows(lo, hi))
        tool_error = norms(behind)
        self.rises["path_deviation"].add(deviation, lo)
        for away in self.departures.values():
            away.add(deviation, lo)
        return {"joint_error": joint_error, "path_deviation": deviation, "path_lag": lag, "tool_error": tool_error}

    def _orientation(self, series: dict[str, np.ndarray], lo: int) -> None:
        """Where the orientation error rose, where the task is an orientation (beside the tool point's)."""
        error = series.get(self.robot.orientation_error)
        if error is not None:
            self.rises[self.robot.orientation_error].add(error, lo)

    def _measure(self, traj: JointTrajectory, rec: Recording, series: dict[str, np.ndarray]) -> None:
        """The metrics' next window."""
        for metric in self.metrics:
            metric.add(traj, rec, series)

    def _singular(self, sets: list, lo: int) -> None:
        """The spans where the recorded state lies near each of the robot's singular sets, with the closest sample."""
        if not self.singular:
            self.singular = [Spans(_closest) for _ in sets]
            self.sets = [(s.name, s.family, s.condition) for s in sets]

        for sset in sets:
            self.least[sset.name] = min(self.least.get(sset.name, np.inf), float(sset.distance.min(initial=np.inf)))
        for spans_of, sset in zip(self.singular, sets):
            def closest(a: int, b: int, sset=sset) -> tuple:
                i = sset.closest(a, b) if sset.closest is not None else a + int(np.argmin(sset.distance[a:b + 1]))
                more = sset.detail(i) if sset.detail is not None else {}
                return float(sset.distance[i]), lo + i, {k: float(v[i]) for k, v in sset.gaps.items()}, more
            spans_of.add(sset.distance <= 1.0, lo, closest)

    def _limits(self, rec: Recording, lo: int) -> None:
        """The spans where a joint sits at a limit (with its extreme there) or its actuator at its force bound."""
        self.at_limit.add(rec.q, lo)
        for j in range(self.robot.dof):
            force = rec.force[:, j]
            self.saturated[j].add(np.abs(force) >= rec.force_limit[j] * (1 - 1e-6), lo,
                                  lambda a, b, force=force: float(force[a]))

    def plan(self) -> JointTrajectory:
        """The plan at the recording's kept rows analysed so far, without its (spent) feedback: what the outputs
        of a run with a recording stride show."""
        return replace(joined(self.plan_kept), feedback=None)

    def finish(self, whole: Recording | None = None) -> Analysis:
        """The whole run's analysis; `whole`, the run's recording, is needed where the robot has no Summariser."""
        robot, traj, t = self.robot, self.traj, self.traj.t
        series = {name: np.concatenate(parts) if len(parts) > 1 else parts[0] for name, parts in self.kept.items()}
        singular = []
        for spans_of, (name, family, condition) in zip(self.singular, self.sets):
            for first, last, (distance, i, gaps, more) in spans_of.finish():
                detail = {"family": family, "condition": condition, "t_closest": float(t[i]), "distance": distance,
                          "gaps_at_closest": gaps, **more}
                singular.append(event(t, (first, last), name, detail))
        if self.summariser is not None:
            extra, events = self.summariser.finish()
        else:  # the whole run's summary, then its series at the kept rows
            if whole is None:
                raise ValueError(f"robot '{robot.name}' has no Summariser: its analysis needs the whole run's "
                                 "recording")
            extra, events, more = robot.summary(traj, whole, series)
            series.update(more)
            self._orientation(series, 0)
            self._measure(traj, whole, series)
            if whole.kept is not None:
                series = {name: v[whole.kept] for name, v in series.items()}
        figures = {metric.name: metric.finish() for metric in self.metrics}
        return Analysis(tracking=figures.pop("tracking"), metrics=figures, singularity_events=sorted(
                            singular + [Event.of(e) for e in events], key=lambda e: (e.t_start, e.kind)),
                        limit_events=self._limit_events(), series=series, measures=self.measures, extra=extra,
                        samples=self.samples,
                        rises={k: v for k, v in self.rises.items() if k is not None and v.at},
                        extremes={"qd_ref_peak": self.plan_limits.peak.copy(), "singular_min": dict(self.least)})

    def _limit_events(self) -> list[Event]:
        """Joint-limit, at-limit, reference-jump, velocity-limit and actuator-saturation events."""
        robot, traj, t = self.robot, self.traj, self.traj.t
        events = self.plan_limits.events(t)
        for j, bound, first, last, extreme in self.at_limit.finish():
            limit = robot.lower[j] if bound == "lower" else robot.upper[j]
            events.append(event(t, (first, last), "at_limit", {"joint": robot.joints[j], "bound": bound,
                                                               "limit": float(limit), "extreme": extreme}))
        events += jump_events(robot, traj, self.jumps, self.departures)
        for j, spans_of in enumerate(self.saturated):
            events += [event(t, (first, last), "actuator_saturation", {
                "joint": robot.joints[j], "limit": float(self.force_limit[j]), "force": force,
                "duration": float(t[last] - t[first] + self.timestep)}) for first, last, force in spans_of.finish()]
        return sorted(events, key=lambda e: (e.t_start, e.kind))
