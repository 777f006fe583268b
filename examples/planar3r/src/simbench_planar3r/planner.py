"""Resolved-rate motion along a straight line of the planar 3R arm's tool, by damped least squares.

The reference pose X_ref(t) = X_0 + s(t) (X_1 - X_0) runs on a straight line in (x, y, phi) from the start's pose
to the goal, on the scenario's time law s(t). The joint rates are those of damped least squares (Nakamura and
Hanafusa 1986; Wampler 1986) with feedback on the pose error e = X_ref - X(q):

    qdot = J^T (J J^T + lambda^2 I)^-1 (Xdot_ref + K e)

integrated by forward Euler at the control period dt. Away from the singular set the damping costs little (the
feedback K e takes up the rest), and the tool follows the line; near the stretched or folded elbow, where J loses
rank, DLS trades accuracy for bounded joint rates, and the tool leaves the line. The plan says so: a warning, the
largest deviation in `info`, and an `off_path` violation where the deviation exceeds the scenario's tolerance.
"""

from __future__ import annotations

import math
from typing import Annotated

import numpy as np
from pydantic import AfterValidator, Field, ValidationInfo
from simbench.api import Planner, Robot, Violation
from simbench.api.trajectory import JointTrajectory, control_grid
from simbench.core.errors import RunError
from simbench.scenario.schema import MAX_LENGTH, Angle, JointVector, SimbenchModel

from simbench_planar3r.robot import L1, L2, L3, UPPER, Z, elbow_gaps, pose


def _to_point2(value: list[float], info: ValidationInfo) -> list[float]:
    """A point [x, y] in the plane of motion, in the file's length unit, converted to metres."""
    if len(value) != 2:
        raise ValueError(f"expected a point [x, y] in the arm's plane, got {len(value)} values")
    units = (info.context or {}).get("units")
    factor, unit = (units.length_factor, units.length) if units is not None else (1.0, "m")
    si = [v * factor for v in value]
    if any(abs(v) > MAX_LENGTH for v in si):
        raise ValueError(f"expected coordinates within +-{MAX_LENGTH / factor:g} {unit}, got "
                         f"{max(value, key=abs):.6g} {unit}")
    return si


Point2 = Annotated[list[float], AfterValidator(_to_point2)]


class Task(SimbenchModel):
    """`task:` of a DLS line. `goal` is the tool point [x, y] in the arm's plane (its height is the robot's, so
    it is not written), `goal_phi` the tool's heading there; the tool turns from the start's heading by the
    shorter way (goal_phi is taken modulo one turn). `damping` is lambda (in the units of the Jacobian: m for
    x, y and 1 for phi), `gain` the pose feedback K (1/s)."""

    start: JointVector
    goal: Point2
    goal_phi: Angle
    damping: Annotated[float, Field(gt=0, le=10)] = 0.02
    gain: Annotated[float, Field(gt=0, le=1e4)] = 20.0


def _wrap(angle: float) -> float:
    """angle in (-pi, pi]."""
    return float(np.angle(np.exp(1j * angle)))


