"""Whether a run kept every promise its report makes: the status, and each promise broken, in one line.

A run is `ok` only if the plan stayed within the mechanism's limits and the mechanism did what the plan asked;
otherwise `limits`, with one Violation per broken promise: a kind of events.KINDS (planners report `goal_missed`,
`singular_crossing`, `clearance_margin` and `acceleration_limit` in `JointTrajectory.violations`) or an event the
robot declares breaking (`Robot.breaking`). A scenario's `expect:` does not change the status; the verdict says
whether it met it.
An episode that ended early (simbench.env) is `failed` where its physics failed, else `truncated`: never `ok`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simbench.api import Event, Violation
from simbench.api.trajectory import JointTrajectory
from simbench.robots import REVOLUTE, Robot

OK, LIMITS = "ok", "limits"
FAILED, TRUNCATED = "failed", "truncated"  # a run cut short: its physics failed, or it was stopped
# Violation kinds every robot can have (besides its own `breaking` events and its planner's).


@dataclass(frozen=True)
class Verdict:
    """A run's status (`ok` or `limits`), its violations, and the scenario's expectation (None: expects `ok`)."""

    status: str
    violations: tuple[Violation, ...]
    expected: dict | None = None

    @property
    def as_expected(self) -> bool:
        """Whether the run ended as its scenario says it should (`ok` if it says nothing)."""
        return self.status == OK if self.expected is None else self.expected["met"]

    def to_report(self) -> dict:
        """The report.json entries: status, violations and, if the scenario expects a failure, expected."""
        out = {"status": self.status, "violations": list(self.violations)}
        if self.expected is not None:
            out["expected"] = self.expected
        return out


def _quantity(value: float, kind: str, rate: bool = False) -> str:
    """A joint quantity in the units a reader thinks in: degrees (per second) or millimetres (per second)."""
    per = "/s" if rate else ""
    return f"{np.rad2deg(value):.2f} deg{per}" if kind == REVOLUTE else f"{value * 1e3:.2f} mm{per}"


def _violation(kind: str, message: str, events: list[Event], **detail) -> Violation:
    return Violation(kind, message, events[0].t_start if events else detail.pop("t", None), len(events), detail)


def _limit_violations(robot: Robot, limit_events: list[Event]) -> list[Violation]:
    """One violation per kind and joint of the limit events that break a promise (not `at_limit`)."""
    kind_of = dict(zip(robot.joints, robot.kinds))

    def each_joint(kind: str) -> list[tuple[str, list[Event], str]]:  # (joint, its events of this kind, its kind)
        by_joint: dict[str, list[Event]] = {}
        for e in limit_events:
            if e.kind == kind:
                by_joint.setdefault(e.detail["joint"], []).append(e)
        return [(name, found, kind_of[name]) for name, found in by_joint.items()]

    out = [_joint_limit(*found) for found in each_joint("joint_limit")]
    out += [_velocity_limit(*found) for found in each_joint("velocity_limit")]
    jumps = [e for e in limit_events if e.kind == "reference_jump"]
    if jumps:
        out.append(_reference_jump(robot, jumps))
    out += [_actuator_saturation(*found) for found in each_joint("actuator_saturation")]
    return out


def _joint_limit(name: str, events: list[Event], kind: str) -> Violation:
    """A joint the plan takes beyond its range: the worst excess, and when it starts."""
    worst = max(events, key=lambda e: e.detail["excess"]).detail
    return _violation("joint_limit", f"{name} is asked for {_quantity(worst['worst'], kind)}, "
                      f"{_quantity(worst['excess'], kind)} beyond its {worst['bound']} limit "
                      f"{_quantity(worst['limit'], kind)}, from t = {events[0].t_start:.3f} s",
                      events, joint=name, excess=worst["excess"])


def _velocity_limit(name: str, events: list[Event], kind: str) -> Violation:
    """A joint the plan drives faster than its speed limit: the worst speed, and when it starts."""
    worst = max(events, key=lambda e: e.detail["worst"]).detail
    return _violation("velocity_limit", f"{name} is asked for {_quantity(worst['worst'], kind, True)} against its "
                      f"speed limit {_quantity(worst['limit'], kind, True)}, from t = {events[0].t_start:.3f} s",
                      events, joint=name, ratio=worst["worst"] / worst["limit"])


def _reference_jump(robot: Robot, jumps: list[Event]) -> Violation:
    """The plan's discontinuities, in one violation: the joints that step, and what the worst cost the tool."""
    joints = sorted({j for e in jumps for j in e.detail["joints"]}, key=robot.joints.index)
    cost = max((e.detail.get("cost", {}).get("tool_off_path_max", 0.0) for e in jumps), default=0.0)
    costly = f", the tool leaving the path by {cost * 1e3:.1f} mm" if "cost" in jumps[0].detail else ""
    return _violation("reference_jump", f"the plan steps {', '.join(joints)} discontinuously at t = "
                      f"{jumps[0].t_start:.3f} s ({len(jumps)} jump{'s' * (len(jumps) > 1)}){costly}",
                      jumps, joints=joints)


def _actuator_saturation(name: str, events: list[Event], kind: str) -> Violation:
    """A joint's actuator at its force limit: for how long in all, and from when."""
    total = sum(e.detail["duration"] for e in events)
    unit = "N m" if kind == REVOLUTE else "N"
    return _violation("actuator_saturation", f"{name}'s actuator sits at its force limit "
                      f"{events[0].detail['limit']:g} {unit} for {total:.3f} s from t = "
                      f"{events[0].t_start:.3f} s", events, joint=name, duration=total)


