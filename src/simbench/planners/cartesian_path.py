"""A tool path of lines and arcs for any serial arm simbench can evaluate (robots.model_arm), by damped
least-squares resolved rates with closed-loop correction (or another method).

The task: the joints `start`, the path (decoupled_path's segments, each placed absolutely or from where the path
is: path_segments; the first line's start may be left out: the tool's point at `start`) on the scenario's time law,
and the orientation: `hold`, a goal reached by slerp along the path, or `free`: the tool's point alone follows the
path, its orientation whatever the joints give (an arm of fewer than six joints cannot hold one along a line). At
each control sample k, in the unit-consistent frame of robots.rank_loss (Ju = [Jp / L; Jr], the twist
x = [v / L; w], L the reach; a free task keeps the position rows alone: Ju = Jp / L, x = v / L, e_k the point's
error):

    qd_k = Ju# (x_d + K e_k) + (I - Ju+ Ju) K_N (q_start - q_k)        q_{k+1} = q_k + dt qd_k

  - x_d the path's twist (its tangent times ds/dt; the slerp's axis times its angle times ds/dt), e_k the tool's
    error at q_k: the point's / L, and the orientation's 1/2 (n x n_d + s x s_d + a x a_d) (Siciliano et al.,
    Robotics: Modelling, Planning and Control, 2009, eq. 3.85);
  - K = CLIK_SHARE / dt, closed-loop inverse kinematics (ibid., sec. 3.7, eq. 3.70): Euler's error does not
    accumulate, the gain under the 1 / dt at which explicit Euler would overshoot;
  - Ju# the method's damped least-squares inverse (ibid., eq. 3.59; path_methods);
  - a redundant arm (more joints than Ju has rows: 6, or 3 on a free task) is pulled back to its start posture at
    rate K_N = NULL_GAIN in the null space of Ju (ibid., eq. 3.54; Ju+ the pseudo-inverse);
  - a joint the rates would take past a limit within the sample is held to reach it exactly and the others solved
    again (Flacco, De Luca and Khatib, IEEE Trans. Robot. 31(3), 2015, Alg. 1, without its task scaling);
  - rates over a speed limit are all scaled down together (ours): the tool falls behind the time law, which the
    closed loop makes up where it can;
  - dls_adaptive damps only a passage (samples in a row where sigma_min < EPSILON) in which pinv's rates would pass
    a speed limit, and crosses any other by pinv, on the path (ours). There the damping would lower no rate: along
    the damped direction (singular value sigma, commanded twist x_n) the loop settles, within about
    (sigma^2 + lambda^2) / (K sigma^2), at pinv's rate x_n / sigma, the tool x_n lambda^2 / (K sigma^2) behind
    (Ju's units), off the path wherever that direction is not the path's.

sigma_min, which the plan damps on and reports (`sigma_min_least`), is that of the rows of Ju the task uses: on a
free task, of Jp / L alone. The run's `rank_loss` analysis is the robot's, of [Jp / L; Jr], whatever the task.

`task.method` picks the rate rule (path_methods, with references): the above is `dls_adaptive`; `dls` has a fixed
lambda (`task.damping`); `pinv` is never scaled down (the verdict reports `velocity_limit`); `time_scaling` retimes
pinv's joint path by TOPP-RA under the speed and acceleration limits (path_retiming; the report's `slowdown`;
`acceleration_limit` where its exact joints still ask more, at a corner or a singularity); `mink` solves
mink_baseline's QP per control step (its orientation cost 0 on a free task, as on an arm of fewer than six
joints); `sns` saturates joints at their speed limits and ranges and scales the task's twist where it must (its
scale is `plan_speed_scale`); `gradient` (a redundant arm's alone) climbs manipulability in the null space, in place
of the return to the start posture; `priority` keeps the tool's point first and its orientation second, damped, and
is scaled down as dls is. Every method but mink holds the joint ranges as above (sns within its bounds).

A corner between segments (their tangents more than path_segments.CORNER apart) is a plan warning: the tool's
velocity turns there within one control step. Where the plan's own tool leaves the path by more than the path
tolerance, or ends farther than the goal tolerance from its end, the plan reports it (`off_path`, `goal_missed`),
with each joint held at a limit there (`joint_limit`); where its tool turns from the asked orientation by more
than the orientation tolerance, `orientation_error`. A free task asks none: its plan writes no
`tool_orientation_ref`, so the run reports the tool's orientation unjudged.
"""

from __future__ import annotations

from functools import partial
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, ValidationInfo, field_validator