def goal_pose(task: Task) -> tuple[np.ndarray, np.ndarray]:
    """The line's ends in (x, y, phi): the start's pose and the goal, its phi the start's plus the shorter turn."""
    x0 = pose(np.array(task.start))[0]
    phi1 = x0[2] + _wrap(task.goal_phi - x0[2])
    return x0, np.array([task.goal[0], task.goal[1], phi1])


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (N,) of points (N, 2) from the segment a-b in the plane."""
    ab = b - a
    length2 = float(ab @ ab)
    u = np.zeros(len(points)) if length2 == 0 else np.clip((points - a) @ ab / length2, 0.0, 1.0)
    return np.linalg.norm(points - (a + u[:, None] * ab), axis=1)


class DLSLine(Planner[Task]):
    """Straight line of the tool in (x, y, phi) by damped-least-squares resolved rates (planar 3R only)."""

    name = "dls_line"
    description = "straight tool line in (x, y, phi) by damped least squares resolved rates (planar3r)"
    task = Task
    robots = ("planar3r",)
    needs = ("fk",)

    def plan(self, scenario, robot: Robot, dt: float) -> JointTrajectory:
        """q(t) by integrating the DLS rates along the line; tool_ref is the line itself."""
        task: Task = scenario.task
        if task.gain * dt >= 1.0:  # forward Euler of e' = -K e converges without overshoot only for K dt < 1
            raise RunError(f"task.gain K = {task.gain:g} 1/s is too high for the control period {dt:g} s: "
                           f"K dt must stay below 1")
        law = scenario.timing.law_fn()
        t = control_grid(law.duration, scenario.timing.hold, dt)
        s, ds = law(t, order=1)
        x0, x1 = goal_pose(task)
        x_ref = x0 + s[:, None] * (x1 - x0)
        xd_ref = ds[:, None] * (x1 - x0)
        q, qd, err = _integrate(np.array(task.start), x_ref, xd_ref, task.damping, task.gain, dt)

        tool_ref = np.column_stack([x_ref[:, :2], np.full(len(t), Z)])
        planned = pose(q)
        deviation = _segment_distance(planned[:, :2], x0[:2], x1[:2])
        position_error = np.linalg.norm(err[:, :2], axis=1)
        k_dev = int(np.argmax(deviation))
        stretched, folded = elbow_gaps(q)
        info = {
            "method": "damped least squares resolved rate, qdot = J^T (J J^T + lambda^2 I)^-1 (Xdot_ref + K e)",
            "damping": task.damping,
            "gain": task.gain,
            "line": {"start": x0.tolist(), "goal": x1.tolist()},
            "max_pose_error": {"position": float(position_error.max()), "phi": float(np.abs(err[:, 2]).max())},
            "max_line_deviation": float(deviation[k_dev]),
            "min_abs_det_J": float(np.min(np.abs(L1 * L2 * np.sin(q[:, 1])))),
        }
        warnings: list[str] = []
        violations: list[Violation] = []
        tol = scenario.analysis
        k_sing = int(np.argmin(np.minimum(stretched, folded)))
        gap, which = ((stretched[k_sing], "stretched (q2 = 0)") if stretched[k_sing] <= folded[k_sing]
                      else (folded[k_sing], "folded (q2 = +-180 deg)"))
        # Near the singular set (the scenario's near_angle) or visibly off the line (a tenth of its path
        # tolerance): say where, and how far DLS strays.
        if gap < tol.near_angle or deviation[k_dev] > 0.1 * tol.path_tolerance:
            warnings.append(f"the plan comes within {np.rad2deg(gap):.2f} deg of the elbow {which} at t = "
                            f"{t[k_sing]:.3f} s; damped least squares trades accuracy for bounded joint rates there: "
                            f"the planned tool is up to {deviation[k_dev] * 1e3:.3f} mm off the line "
                            f"(t = {t[k_dev]:.3f} s)")
        if deviation[k_dev] > tol.path_tolerance:
            violations.append(Violation("off_path", f"the plan leaves the line by up to "
                                        f"{deviation[k_dev] * 1e3:.2f} mm at t = {t[k_dev]:.3f} s (tolerance "
                                        f"{tol.path_tolerance * 1e3:g} mm; the elbow comes within "
                                        f"{np.rad2deg(gap):.2f} deg of {which})"))
        end_error, end_phi = float(np.linalg.norm(err[-1, :2])), float(abs(err[-1, 2]))
        if end_error > tol.goal_tolerance or end_phi > tol.goal_orientation_tolerance:
            violations.append(Violation("goal_missed", f"the plan ends {end_error * 1e3:.2f} mm and "
                                        f"{np.rad2deg(end_phi):.2f} deg from the goal"))
        waypoints = tuple({"s": float(v), "X": [*x.tolist()[:2], Z], "phi": float(x[2]), "q": qk.tolist()}
                          for v, x, qk in ((0.0, x0, q[0]), (1.0, x1, q[-1])))
        return JointTrajectory(t=t, s=s, q_ref=q, qd_ref=qd, tool_ref=tool_ref, waypoints=waypoints, info=info,
                               warnings=tuple(warnings), violations=tuple(violations),
                               series={"line_deviation": deviation, "pose_error": err})

    def check(self, scenario, robot: Robot) -> tuple[str, str] | None:
        """Refuse a goal whose wrist point lies outside the arm's reach, and a line of zero length."""
        task: Task = scenario.task
        x0, x1 = goal_pose(task)
        if np.allclose(x0, x1, rtol=0.0, atol=1e-12):
            return "task.goal", "equals the start's pose: a zero-length line"
        # The wrist (the tip of link 2) lies L3 behind the tool along its heading; links 1 and 2 reach it if
        # its distance r from joint 1 satisfies r_min <= r <= L1 + L2, r_min at q2's range limit (law of cosines).
        wrist = x1[:2] - L3 * np.array([np.cos(task.goal_phi), np.sin(task.goal_phi)])
        r = float(np.linalg.norm(wrist))
        r_min, r_max = np.sqrt(L1**2 + L2**2 + 2 * L1 * L2 * np.cos(UPPER[1])), L1 + L2
        if not r_min <= r <= r_max:
            k, unit = scenario.units.length_factor, scenario.units.length
            return "task.goal", (f"out of reach at goal_phi: the wrist point (goal - L3 (cos phi, sin phi)) lies "
                                 f"{r / k:.6g} {unit} from joint 1, outside [{r_min / k:.6g}, {r_max / k:.6g}] {unit}")
        return None


def _integrate(q0: np.ndarray, x_ref: np.ndarray, xd_ref: np.ndarray, damping: float, gain: float,
               dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q (N, 3), qdot (N, 3) and the pose error e = X_ref - X(q) (N, 3), by forward Euler q_{k+1} = q_k + dt qdot_k.

    Written out in scalars (robot.pose and robot.jacobian, one sample at a time): a step is a few microseconds,
    against tens for NumPy's calls on 3-vectors.
    """
    n = len(x_ref)
    q, qd, err = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    lam2 = damping**2
    q1, q2, q3 = (float(v) for v in q0)
    xr, xdr = x_ref.tolist(), xd_ref.tolist()
    for k in range(n):
        q[k] = q1, q2, q3
        a12, a123 = q1 + q2, q1 + q2 + q3
        c1, s1 = L1 * math.cos(q1), L1 * math.sin(q1)
        c12, s12 = L2 * math.cos(a12), L2 * math.sin(a12)
        c123, s123 = L3 * math.cos(a123), L3 * math.sin(a123)
        ex, ey, ep = xr[k][0] - (c1 + c12 + c123), xr[k][1] - (s1 + s12 + s123), xr[k][2] - a123
        err[k] = ex, ey, ep
        jac = np.array([[-(s1 + s12 + s123), -(s12 + s123), -s123],
                        [c1 + c12 + c123, c12 + c123, c123],
                        [1.0, 1.0, 1.0]])
        v = np.array([xdr[k][0] + gain * ex, xdr[k][1] + gain * ey, xdr[k][2] + gain * ep])
        rate = jac.T @ np.linalg.solve(jac @ jac.T + lam2 * np.eye(3), v)
        qd[k] = rate
        q1, q2, q3 = q1 + dt * rate[0], q2 + dt * rate[1], q3 + dt * rate[2]
    return q, qd, err


PLANNER = DLSLine()
