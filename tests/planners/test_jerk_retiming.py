"""jerk_retiming.retime_jerk (issue 47): Ruckig's jerk-limited timing of a joint path, checked on random joint paths
(fixed seed) by finite differences of its returned samples alone, against the joints' limits:

  - the path kept: q(t) is the joint path's spline (toppra's SplineInterpolator, which path_retiming.retime uses)
    at s(t), and qd(t) its rates (central differences within dt^2 jerk_max / 6);
  - every joint's speed, acceleration and jerk (first, second and third differences of q) within its limits, and s's
    acceleration and jerk within what the most-moving joint allows by itself (min_j limit_j / |q_j'(s)|);
  - s from 0 to 1, never back, at rest from the planned duration on;
  - the duration at least TOPP-RA's time-optimal one under the same speed and acceleration limits without a jerk
    limit (toppra on a uniform grid, no law), and the slowdown against path_retiming.retime's printed
    (`pytest -n 0 -s`);
  - fast joints follow the asked law (about its duration, never shorter); a timing past MAX_SLOWDOWN is refused.

Paths: splines through random points of 6 joints, and such paths with a wrist flip (q4 and q6 turning 3 rad in a
few percent of the path, as pinv's near a wrist singularity), where |q'(s)| peaks 150 times the path's own.
"""

import numpy as np
import pytest
import toppra
import toppra.algorithm
import toppra.constraint
from scipy.interpolate import CubicSpline

from simbench.api.trajectory import control_grid
from simbench.core.errors import RunError
from simbench.maths.timing import LAWS, TimeLaw
from simbench.planners.jerk_retiming import default_jerk_limits, retime_jerk
from simbench.planners.path_retiming import ACCEL_TIME, MARGIN, retime

DT, HOLD = 0.004, 0.1
ROUNDING = 1e-9  # relative: floating-point room in the finite differences


def _path(rng, n: int, flip: bool) -> np.ndarray:
    """A random smooth joint path (n, 6) on a uniform s grid; with a wrist flip, q4 and q6 turning fast about a
    random s."""
    grid = np.linspace(0.0, 1.0, n)
    knots = rng.integers(3, 8)
    q = CubicSpline(np.linspace(0.0, 1.0, knots), rng.uniform(-1.5, 1.5, (knots, 6)))(grid)
    if flip:
        width, centre = rng.uniform(0.005, 0.02), rng.uniform(0.2, 0.8)
        turn = 1.5 * np.arctan((grid - centre) / width)
        q[:, 3] += turn
        q[:, 5] -= turn
    return q


def _limits(rng):
    """Random speed limits (rad/s), acceleration limits about path_retiming's default, jerk about the default."""
    qd_max = rng.uniform(0.5, 3.0, 6)
    qdd_max = qd_max / ACCEL_TIME * rng.uniform(0.5, 2.0, 6)
    return qd_max, qdd_max, default_jerk_limits(qdd_max) * rng.uniform(0.5, 2.0, 6)


def _toppra_duration(grid, q, qd_max, qdd_max) -> float:
    """TOPP-RA's time-optimal duration of the path's spline under MARGIN of the speed and acceleration limits."""
    constraints = [toppra.constraint.JointVelocityConstraint(np.column_stack([-MARGIN * qd_max, MARGIN * qd_max])),
                   toppra.constraint.JointAccelerationConstraint(np.column_stack([-MARGIN * qdd_max,
                                                                                  MARGIN * qdd_max]))]
    solver = toppra.algorithm.TOPPRA(constraints, toppra.SplineInterpolator(grid, q),
                                     gridpoints=np.linspace(0.0, 1.0, 1001), parametrizer="ParametrizeConstAccel")
    return float(solver.compute_trajectory(0.0, 0.0).duration)