from simbench.api import REVOLUTE, Planner, Violation
from simbench.api.trajectory import ORIENTATION_REF, JointTrajectory, control_grid
from simbench.core import extras
from simbench.maths.path_distance import path_deviation
from simbench.maths.paths import Composite
from simbench.maths.rotations import axis_rotation, matrix_to_quat
from simbench.planners.decoupled_path import join_gap, segment_waypoints
from simbench.planners.path_methods import DAMPING, EPSILON, GRADIENT_GAIN, LAMBDA_MAX, METHODS, resolver_of
from simbench.planners.path_reach import beyond_reach
from simbench.planners.path_retiming import ACCEL_TIME
from simbench.planners.path_segments import PathSegment, corner_warning, corners, place, placed_path
from simbench.planners.resolved_rates import (CLIK_SHARE, KNOT_STEP, NULL_GAIN, POSITION_ROWS, integrate,
                                              orientation_error, sigma_min, task_error, tool_pose)
from simbench.scenario.schema import JointVector, Orientation, SimbenchModel, Units

START_TOL = 1e-4  # m: a first line's given start must be this near the tool's point at `start`
MAX_ACCELERATION = 1e6  # rad/s^2 or m/s^2: time_scaling's acceleration limits at most
RETIMED = ("time_scaling", "ruckig")  # the methods that keep pinv's exact joint path and retime it
_NEEDS = ("fk", "tool_rotation", "jacobian", "reach", "anchor")  # what the planner reads of the robot


class Task(SimbenchModel):
    """`task:` of cartesian_path: the joints at the start, the tool's path, its orientation along it."""

    start: JointVector
    path: list[PathSegment] = Field(min_length=1)
    orientation: Literal["hold", "free"] | Orientation = Field(
        "hold", description="'hold': the tool's orientation at start, all along; 'free': the tool's point alone "
                            "follows the path, its orientation whatever the joints give; or the orientation it "
                            "turns to by slerp along the path")
    method: Literal["dls_adaptive", "pinv", "dls", "time_scaling", "mink", "sns", "gradient", "priority",
                    "ruckig"] = Field(
        "dls_adaptive", description="how a singularity is met: " + ", ".join(METHODS) + " (path_methods)")
    damping: Annotated[float, Field(gt=0, le=1)] | None = Field(
        None, description=f"dls's fixed lambda, dimensionless (a metre at the reach's end counts as a radian); "
                          f"default {DAMPING:g}")
    knot_step: Annotated[float, Field(ge=0, le=1)] = Field(
        KNOT_STEP, description="s: where the arm is clear of its singular set and its limits, the joints are put on "
                               "the path at knots this far apart and the control samples between follow a cubic "
                               "through them; 0: every control sample resolved alone (resolved_rates.integrate)")
    acceleration_limits: list[float] | None = Field(
        None, description="time_scaling's and ruckig's joint acceleration limits, the angle (or length) unit per "
                          f"s^2, one per joint; default each speed limit / {ACCEL_TIME:g} s")

    @field_validator("damping")
    @classmethod
    def _dls_only(cls, value: float | None, info: ValidationInfo) -> float | None:
        if value is not None and info.data.get("method", "dls") != "dls":
            raise ValueError(f"is dls's fixed damping; method {info.data['method']} has none")
        return value

    @field_validator("acceleration_limits")
    @classmethod
    def _per_joint(cls, value: list[float] | None, info: ValidationInfo) -> list[float] | None:
        if value is None:
            return None
        if info.data.get("method", "time_scaling") not in RETIMED:
            raise ValueError(f"are time_scaling's and ruckig's; method {info.data['method']} reads none")
        robot = (info.context or {}).get("robot")
        if robot is None:
            return value
        if len(value) != robot.dof:
            raise ValueError(f"expected {robot.dof} values, one per joint ({', '.join(robot.joints)}), "
                             f"got {len(value)}")
        units = (info.context or {}).get("units", Units())
        si = [v * units.factor(kind) for v, kind in zip(value, robot.kinds)]
        bad = next((v for v, x in zip(value, si) if not 0 < x <= MAX_ACCELERATION), None)
        if bad is not None:
            raise ValueError(f"expected limits in (0, {MAX_ACCELERATION:g}] rad/s^2 or m/s^2, got {bad:g} "
                             "(the file's unit per s^2)")
        return si


def _rows(task: Task) -> int:
    """The rows of Ju and of the twist the task asks for: the point's alone where its orientation is free."""
    return POSITION_ROWS if task.orientation == "free" else 6


