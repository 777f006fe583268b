"""The limit events of a plan and a run: spans beyond a joint's range or speed limit (`PlanLimits`, `Bounds`),
the plan's jumps (`plan_jumps`, `jump_events`), each stamped with the plan's times (`event`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simbench.api import Event
from simbench.api.trajectory import JointTrajectory
from simbench.core.windowed import Departure, Spans
from simbench.robots import Robot

_JUMP_FACTOR = 10.0  # a plan's step farther than this many samples at a joint's speed limit is a jump


def event(t: np.ndarray, span: tuple[int, int], kind: str, detail: dict) -> Event:
    """An event of kind `kind` over samples span[0]..span[1], stamped with their times t."""
    return Event(float(t[span[0]]), float(t[span[1]]), kind, detail)


def _waypoint_interval(traj: JointTrajectory, s0: float, s1: float) -> list[int] | None:
    """1-based numbers of the waypoints a step from s0 to s1 lies between (Table 2's row numbers)."""
    if not traj.waypoints:
        return None
    ws = np.array([w["s"] for w in traj.waypoints])
    i = int(np.clip(np.searchsorted(ws, s0, side="right") - 1, 0, len(ws) - 2))
    j = int(np.clip(np.searchsorted(ws, s1, side="left"), i + 1, len(ws) - 1))
    return [i + 1, j + 1]


def plan_limit_events(robot: Robot, traj: JointTrajectory) -> list[Event]:
    """The limits the plan itself breaks, found without simulating: `joint_limit` (a reference beyond a joint's
    range), `velocity_limit` (a reference rate beyond its speed limit) and `reference_jump` (without its cost in
    physics)."""
    limits = PlanLimits(robot)
    limits.add(traj, 0)
    return sorted(limits.events(traj.t) + jump_events(robot, traj, plan_jumps(robot, traj, 0, len(traj.t) - 1)),
                  key=lambda e: (e.t_start, e.kind))


class Bounds:
    """The spans where each column of a per-joint series (N, dof) lies below its lower level or above its upper
    one, each with its extreme there (the least below, the largest above), seen a window at a time."""

    def __init__(self, lower: np.ndarray, upper: np.ndarray):
        self.lower, self.upper = lower, upper
        self.spans = {(j, bound): Spans(min if bound == "lower" else max)
                      for j in range(len(lower)) for bound in ("lower", "upper")}

    def add(self, values: np.ndarray, lo: int) -> None:
        """The window of samples lo.. of the series."""
        for j in range(values.shape[1]):
            x = values[:, j]
            for bound, beyond in (("lower", x < self.lower[j]), ("upper", x > self.upper[j])):
                extreme = np.min if bound == "lower" else np.max
                self.spans[j, bound].add(beyond, lo, lambda a, b, x=x, extreme=extreme: float(extreme(x[a:b + 1])))

    def finish(self) -> list[tuple[int, str, int, int, float]]:
        """Every span as (joint, bound, first, last, extreme), a joint at a time, its lower bound's first."""
        return [(j, bound, first, last, extreme) for (j, bound), spans_of in self.spans.items()
                for first, last, extreme in spans_of.finish()]


class PlanLimits:
    """The spans where the plan's references pass a joint's range (`joint_limit`, with the worst reference) or its
    rates a joint's speed limit (`velocity_limit`, with the fastest), the plan seen a window at a time: a joint at
    a time, so that there are no (N, dof) temporaries on a long run."""

    def __init__(self, robot: Robot):
        self.robot = robot
        self.beyond = Bounds(robot.lower - 1e-9, robot.upper + 1e-9)
        self.fast = [Spans(max) for _ in range(robot.dof)]
        self.peak = np.zeros(robot.dof)  # each joint's largest |qd_ref| so far

    def add(self, traj: JointTrajectory, lo: int) -> None:
        """The plan's rows lo.. (traj: those rows alone)."""
        robot = self.robot
        self.beyond.add(traj.q_ref, lo)
        for j in range(robot.dof):
            speed = np.abs(traj.qd_ref[:, j])
            self.fast[j].add(speed > robot.qd_max[j], lo, lambda a, b, speed=speed: float(speed[a:b + 1].max()))
            self.peak[j] = max(self.peak[j], float(speed.max(initial=0.0)))

    def events(self, t: np.ndarray) -> list[Event]:
        """The spans' events, a joint at a time (its range, then its speed limit), t the whole plan's times."""
        robot, events = self.robot, []
        for j, bound, first, last, worst in self.beyond.finish():
            limit = float(robot.lower[j] if bound == "lower" else robot.upper[j])
            events.append(event(t, (first, last), "joint_limit", {
                "joint": robot.joints[j], "bound": bound, "limit": limit, "worst": worst,
                "excess": abs(worst - limit), "source": "reference"}))
        for j, spans_of in enumerate(self.fast):
            events += [event(t, (first, last), "velocity_limit", {
                "joint": robot.joints[j], "limit": float(robot.qd_max[j]), "worst": worst})
                for first, last, worst in spans_of.finish()]
        return events


@dataclass(frozen=True)
class Jump:
    """A step k -> k + 1 of the plan that jumps (`plan_jumps`): the joints that jump, the step and the path parameters
    at both ends, taken when it is found."""

    k: int
    joints: list[int]
    step: list[float]
    s: list[float]


def plan_jumps(robot: Robot, traj: JointTrajectory, first: int, stop: int) -> list[Jump]:
    """The steps k -> k + 1 of the plan, first <= k < stop, farther than ten samples at the speed limit: a joint
    at a time, the steps as np.diff gives them, so that there are no (N, dof) temporaries on a long run; a joint a
    row, so that `any` runs along the samples (as in `windowed.norms`)."""
    limit = _JUMP_FACTOR * robot.qd_max * traj.dt
    q, s = traj.q_ref[first:stop + 1], traj.s[first:stop + 1]
    jump = np.stack([np.abs(np.diff(q[:, j])) > limit[j] for j in range(len(limit))])
    return [Jump(first + k, np.flatnonzero(jump[:, k]).tolist(), (q[k + 1] - q[k]).tolist(),
                  [float(s[k]), float(s[k + 1])]) for k in np.flatnonzero(jump.any(axis=0)).tolist()]


def jump_events(robot: Robot, traj: JointTrajectory, jumps: list[Jump],
                 departures: dict[int, Departure] | None = None) -> list[Event]:
    """The plan's jumps (`plan_jumps`); with the tool's departure from the path after each (the recorded path
    deviation's), what each cost: how far and how long the tool left the path."""
    t, events = traj.t, []
    for jump in jumps:
        k = jump.k
        detail = {"joints": [robot.joints[j] for j in jump.joints], "step": jump.step, "s": jump.s,
                  "between_waypoints": _waypoint_interval(traj, *jump.s)}
        if departures is not None:
            away = departures[k]
            back_at = away.back_at if away.back_at is not None else len(t) - 1
            detail["cost"] = {"tool_off_path_max": away.peak, "time_off_path": float(t[back_at] - t[k + 1]),
                              "back_on_path": away.back_at is not None}
        events.append(event(t, (k, k + 1), "reference_jump", detail))
    return events