def _check(grid, q_grid, law, qd_max, qdd_max, jerk_max) -> float:
    """retime_jerk's timing of the path, checked (the module's docstring); returns its duration."""
    t, s, q, qd, duration = retime_jerk(grid, q_grid, law, qd_max, qdd_max, jerk_max, DT, HOLD)
    assert np.array_equal(t, control_grid(duration, HOLD, DT))
    assert s.shape == t.shape and q.shape == qd.shape == (len(t), 6)
    spline = toppra.SplineInterpolator(grid, q_grid)
    assert np.abs(q - spline(s)).max() < 1e-12
    assert np.abs(qd[1:-1] - (q[2:] - q[:-2]) / (2 * DT)).max() <= DT**2 * jerk_max.max() / 6 * 1.01 + 1e-12
    for order, limit in enumerate((qd_max, qdd_max, jerk_max), start=1):
        ratio = np.abs(np.diff(q, order, axis=0)) / DT**order / limit
        assert ratio.max() <= 1.0 + ROUNDING, f"order {order}: {ratio.max():.4f} of the limit"
    slope = np.abs(spline(s, 1))  # |q'(s)|: what the joints allow s by themselves
    with np.errstate(divide="ignore"):
        for order, limit in ((2, qdd_max), (3, jerk_max)):
            allowed = (limit / slope).min(axis=1)
            spans = np.lib.stride_tricks.sliding_window_view(allowed, order + 1).max(axis=1)
            assert (np.abs(np.diff(s, order)) / DT**order <= spans * (1 + 1e-6)).all()
    assert s[0] == 0.0 and s[-1] == 1.0 and np.diff(s).min() >= 0.0
    rest = t >= duration
    assert rest.sum() >= int(HOLD / DT) and (s[rest] == 1.0).all() and (qd[rest] == 0.0).all()
    return duration


@pytest.mark.parametrize("flip", [False, True], ids=["smooth", "wrist_flip"])
def test_random_paths_keep_the_path_and_the_joint_limits(flip):
    """24 random paths each: the limits by finite differences, and never faster than TOPP-RA without jerk limits."""
    rng = np.random.default_rng(47 + flip)
    slowdowns, against_retime = [], []
    for _ in range(12 if flip else 24):
        law = TimeLaw(str(rng.choice(LAWS)), float(rng.uniform(0.5, 2.0)))
        n = round(law.duration / DT) + 1
        grid, q = np.linspace(0.0, 1.0, n), _path(rng, n, flip)
        qd_max, qdd_max, jerk_max = _limits(rng)
        duration = _check(grid, q, law, qd_max, qdd_max, jerk_max)
        optimal = _toppra_duration(grid, q, qd_max, qdd_max)
        assert duration >= optimal
        slowdowns.append(duration / optimal)
        try:
            against_retime.append(duration / retime(grid, q, law, qd_max, qdd_max, DT, HOLD)[-1])
        except RunError:  # retime's TOPP-RA finds no timing on some of these (the law's gridpoints)
            pass
    print(f"\n{'wrist flip' if flip else 'smooth'}: duration / TOPP-RA's (no jerk limit) "
          f"{np.min(slowdowns):.2f}..{np.max(slowdowns):.2f} (median {np.median(slowdowns):.2f}); / retime's "
          f"{np.min(against_retime):.2f}..{np.max(against_retime):.2f} (median {np.median(against_retime):.2f}, "
          f"{len(against_retime)} of {len(slowdowns)})")


def test_fast_joints_follow_the_asked_law():
    """Joints whose limits are 10 times what the asked quintic law asks of them (its samples' differences): the
    timing takes about the law's duration, never much less (the law caps sd; the stop at s = 1 is Ruckig's)."""
    law = TimeLaw("quintic", 1.0)
    n = round(law.duration / DT) + 1
    grid, q = np.linspace(0.0, 1.0, n), _path(np.random.default_rng(7), n, False)
    asked = toppra.SplineInterpolator(grid, q)(law(control_grid(law.duration, HOLD, DT), order=0)[0])
    qd_max, qdd_max, jerk_max = (10 * np.abs(np.diff(asked, order, axis=0)).max(axis=0) / DT**order
                                 for order in (1, 2, 3))
    duration = _check(grid, q, law, qd_max, qdd_max, jerk_max)
    print(f"\nfast joints: duration / the asked law's {duration / law.duration:.3f}")
    assert 0.98 * law.duration <= duration <= 1.1 * law.duration


