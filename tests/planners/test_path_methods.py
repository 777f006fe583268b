"""cartesian_path's `task.method` (issue 36) on the generic PUMA 600 (its own MJCF) along paper 002's wrist line,
which passes 3.7 deg from q5 = 0. Each method is checked against MuJoCo's own kinematics (mj_jacSite,
mj_kinematics), computed here from the scenario alone:

  - pinv, dls, dls_adaptive: at random samples the planned rates satisfy the method's defining equation for the
    commanded twist x = (path twist) + K (tool error), K = CLIK_SHARE / dt: pinv J qd = x; dls
    qd = Ju^T (Ju Ju^T + lambda^2 I)^-1 xu with the recorded lambda (Ju = [Jp / L; Jr], xu = [xp / L; xr]);
    dls_adaptive the same with lambda from sigma_min of MuJoCo's Ju by the documented rule;
  - pinv's speed peaks break the wrist's limits, and the plan's verdict says so (velocity_limit, q4 and q6);
  - time_scaling: the tool on the line to 1e-9 m, every joint within its speed and acceleration limits by finite
    differences, and the slowdown the planned duration over the asked one; near the wrist singularity and at a
    corner, the rates within the acceleration limits and the joints' kinks reported (`acceleration_limit`);
  - mink: inside the joint ranges and speed limits;
  - a bad method or a field of another method is a one-line error naming the field (exit 2).
"""

from importlib.metadata import distribution

import mujoco
import numpy as np
import pytest
import yaml

from simbench.cli import main
from simbench.commands.pipeline import check_plan
from simbench.core.plant import compiled_scene
from simbench.core.resources import models_dir
from simbench.planners.path_methods import EPSILON, LAMBDA_MAX
from simbench.planners.resolved_rates import CLIK_SHARE, NULL_GAIN
from simbench.scenario import load_scenario

XML = models_dir() / "puma600" / "puma600.xml"
START = [181.8737, -117.777, -222.6356, 15.0872, 15.8376, -13.0006]  # deg: paper 002's wrist line's start
END = np.array([780.0, -149.0, -200.0])  # mm
SPEED = [60.0, 60.0, 60.0, 300.0, 300.0, 300.0]  # deg/s: the PUMA's drives (robots/puma600.py)
DURATION, DT = 2.0, 0.002


def _scenario(folder, method: str, **fields):
    """The generic PUMA along the wrist line with `method`, quintic over 2 s (deg, mm)."""
    doc = {"robot": {"model": str(XML), "tool": {"site": "tool"}, "speed_limits": SPEED},
           "planner": "cartesian_path", "units": {"angle": "deg", "length": "mm"},
           "task": {"start": START, "path": [{"line": {"end": END.tolist()}}], "method": method, **fields},
           "timing": {"law": "quintic", "duration": DURATION, "hold": 0.5}, "analysis": {"near_angle": 5}}
    path = folder / f"{method}.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


class Mujoco:
    """MuJoCo's own tool site, Jacobian and orientation of a model (default: the PUMA's MJCF) at joint values."""

    def __init__(self, joints, model=None, site="tool"):
        self.model = mujoco.MjModel.from_xml_path(str(XML)) if model is None else model
        self.data = mujoco.MjData(self.model)
        self.adr = [self.model.joint(name).qposadr[0] for name in joints]
        self.dofs = [self.model.joint(name).dofadr[0] for name in joints]
        self.site = self.model.site(site).id

    def pose(self, q):
        self.data.qpos[self.adr] = q
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)
        return self.data.site_xpos[self.site].copy(), self.data.site_xmat[self.site].reshape(3, 3).copy()

    def jacobian(self, q):
        self.pose(q)
        jacp, jacr = np.zeros((3, self.model.nv)), np.zeros((3, self.model.nv))
        mujoco.mj_jacSite(self.model, self.data, jacp, jacr, self.site)
        return np.vstack([jacp[:, self.dofs], jacr[:, self.dofs]])