def _tolerance_violations(analysis, traj: JointTrajectory, robot: Robot, tol) -> list[Violation]:
    """Tracking beyond the scenario's tolerances: off the path, off the orientation (where the plan promises it),
    short of the goal (the first sample beyond from Analysis.rises, which saw every sample, a stride's too)."""
    out, tracking, t = [], analysis.tracking, traj.t
    if tracking["tool_max"] > tol.path_tolerance:
        k = analysis.rises["path_deviation"].first_beyond(tol.path_tolerance)
        out.append(_violation("off_path", f"the tool leaves the planned path by up to {tracking['tool_max'] * 1e3:.2f} "
                              f"mm (tolerance {tol.path_tolerance * 1e3:g} mm), from t = {t[k]:.3f} s", [],
                              t=float(t[k]), worst=tracking["tool_max"]))
    if tracking["tool_error_final"] > tol.goal_tolerance:
        out.append(_violation("goal_missed", f"the tool ends {tracking['tool_error_final'] * 1e3:.2f} mm from the "
                              f"plan's end (tolerance {tol.goal_tolerance * 1e3:g} mm)", [],
                              t=float(t[-1]), error=tracking["tool_error_final"]))
    if "orientation_max" in tracking and robot.judges_orientation(traj):
        worst, final = tracking["orientation_max"], tracking["orientation_final"]
        if worst > tol.orientation_tolerance:
            k = analysis.rises[robot.orientation_error].first_beyond(tol.orientation_tolerance)
            out.append(_violation("orientation_error", f"the orientation leaves the plan's by up to "
                                  f"{np.rad2deg(worst):.2f} deg (tolerance "
                                  f"{np.rad2deg(tol.orientation_tolerance):g} deg), from t = {t[k]:.3f} s",
                                  [], t=float(t[k]), worst=worst))
        if final > tol.goal_orientation_tolerance and not any(v.kind == "goal_missed" for v in out):
            out.append(_violation("goal_missed", f"the orientation ends {np.rad2deg(final):.2f} deg from the "
                                  f"plan's end (tolerance {np.rad2deg(tol.goal_orientation_tolerance):g} deg)", [],
                                  t=float(t[-1]), error=final))
    return out


def _breaking_violations(robot: Robot, events: list[Event]) -> list[Violation]:
    """The robot's breaking events (an assembly-mode change, say), one violation per kind."""
    out = []
    for kind in robot.breaking:
        found = [e for e in events if e.kind == kind]
        if found:
            times = ", ".join(f"{e.t_start:.3f}" for e in found[:3]) + (", ..." if len(found) > 3 else "")
            count = "once" if len(found) == 1 else f"{len(found)} times"
            what = f" ({found[0].detail['describe']}, the first)" if "describe" in found[0].detail else ""
            out.append(_violation(kind, f"{kind.replace('_', ' ')} {count}, at t = {times} s{what}", found))
    return out


def _planner_violations(traj: JointTrajectory) -> list[Violation]:
    """What the planner reports its plan breaks, as Violations (a planner's dicts read as one)."""
    return [Violation.of(v) for v in traj.violations]


def plan_verdict(robot: Robot, traj: JointTrajectory, limit_events: list[Event], expect=None) -> Verdict:
    """What can be known before simulating: the limits the plan breaks and what its planner reported."""
    found = _limit_violations(robot, limit_events) + _planner_violations(traj)
    return _verdict(found, expect, complete=False)


def run_verdict(robot: Robot, traj: JointTrajectory, analysis, tolerances, expect=None) -> Verdict:
    """The verdict on a simulated run: limits, breaking events and tracking against the scenario's tolerances."""
    found = (_limit_violations(robot, analysis.limit_events) + _planner_violations(traj)
             + _breaking_violations(robot, analysis.singularity_events)
             + _tolerance_violations(analysis, traj, robot, tolerances))
    return _verdict(found, expect)


def _verdict(found: list[Violation], expect, complete: bool = True) -> Verdict:
    """The status of the violations found, checked against `expect`; before the physics (`complete` false) a
    plan meets it if it breaks no kind but those expected."""
    status = LIMITS if found else OK
    expected = None
    if expect is not None:
        kinds = sorted({v.kind for v in found})
        wanted = sorted(set(expect.violations))
        met = (status == expect.status and kinds == wanted) if complete else set(kinds) <= set(wanted)
        expected = {"status": expect.status, "violations": wanted, "reason": expect.reason, "met": met}
        if not met:
            expected["unexpected"] = sorted(set(kinds) - set(wanted))
            expected["missing"] = sorted(set(wanted) - set(kinds))
    return Verdict(status, tuple(found), expected)


def cut_short(verdict: Verdict, status: str, t: float, why: str) -> Verdict:
    """The verdict on a run that stopped at time t before its plan's end (status FAILED or TRUNCATED): the
    violations of what ran, and the reason first."""
    assert status in (FAILED, TRUNCATED), status
    stop = Violation(status, why, t, 1, {})
    expected = None if verdict.expected is None else {**verdict.expected, "met": False}
    return Verdict(status, (stop, *verdict.violations), expected)