def test_a_timing_past_max_slowdown_is_refused():
    """A path the joints can only crawl along: RunError naming the stretch, before any cycle is run."""
    grid = np.linspace(0.0, 1.0, 251)
    with pytest.raises(RunError, match="more than 100 times the asked 1 s"):
        retime_jerk(grid, np.outer(grid, np.full(6, 3.0)), TimeLaw("quintic", 1.0), np.full(6, 0.01),
                    np.full(6, 0.1), np.full(6, 1.0), DT, HOLD)


def test_cartesian_paths_ruckig_method_keeps_the_wrist_line_and_the_jerk_limits(tmp_path):
    """task.method: ruckig on paper 002's wrist line (the PUMA's MJCF, its drives' speed limits): by MuJoCo's own
    kinematics the tool stays on the line; the plan's joint speeds, accelerations and jerks (differences of its
    samples) within the limits (jerk: the default, acceleration limit / JERK_TIME); no faster than TOPP-RA's."""
    import mujoco
    import yaml

    from simbench.core.resources import models_dir
    from simbench.planners.jerk_retiming import JERK_TIME
    from simbench.scenario import load_scenario

    model_path = models_dir() / "puma600" / "puma600.xml"
    plans = {}
    for method in ("time_scaling", "ruckig"):
        doc = {"robot": {"model": str(model_path), "tool": {"site": "tool"},
                         "speed_limits": [250, 250, 250, 300, 300, 300]},
               "planner": "cartesian_path", "units": {"angle": "deg", "length": "mm"},
               "timing": {"law": "quintic", "duration": 2},
               "task": {"start": [181.8737, -117.777, -222.6356, 15.0872, 15.8376, -13.0006],
                        "path": [{"line": {"end": [780, -149, -200]}}], "method": method}}
        (tmp_path / f"{method}.yaml").write_text(yaml.safe_dump(doc))
        sc = load_scenario(tmp_path / f"{method}.yaml")
        plans[method] = sc.planner_def.plan(sc, sc.robot_def, 0.001)
    robot, plan = sc.robot_def, plans["ruckig"]
    model = mujoco.MjModel.from_xml_path(str(model_path))
    data = mujoco.MjData(model)
    adr = [model.joint(name).qposadr[0] for name in robot.joints]
    site = model.site("tool").id
    tool = []
    for q in plan.q_ref:
        data.qpos[adr] = q
        mujoco.mj_kinematics(model, data)
        tool.append(data.site_xpos[site].copy())
    tool = np.array(tool)
    start, end = tool[0], tool[-1]
    along = np.clip((tool - start) @ (end - start) / ((end - start) @ (end - start)), 0, 1)
    assert np.linalg.norm(tool - (start + along[:, None] * (end - start)), axis=1).max() < 1e-6
    assert np.linalg.norm(end - np.array([0.780, -0.149, -0.200])) < 1e-6  # the line's end (the model's frame)
    qdd_max = robot.qd_max / ACCEL_TIME
    dt = plan.t[1] - plan.t[0]
    assert np.all(np.abs(plan.qd_ref) <= robot.qd_max)
    accel = np.abs(np.diff(plan.qd_ref, axis=0)) / dt
    assert np.all(accel <= qdd_max)
    jerk = np.abs(np.diff(plan.qd_ref, 2, axis=0)) / dt**2
    assert np.all(jerk <= qdd_max / JERK_TIME)
    assert plan.info["duration_planned"] >= plans["time_scaling"].info["duration_planned"]
    assert plan.info["path_method"] == "ruckig" and plan.info["slowdown"] >= 1.0