def _commanded(mj, plan, k, start, end, r0, duration=DURATION):
    """The commanded twist [v; w] (SI) at sample k: the line's velocity under the quintic law plus K times the
    tool's error at the plan's q there (position, and 1/2 sum n x n_d of the held orientation)."""
    tau = plan.t[k] / duration
    s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    ds = (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / duration
    point, rotation = mj.pose(plan.q_ref[k])
    gain = CLIK_SHARE / DT
    ep = start + s * (end - start) - point
    eo = 0.5 * np.cross(rotation.T, r0.T).sum(axis=0)
    return np.concatenate([(end - start) * ds + gain * ep, gain * eo])


def _planned(tmp_path, method, **fields):
    sc = load_scenario(_scenario(tmp_path, method, **fields))
    robot = sc.robot_def
    plan = sc.planner_def.plan(sc, robot, DT)
    mj = Mujoco(robot.joints)
    start, r0 = mj.pose(np.deg2rad(START))
    return sc, robot, plan, mj, start, r0


def _samples(plan, rng, n=25):
    """Random samples inside the motion, and the five around the fastest joint rate (the wrist's spin)."""
    moving = np.flatnonzero((plan.t > 0) & (plan.t < DURATION))
    return np.concatenate([rng.choice(moving, n, replace=False), np.arange(-2, 3) + np.argmax(np.abs(plan.qd_ref))
                           // plan.qd_ref.shape[1]])


def test_pinv_rates_make_the_commanded_twist_and_break_the_wrist_speed_limits(tmp_path):
    sc, robot, plan, mj, start, r0 = _planned(tmp_path, "pinv", knot_step=0)
    for k in _samples(plan, np.random.default_rng(1)):
        x = _commanded(mj, plan, k, start, END / 1e3, r0)
        made = mj.jacobian(plan.q_ref[k]) @ plan.qd_ref[k]
        np.testing.assert_allclose(made, x, rtol=0, atol=1e-9 * (1 + abs(x).max()))
    _, verdict = check_plan(sc)
    fast = {v.detail["joint"]: v.detail["ratio"] for v in verdict.violations if v.kind == "velocity_limit"}
    assert verdict.status == "limits" and set(fast) == {robot.joints[3], robot.joints[5]}
    assert min(fast.values()) > 1.3  # measured: 1.42 (paper 002's analytic plan: 425 of 300 deg/s)
    assert plan.info["speed_share_max"] == pytest.approx(max(fast.values()), rel=1e-2)  # its plan at the sim's step


def test_dls_rates_are_damped_least_squares_with_the_recorded_lambda(tmp_path):
    sc, robot, plan, mj, start, r0 = _planned(tmp_path, "dls", damping=0.03)
    lam, scale = plan.series["plan_damping"], plan.series["plan_speed_scale"]
    assert np.all(lam == 0.03) and plan.info["damping"] == 0.03
    assert scale.min() < 1  # the wrist's rates were scaled down under its limits
    unit = np.array([1 / robot.reach] * 3 + [1.0] * 3)
    for k in _samples(plan, np.random.default_rng(2)):
        ju = unit[:, None] * mj.jacobian(plan.q_ref[k])
        xu = unit * _commanded(mj, plan, k, start, END / 1e3, r0)
        expected = ju.T @ np.linalg.solve(ju @ ju.T + lam[k] ** 2 * np.eye(6), xu)
        np.testing.assert_allclose(plan.qd_ref[k], scale[k] * expected, rtol=0, atol=1e-9 * (1 + abs(expected).max()))
    assert np.all(np.abs(plan.qd_ref) < np.deg2rad(SPEED))
    off = _line_distance(np.array([mj.pose(q)[0] for q in plan.q_ref]), start, END / 1e3)
    assert off.max() > 1e-3  # the damped wrist leaves the line (measured: 4.4 mm) and says so beyond the tolerance
    assert ("off_path" in [v.kind for v in plan.violations]) == (off.max() > sc.analysis.path_tolerance)


def test_dls_adaptive_damps_by_mujocos_sigma_min(tmp_path):
    sc, robot, plan, mj, start, r0 = _planned(tmp_path, "dls_adaptive", knot_step=0)
    unit = np.array([1 / robot.reach] * 3 + [1.0] * 3)
    unscaled = np.all(np.abs(plan.qd_ref) < (1 - 1e-6) * np.deg2rad(SPEED), axis=1)
    checked = damped = 0
    for k in _samples(plan, np.random.default_rng(3), n=60):
        if not unscaled[k]:
            continue
        ju = unit[:, None] * mj.jacobian(plan.q_ref[k])
        sigma = np.linalg.svd(ju, compute_uv=False)[-1]
        lam2 = LAMBDA_MAX**2 * (1 - (sigma / EPSILON) ** 2) if sigma < EPSILON else 0.0
        xu = unit * _commanded(mj, plan, k, start, END / 1e3, r0)
        expected = ju.T @ np.linalg.solve(ju @ ju.T + lam2 * np.eye(6), xu)
        np.testing.assert_allclose(plan.qd_ref[k], expected, rtol=0, atol=1e-9 * (1 + abs(expected).max()))
        checked, damped = checked + 1, damped + (lam2 > 0)
    assert checked > 30 and damped > 0
    assert "path_method" not in plan.info and set(plan.series) == {"tool_orientation_ref"}  # the default's report


PANDA = (distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data") / "robots"
         / "panda_description" / "urdf" / "panda.urdf")


@pytest.mark.parametrize("method", ["pinv", "dls"])
def test_a_redundant_arm_returns_to_its_start_posture_in_the_null_space(tmp_path, method):
    """Panda (7 joints, example-robot-data's URDF): J qd is the commanded twist (pinv) or the damped rates plus the
    null-space term (I - Ju+ Ju) K_N (q0 - q), Ju+ numpy's pseudo-inverse of MuJoCo's Ju."""
    start = [0.0, -45.0, 0.0, -135.0, 0.0, 90.0, 45.0]
    doc = {"robot": {"model": str(PANDA), "tool": {"body": "panda_link7", "offset": [0, 0, 107]},
                     "joints": [f"panda_joint{i}" for i in range(1, 8)]},
           "planner": "cartesian_path", "units": {"angle": "deg", "length": "mm"},
           "task": {"start": start, "path": [{"line": {"end": [300.0, 250.0, 500.0]}}], "method": method,
                    "knot_step": 0},
           "timing": {"law": "quintic", "duration": 3.0, "hold": 0.2}}
    path = tmp_path / "panda.yaml"
    path.write_text(yaml.safe_dump(doc))
    sc = load_scenario(path)
    robot = sc.robot_def
    plan = sc.planner_def.plan(sc, robot, DT)
    mj = Mujoco(robot.joints, compiled_scene(str(robot.scene)), robot.tool_site)
    q0 = np.deg2rad(start)
    tool0, r0 = mj.pose(q0)
    assert plan.info["range_held_from"] is None
    unit = np.array([1 / robot.reach] * 3 + [1.0] * 3)
    lam = plan.series["plan_damping"]
    moving = np.flatnonzero((plan.t > 0) & (plan.t < 3.0))
    for k in np.random.default_rng(5).choice(moving, 20, replace=False):
        ju = unit[:, None] * mj.jacobian(plan.q_ref[k])
        xu = unit * _commanded(mj, plan, k, tool0, np.array([0.3, 0.25, 0.5]), r0, duration=3.0)
        null = (np.eye(7) - np.linalg.pinv(ju) @ ju) @ (NULL_GAIN * (q0 - plan.q_ref[k]))
        task = ju.T @ np.linalg.solve(ju @ ju.T + lam[k] ** 2 * np.eye(6), xu)
        expected = plan.series["plan_speed_scale"][k] * (task + null)
        np.testing.assert_allclose(plan.qd_ref[k], expected, rtol=0, atol=1e-9 * (1 + abs(expected).max()))
        if method == "pinv":
            np.testing.assert_allclose(ju @ plan.qd_ref[k], xu, rtol=0, atol=1e-9 * (1 + abs(xu).max()))
    assert np.abs(plan.q_ref[-1] - q0).max() > 0.01  # the joints moved (the null space does not hold them)


def _line_distance(points, start, end):
    d = (end - start) / np.linalg.norm(end - start)
    rel = points - start
    return np.linalg.norm(rel - np.outer(rel @ d, d), axis=1)


def test_time_scaling_keeps_the_line_and_every_joint_within_its_limits(tmp_path):
    accel = [200.0, 200.0, 200.0, 2000.0, 2000.0, 2000.0]  # deg/s^2
    sc, robot, plan, mj, start, r0 = _planned(tmp_path, "time_scaling", acceleration_limits=accel)
    end = END / 1e3
    tool = np.array([mj.pose(q)[0] for q in plan.q_ref])
    turned = max(np.linalg.norm(mj.pose(q)[1] - r0) for q in plan.q_ref)
    assert _line_distance(tool, start, end).max() < 1e-9 and turned < 1e-9
    along = (tool - start) @ (end - start) / np.linalg.norm(end - start) ** 2
    assert along.min() > -1e-9 and along.max() < 1 + 1e-9 and np.linalg.norm(tool[-1] - end) < 1e-9
    assert np.all(np.diff(along) > -1e-12)  # forward along the line, never back
    speed = np.abs(np.diff(plan.q_ref, axis=0)) / DT
    acceleration = np.abs(np.diff(plan.q_ref, 2, axis=0)) / DT**2
    assert np.all(speed <= np.deg2rad(SPEED)) and np.all(acceleration <= np.deg2rad(accel))
    assert speed[:, 3].max() > 0.9 * np.deg2rad(SPEED[3])  # the wrist at its limit: the slowdown is that
    moving = np.flatnonzero(along < 1 - 1e-12)
    duration = plan.t[moving[-1] + 1]
    assert plan.info["slowdown"] == pytest.approx(duration / DURATION, abs=DT / DURATION)
    assert 1.0 < plan.info["slowdown"] < 1.5  # measured: 1.024
    _, verdict = check_plan(sc)
    assert verdict.status == "ok"


def _accelerations_reported(sc):
    """The plan and verdict of a time_scaling scenario, checked against finite differences at the plan's samples:
    its rates' first differences within each joint's acceleration limit (the 98 % margin's slack allowed), and an
    `acceleration_limit` violation for exactly the joints whose planned q's second differences pass it, with their
    worst ratio and first time."""
    plan, verdict = check_plan(sc)
    dt = plan.t[1] - plan.t[0]
    limit = np.array(plan.info["acceleration_limits"])
    assert np.allclose(limit, sc.robot_def.qd_max / 0.1)  # the default: each speed limit reached in 0.1 s
    assert np.all(np.abs(np.diff(plan.qd_ref, axis=0)) / dt <= limit)
    assert np.all(np.abs(plan.qd_ref) <= sc.robot_def.qd_max)
    bends = np.abs(np.diff(plan.q_ref, 2, axis=0)) / dt**2 / limit  # bends[k]: at sample k + 1
    found = {v.detail["joint"]: v for v in verdict.violations if v.kind == "acceleration_limit"}
    assert set(found) == {sc.robot_def.joints[j] for j in np.flatnonzero(bends.max(axis=0) > 1)}
    for name, v in found.items():
        j = sc.robot_def.joints.index(name)
        assert v.detail["ratio"] == pytest.approx(bends[:, j].max(), rel=1e-9)
        assert v.t == pytest.approx(plan.t[np.argmax(bends[:, j] > 1) + 1])
    assert verdict.status == ("limits" if found else "ok")
    return plan, found


def test_time_scaling_keeps_the_rates_within_the_acceleration_limits_and_reports_the_joints_kinks(tmp_path):
    """An arc passing near the wrist singularity (the PUMA bench's task 9, seed 0), where q(s) bends sharply
    between TOPP-RA's gridpoints: the plan's rates keep every acceleration limit (before the timing was stretched
    for them, 1.38 times q4's and the run ended ok), and the exact joints' kink at the wrist is reported."""
    speed = [4.363323129985824] * 3 + [5.235987755982989] * 3  # rad/s
    arc = {"center": [-0.060928780945951735, -1.0272031675513507, 0.0710733120232599], "radius": 0.3799539282227059,
           "normal": [-0.9951438633800633, 0.09504657830738787, -0.02558982471724994],
           "ref": [0.07216283302234654, 0.5276761952941735, -0.846374833303811],
           "start": -0.25579034058793965, "end": 0.22563550878706204}
    doc = {"robot": {"model": str(XML), "tool": {"site": "tool"}, "speed_limits": speed},
           "planner": "cartesian_path",
           "task": {"start": [1.7382502833571756, -2.3991163316083006, -3.1558577234945657, 0.308624098373298,
                              0.06281929385746834, 1.2217339722962344],
                    "path": [{"arc": arc}], "method": "time_scaling"},
           "timing": {"law": "quintic", "duration": 1.219464, "hold": 0.3}}
    path = tmp_path / "arc.yaml"
    path.write_text(yaml.safe_dump(doc))
    plan, found = _accelerations_reported(load_scenario(path))
    assert {"q4", "q6"} <= set(found)  # measured: 3.5 times, within a sample of the wrist's flip


def test_time_scaling_at_a_corner_keeps_the_rates_within_the_acceleration_limits_and_reports_the_kink(tmp_path):
    """Two lines meeting at a right angle on the generic PUMA: the exact joints turn the corner within a sample,
    which no uniform stretch of the timing smooths; the plan's rates keep the acceleration limits (before: 2.1
    times q2's, and the run ended ok), and the joints that kink are reported."""
    mid = [600.0, -149.0, -200.0]
    path = _scenario(tmp_path, "time_scaling")
    doc = yaml.safe_load(path.read_text())
    doc["task"]["path"] = [{"line": {"end": mid}}, {"line": {"start": mid, "end": [600.0, -149.0, -100.0]}}]
    doc["timing"]["duration"] = 1.0
    path.write_text(yaml.safe_dump(doc))
    plan, found = _accelerations_reported(load_scenario(path))
    assert "q2" in found  # measured: 3.2 times at the corner


def test_time_scaling_keeps_the_asked_law_where_no_limit_binds(tmp_path):
    path = _scenario(tmp_path, "time_scaling")
    path.write_text(path.read_text().replace("780.0", "500.0").replace("duration: 2.0", "duration: 4.0"))
    sc = load_scenario(path)
    plan = sc.planner_def.plan(sc, sc.robot_def, DT)
    assert plan.info["slowdown"] == pytest.approx(1.0, abs=0.01)
    tau = np.clip(plan.t / 4.0, 0, 1)
    law = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    assert np.abs(plan.s - law).max() < 0.01


def test_mink_keeps_the_ranges_and_speed_limits(tmp_path):
    sc, robot, plan, mj, start, r0 = _planned(tmp_path, "mink")
    assert np.all(np.abs(plan.qd_ref) <= np.deg2rad(SPEED) * (1 + 1e-12))
    assert np.all((plan.q_ref >= robot.lower) & (plan.q_ref <= robot.upper))
    tool = np.array([mj.pose(q)[0] for q in plan.q_ref])
    off = _line_distance(tool, start, END / 1e3)
    assert off.max() > 1e-3  # measured: 4.9 mm, where the wrist is held at its speed limit
    assert ("off_path" in [v.kind for v in plan.violations]) == (off.max() > sc.analysis.path_tolerance)
    assert np.linalg.norm(tool[-1] - END / 1e3) < 1e-3


@pytest.mark.parametrize(("method", "fields", "where"), [
    ("newton", {}, "task.method"),
    ("pinv", {"damping": 0.1}, "task.damping"),
    ("dls", {"acceleration_limits": [1, 1, 1, 1, 1, 1]}, "task.acceleration_limits"),
    ("time_scaling", {"acceleration_limits": [1, 1, 1]}, "task.acceleration_limits"),
])
def test_a_bad_method_or_a_field_of_another_is_a_one_line_error(tmp_path, capsys, method, fields, where):
    path = _scenario(tmp_path, method, **fields)
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and where in err and str(path) in err


def test_time_scaling_refuses_a_motion_stretched_past_a_hundred_times(tmp_path, capsys):
    path = _scenario(tmp_path, "time_scaling", acceleration_limits=[1e-3] * 6)
    assert main(["validate", str(path)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "100 times" in err


def test_time_scaling_never_asks_past_a_speed_limit_between_toppras_gridpoints():
    """Lines and arcs of the planar 3R through, near and far from its stretched elbow (the bench's tasks): each is
    planned within every speed limit (|qd_ref| <= qd_max at every sample) or refused as too slow. Before the
    timing was probed between TOPP-RA's gridpoints, the line ending at full stretch was planned at more than twice
    q2's limit."""
    import json

    from simbench.commands.bench.methods import METHODS
    from simbench.commands.bench.robots import SHIPPED
    from simbench.commands.bench.tasks import draw
    from simbench.core.errors import RunError
    from simbench.scenario import parse_scenario

    robot = SHIPPED["planar3r"]()
    planned, refused = 0, 0
    for task in draw(robot, 6, 0):
        document = json.loads(json.dumps(METHODS["time_scaling"].document(task, robot), default=float))
        scenario = parse_scenario(document, "planar3r time_scaling")
        arm = scenario.robot_def
        try:
            plan = scenario.planner_def.plan(scenario, arm, 0.001)
        except RunError as err:
            assert "more than 100 times the asked" in str(err)
            refused += 1
            continue
        assert np.all(np.abs(plan.qd_ref) <= arm.qd_max), task.id
        planned += 1
    assert planned >= 4