def _angles(r_goal: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The angles (N,) in [0, pi] of the rotations from r to r_goal (N, 3, 3): atan2 of eq. 3.85's sin (the norm of
    orientation_error) and the cos from the trace, exact near 0 and past 90 deg, where the arcsine folds back."""
    sin = np.linalg.norm(orientation_error(r_goal, r), axis=-1)
    cos = (np.einsum("nij,nij->n", r_goal, r) - 1) / 2
    return np.arctan2(sin, cos)


def _turn(r0: np.ndarray, r1: np.ndarray) -> np.ndarray:
    """The rotation vector (3,), world frame, of the rotation from r0 to r1 (the slerp's axis times its angle)."""
    w, *xyz = matrix_to_quat((r1 @ r0.T)[None])[0]
    sin = np.linalg.norm(xyz)
    return np.zeros(3) if sin < 1e-12 else 2 * np.arctan2(sin, w) * np.asarray(xyz) / sin


class CartesianPath(Planner):
    """Lines and arcs of the tool for any serial arm: damped least-squares resolved rates, closed loop."""

    name = "cartesian_path"
    description = ("lines and arcs of the tool for any serial arm (a derived one): damped least-squares resolved "
                   "rates on the tool's twist, closed loop")
    task = Task

    def refuses(self, robot) -> str | None:
        """An arm whose tool orientation, 6-row Jacobian and reach simbench cannot read (the analytic robots)."""
        lacking = [name for name in _NEEDS if not (robot.has_fk if name == "fk" else hasattr(robot, name))]
        if lacking:
            return (f"'{self.name}' needs the robot's {', '.join(lacking)} (an arm derived from its model has them), "
                    f"which '{robot.name}' has not")
        return None

    def check(self, scenario, robot) -> tuple[str, str] | None:
        """Only the first line, or one placed by an offset, may leave out its start; a relative arc must start
        where the path is (path_segments.place); a given start (a line's, an arc's first point) must be the tool's
        point at `start`, the segments must join, and none may reach past the arm (_beyond_reach); the `mink`
        method needs mink installed (extras)."""
        task = scenario.task
        refusal = extras.missing("mink", "the mink method") if task.method == "mink" else None
        if refusal:
            return "task.method", refusal
        if task.method == "gradient" and robot.dof <= _rows(task):
            return "task.method", (f"gradient moves the joints the task leaves free: it needs more joints than the "
                                   f"task's {_rows(task)} rows, and {robot.name} has {robot.dof}")
        for i, seg in enumerate(task.path[1:], 1):
            if seg.line is not None and seg.line.start is None and seg.line.end is not None:
                return f"task.path[{i}].line.start", ("missing: only the first line, or one placed by 'by' or "
                                                      "'by_tool', may leave out its start")
        q0 = np.array([task.start])
        tool = robot.fk(q0)[0]
        segments, misfit = place(task.path, tool, robot.tool_rotation(q0)[0])
        if misfit is not None:
            return misfit
        first = task.path[0].line
        if first is not None and first.start is not None and np.linalg.norm(tool - first.start) > START_TOL:
            gap = np.linalg.norm(tool - first.start) * 1e3
            return ("task.path[0].line.start", f"lies {gap:.3f} mm from the tool's point at task.start: leave it "
                                               "out to start where the tool is")
        if first is not None and segments[0].length < 1e-9:
            return f"task.path[0].line.{first.placed_by}", "is the tool's point at task.start: a zero-length line"
        gap = np.linalg.norm(tool - segments[0].point(np.zeros(1))[0])
        if first is None and gap > START_TOL:
            return "task.path[0].arc", (f"starts {gap * 1e3:.3f} mm from the tool's point at task.start: the path "
                                        "must start there")
        return join_gap(segments) or beyond_reach(task.path, segments, robot)

    def plan(self, scenario, robot, dt: float) -> JointTrajectory:
        """The task's method on the control grid (the module's docstring)."""
        task = scenario.task
        law = scenario.timing.law_fn()
        t = control_grid(law.duration, scenario.timing.hold, dt)
        s, ds = law(t, order=1)
        q0 = np.array(task.start)
        r0 = robot.tool_rotation(q0[None])[0]  # a free task's rotations stay r0: no row reads them, mink weighs 0
        segments, _ = place(task.path, robot.fk(q0[None])[0], r0)  # check placed them all
        path = Composite(tuple(segments))
        rows = _rows(task)
        turn = _turn(r0, r0 if task.orientation in ("hold", "free") else task.orientation.matrix())
        angle = np.linalg.norm(turn)
        axis = turn / angle if angle > 0 else np.array([0.0, 0.0, 1.0])

        def pose(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            return path.point(s), axis_rotation(np.tile(axis, (len(s), 1)), s * angle) @ r0

        def twist(s: np.ndarray, ds: np.ndarray) -> np.ndarray:
            x = np.hstack([path.tangent(s) / robot.reach, turn[None] * np.ones((len(s), 1))])
            return x[:, :rows] * ds[:, None]

        points, rotations = pose(s)
        extra: dict = {}
        series: dict = {}
        fast: tuple = ()  # time_scaling's acceleration_limit violations
        if task.method in RETIMED:
            t, s, q, qd, sigma, held, extra, fast = self._time_scaled(task, robot, law, pose, twist, q0, dt,
                                                                      scenario.timing.hold)
            points, rotations = pose(s)
            lam2, scale = np.zeros(len(t)), np.ones(len(t))
        elif task.method == "mink":
            q, qd, extra = _mink(robot, points, rotations, q0, dt, rows)
            sigma = sigma_min(robot, q, rows)
            lam2, scale, held = np.zeros(len(t)), np.ones(len(t)), np.zeros(q.shape, bool)
        else:
            q, qd, sigma, lam2, scale, held = integrate(robot, q0, points, rotations, twist(s, ds), dt,
                                                        resolver_of(task.method, task.damping), task.knot_step)
            extra = {"gradient_gain": GRADIENT_GAIN} if task.method == "gradient" else {}
            if task.method != "dls_adaptive":
                series = {"plan_damping": np.sqrt(lam2), "plan_speed_scale": scale}
        tool, tool_rotations = tool_pose(robot, q)
        off = path_deviation(points, tool)
        turned = _angles(rotations, tool_rotations) if rows > POSITION_ROWS else None  # None: free
        info = {"method": _DESCRIPTION[task.method],
                "constants": {"epsilon": EPSILON, "lambda_max": LAMBDA_MAX, "clik_gain": CLIK_SHARE / dt,
                              "null_gain": NULL_GAIN if robot.dof > rows and task.method != "gradient" else None,
                              "reach": robot.reach, "knot_step": task.knot_step},
                "segments": [("line" if seg.line else "arc") for seg in task.path], "path": placed_path(segments),
                "path_length": path.length,
                "sigma_min_least": float(sigma.min()), "damped_from": _first(t, lam2 > 0),
                "speed_scaled_from": _first(t, scale < 1), "plan_path_deviation_max": float(off.max()),
                "plan_goal_error": float(np.linalg.norm(tool[-1] - points[-1])),
                "plan_orientation_error_max": None if turned is None else float(turned.max())}
        if task.method != "dls_adaptive":
            info["path_method"] = task.method
            info["damping"] = float(np.sqrt(lam2.max())) if task.method == "dls" else None
            excess = np.abs(qd) / robot.qd_max
            info["speed_share_max"] = float(excess.max())
            info["speed_exceeded_from"] = _first(t, (excess > 1).any(axis=1))
            info.update(extra)
        violations = self._off_path(t, off, sigma, scenario.analysis.path_tolerance, held)
        violations += self._turned(t, turned, sigma, scenario.analysis.orientation_tolerance, held)
        if info["plan_goal_error"] > scenario.analysis.goal_tolerance:
            violations += (Violation("goal_missed", f"the plan's own tool ends {info['plan_goal_error'] * 1e3:.2f} mm "
                                     f"from the path's end (tolerance {scenario.analysis.goal_tolerance * 1e3:g} mm)",
                                     float(t[-1]), 0, {"error": info["plan_goal_error"]}),)
        info["range_held_from"] = _first(t, held.any(axis=1))
        if violations:
            violations += self._held(robot, t, q, held, off > scenario.analysis.path_tolerance,
                                     any(v.kind == "goal_missed" for v in violations))
        violations += fast
        if turned is not None:  # what the tool's orientation is judged against; a free task asks none
            series[ORIENTATION_REF] = matrix_to_quat(rotations)
        info["corners"] = corners(path, robot, t, s, qd)
        return JointTrajectory(t=t, s=s, q_ref=q, qd_ref=qd, tool_ref=points,
                               waypoints=segment_waypoints(path, s, q), info=info, violations=violations,
                               warnings=tuple(corner_warning(c, robot) for c in info["corners"]), series=series)

    @classmethod
    def _time_scaled(cls, task: Task, robot, law, pose, twist, q0: np.ndarray, dt: float,
                     hold: float) -> tuple:
        """time_scaling and ruckig (pinv's joint path retimed by TOPP-RA: path_retiming; with jerk limits by Ruckig:
        jerk_retiming): t, s, q, qd, sigma_min, the joints held at a limit (N, dof), the report's slowdown and
        durations, and the joints past their acceleration limits."""
        from simbench.planners.path_retiming import acceleration_violations, exact_ik, retime

        n = max(int(round(law.duration / dt)), 2) + 1
        grid = np.linspace(0.0, 1.0, n)
        step = law.duration / (n - 1)
        rows = _rows(task)
        error_of = partial(task_error, robot, rows=rows)  # exact_ik's: the pose's, or a free task's point's
        points, rotations = pose(grid)
        q, _, _, _, _, held = integrate(robot, q0, points, rotations, twist(grid, np.full(n, 1 / law.duration)),
                                        step, resolver_of("pinv", None), task.knot_step)
        q, _ = exact_ik(robot, q, points, rotations, error_of)
        qdd_max = (np.array(task.acceleration_limits) if task.acceleration_limits is not None
                   else robot.qd_max / ACCEL_TIME)
        if task.method == "ruckig":
            from simbench.planners.jerk_retiming import default_jerk_limits, retime_jerk

            t, s, q_spline, qd, duration = retime_jerk(grid, q, law, robot.qd_max, qdd_max,
                                                       default_jerk_limits(qdd_max), dt, hold)
        else:
            t, s, q_spline, qd, duration = retime(grid, q, law, robot.qd_max, qdd_max, dt, hold)
        points, rotations = pose(s)
        q_plan, residual = exact_ik(robot, np.clip(q_spline, robot.lower, robot.upper), points, rotations,
                                    error_of)  # the spline may overshoot a limit its samples hold
        sigma = sigma_min(robot, q_plan, rows)
        at = np.clip(np.searchsorted(grid, s), 0, n - 1)
        share, fast = acceleration_violations(robot, t, q_plan, qd, qdd_max)
        extra = {"slowdown": duration / law.duration, "duration_asked": law.duration, "duration_planned": duration,
                 "acceleration_limits": qdd_max.tolist(), "acceleration_share_max": float(share.max()),
                 "ik_residual_max": float(residual.max())}
        return t, s, q_plan, qd, sigma, held[at], extra, fast

    @staticmethod
    def _held(robot, t: np.ndarray, q: np.ndarray, held: np.ndarray, off: np.ndarray,
              missed: bool) -> tuple[Violation, ...]:
        """The joints held at a limit where the plan's tool is off the path (`off`, per sample) or, with the goal
        `missed`, at the end: one `joint_limit` each, the path needing the joint past its range there."""
        where = off.copy()
        where[-1] |= missed
        out = []
        for j in np.flatnonzero((held & where[:, None]).any(axis=0)):
            k = int(np.argmax(held[:, j] & where))
            upper = abs(q[k, j] - robot.upper[j]) <= abs(q[k, j] - robot.lower[j])
            bound, limit = ("upper", robot.upper[j]) if upper else ("lower", robot.lower[j])
            shown = f"{np.rad2deg(limit):.2f} deg" if robot.kinds[j] == REVOLUTE else f"{limit * 1e3:.2f} mm"
            out.append(Violation("joint_limit", f"the path needs {robot.joints[j]} past its {bound} limit {shown} "
                                 f"from t = {t[k]:.3f} s: the plan keeps it inside, off the path",
                                 float(t[k]), 0, {"joint": robot.joints[j], "bound": bound, "limit": float(limit),
                                                  "source": "planner"}))
        return tuple(out)

    @staticmethod
    def _turned(t: np.ndarray, turned: np.ndarray | None, sigma: np.ndarray, tolerance: float,
                held: np.ndarray) -> tuple[Violation, ...]:
        """The plan's own tool turned from the asked orientation beyond the orientation tolerance: from when, how
        far, and why (a damped rule gives up orientation as it gives up the path). None where a free task asks
        none."""
        if turned is None or turned.max() <= tolerance:
            return ()
        k, worst = int(np.argmax(turned > tolerance)), int(np.argmax(turned))
        why = (f"a joint held at its limit, least singular value {sigma[worst]:.3g}" if held[worst].any()
               else f"damped near a rank loss (least singular value {sigma[worst]:.3g} there), out of reach, or "
                    "more than the arm's joints can turn")
        return (Violation("orientation_error", f"the plan's own tool turns up to {np.rad2deg(turned[worst]):.2f} deg "
                          f"from the asked orientation (tolerance {np.rad2deg(tolerance):g} deg) from t = "
                          f"{t[k]:.3f} s: {why}", float(t[k]), 0,
                          {"worst": float(turned[worst]), "sigma_min": float(sigma[worst]), "source": "planner"}),)

    @staticmethod
    def _off_path(t: np.ndarray, off: np.ndarray, sigma: np.ndarray, tolerance: float,
                  held: np.ndarray) -> tuple[Violation, ...]:
        """The plan's own tool beyond the path tolerance: from when, how far, and why."""
        if off.max() <= tolerance:
            return ()
        k, worst = int(np.argmax(off > tolerance)), int(np.argmax(off))
        why = (f"a joint held at its limit (joint_limit), least singular value {sigma[worst]:.3g}" if held[worst].any()
               else f"damped near a rank loss (least singular value {sigma[worst]:.3g} there) or out of reach")
        return (Violation("off_path", f"the plan's own tool leaves the path by up to {off[worst] * 1e3:.2f} mm "
                          f"(tolerance {tolerance * 1e3:g} mm) from t = {t[k]:.3f} s: {why}", float(t[k]), 0,
                          {"worst": float(off[worst]), "sigma_min": float(sigma[worst])}),)


def _mink(robot, points: np.ndarray, rotations: np.ndarray, q0: np.ndarray, dt: float, rows: int) -> tuple:
    """mink: mink_baseline's QP per control step (its defaults) towards the path's next pose, from q0, the
    orientation's cost 0 where the task's rows are the point's alone (free) or the arm has fewer than 6 joints.
    Returns q, qd and the QP's failures."""
    import mujoco

    from simbench.planners import mink_baseline as mb

    poses = np.empty((len(points), 7))
    poses[:, 4:] = points
    for pose, rotation in zip(poses, rotations):
        mujoco.mju_mat2Quat(pose[:4], rotation.reshape(-1))
    defaults = {name: mb.Task.model_fields[name].default for name in ("damping", "posture_cost", "solver")}
    costs = (mb.Task.model_fields["position_cost"].default, 1.0 if robot.dof >= 6 and rows > POSITION_ROWS else 0.0)
    q, qd, met = mb.solve(mb.scene_model(robot), robot, dt, poses, q0, defaults["damping"], costs,
                          defaults["posture_cost"], defaults["solver"])
    return q, qd, {"qp_failures": len(met["failed"]), "mink": {**defaults, "costs": list(costs)}}


_DESCRIPTION = {
    "dls_adaptive": "damped least-squares resolved rates on the unit-consistent tool twist, closed loop "
                    "(Siciliano et al. 2009, eqs. 3.59, 3.70; variable damping: Chiaverini et al. 1994), damping "
                    "only a passage near a rank loss that the pseudo-inverse would cross past a speed limit",
    "dls": "damped least-squares resolved rates with fixed damping on the unit-consistent tool twist, closed loop "
           "(Wampler 1986; Nakamura and Hanafusa 1986)",
    "pinv": "pseudo-inverse resolved rates on the unit-consistent tool twist, closed loop, joint speeds unbounded "
            "(Whitney 1969)",
    "time_scaling": "pinv's joint path solved exactly on the path, retimed by TOPP-RA under the joints' speed and "
                    "acceleration limits (Pham and Pham 2018)",
    "ruckig": "pinv's joint path solved exactly on the path, retimed under the joints' speed, acceleration and jerk "
              "limits by Ruckig on the path parameter (Berscheid and Kroeger 2021)",
    "mink": "mink's differential-IK QP per control step along the path (joint ranges and speed limits as "
            "constraints)",
    "sns": "pseudo-inverse resolved rates with joints saturated in the null space and the task's twist scaled "
           "under the speed limits and ranges, closed loop (Flacco, De Luca and Khatib 2012)",
    "gradient": "pseudo-inverse resolved rates plus manipulability's gradient in the null space, closed loop "
                "(Liegeois 1977; Yoshikawa 1985)",
    "priority": "task-priority resolved rates, the tool's point first and its orientation in the null space, "
                "damped inverses, closed loop (Nakamura et al. 1987; Chiaverini 1997)",
}


def _first(t: np.ndarray, mask: np.ndarray) -> float | None:
    """The first time where mask holds, or None."""
    return float(t[np.argmax(mask)]) if mask.any() else None


PLANNER = CartesianPath()
