"""examples/planar3r, the outside package that adds a robot and a planner through simbench.api, checked against
independent truths: MuJoCo's own tool site, finite differences, the determinant, the physics stepping clean, and
the line the planner promises; and the same arm derived from its MJCF alone. Needs `pip install -e
examples/planar3r`."""

import importlib.metadata
import subprocess
import sys
from functools import cache
from pathlib import Path
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest

simbench_planar3r = pytest.importorskip("simbench_planar3r", reason="pip install -e examples/planar3r")

from simbench_planar3r.planner import PLANNER  # noqa: E402
from simbench_planar3r.robot import L1, L2, L3, ROBOT  # noqa: E402

from simbench.api import REVOLUTE, Tolerance  # noqa: E402
from simbench.scenario import Thresholds, Timing, load_scenario  # noqa: E402
from simbench.scenario.schema import Units  # noqa: E402
from tests.conftest import segment_distance  # noqa: E402

_DT = 0.002


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_path(str(ROBOT.scene))


def _random_q(rng: np.random.Generator, n: int) -> np.ndarray:
    return rng.uniform(ROBOT.lower, ROBOT.upper, (n, 3))


def test_description_matches_the_mjcf(model):
    assert ROBOT.kinds == (REVOLUTE,) * 3
    assert [model.actuator(j).name for j in ROBOT.joints] == list(ROBOT.joints)
    for j, name in enumerate(ROBOT.joints):
        assert model.joint(name).range.tolist() == pytest.approx([ROBOT.lower[j], ROBOT.upper[j]], abs=1e-15)
        assert model.actuator(name).ctrlrange.tolist() == pytest.approx([ROBOT.lower[j], ROBOT.upper[j]], abs=1e-15)
        assert model.joint(name).type[0] == mujoco.mjtJoint.mjJNT_HINGE
    assert model.site(ROBOT.tool_site).id >= 0 and model.sensor(ROBOT.tool_sensor).id >= 0
    assert model.key("home").id >= 0 and model.ncam >= 2
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST


def test_entry_points_name_the_robot_and_the_planner():
    found = {group: ep for group in ("simbench.robots", "simbench.planners")
             for ep in importlib.metadata.entry_points(group=group) if ep.dist.name == "simbench-planar3r"}
    assert found["simbench.robots"].name == ROBOT.name and found["simbench.robots"].load() is ROBOT
    assert found["simbench.planners"].name == PLANNER.name and found["simbench.planners"].load() is PLANNER
    assert PLANNER.refuses(ROBOT) is None


def test_fk_matches_mujoco_tool_site(model):
    data = mujoco.MjData(model)
    q = _random_q(np.random.default_rng(0), 50)
    ours = ROBOT.fk(q)
    for k in range(len(q)):
        data.qpos[:] = q[k]
        mujoco.mj_forward(model, data)
        np.testing.assert_allclose(ours[k], data.site(ROBOT.tool_site).xpos, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ours[k], data.sensor(ROBOT.tool_sensor).data, rtol=0, atol=1e-9)
        xmat = data.site(ROBOT.tool_site).xmat.reshape(3, 3)  # the tool's heading phi: link 3's x axis
        phi = ROBOT.pose(q[k])[0, 2]
        np.testing.assert_allclose(xmat[:2, 0], [np.cos(phi), np.sin(phi)], rtol=0, atol=1e-9)


def test_jacobian_matches_finite_differences_of_pose():
    q = _random_q(np.random.default_rng(1), 50)
    step = 1e-6
    numeric = np.stack([(ROBOT.pose(q + step * e) - ROBOT.pose(q - step * e)) / (2 * step) for e in np.eye(3)],
                       axis=-1)
    np.testing.assert_allclose(ROBOT.jacobian(q), numeric, rtol=0, atol=1e-8)


def test_det_j_is_the_determinant_and_vanishes_exactly_on_the_singular_set():
    rng = np.random.default_rng(2)
    q = _random_q(rng, 200)
    det_j = ROBOT.measures(SimpleNamespace(q=q))["det_J"]
    np.testing.assert_allclose(det_j, np.linalg.det(ROBOT.jacobian(q)), rtol=0, atol=1e-12)
    np.testing.assert_allclose(det_j, L1 * L2 * np.sin(q[:, 1]), rtol=0, atol=1e-15)
    # On the set (q2 = 0, +-pi; any q1, q3) the Jacobian loses rank; off it, |det J| = L1 L2 |sin q2| > 0.
    for q2 in (0.0, np.pi, -np.pi):
        on = q.copy()
        on[:, 1] = q2
        assert np.abs(np.linalg.det(ROBOT.jacobian(on))).max() < 1e-15
        assert (np.linalg.matrix_rank(ROBOT.jacobian(on)) == 2).all()
        sets = {s.name: s for s in ROBOT.singular_sets(SimpleNamespace(q=on), Tolerance(0.01, 0.001))}
        assert sets["stretched" if q2 == 0 else "folded"].distance.max() < 1e-12
    tol = Tolerance(np.deg2rad(2.0), 0.002)
    sets = ROBOT.singular_sets(SimpleNamespace(q=q), tol)
    assert [s.family for s in sets] == ["elbow stretched", "elbow folded"]
    nearest = np.minimum(sets[0].gaps["q2"], sets[1].gaps["q2"])
    np.testing.assert_allclose(np.abs(det_j), L1 * L2 * np.sin(nearest), rtol=0, atol=1e-15)
    np.testing.assert_allclose(sets[0].distance, np.abs(q[:, 1]) / tol.angle)


def test_scene_steps_under_random_controls_without_warnings(model):
    rng = np.random.default_rng(3)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    lo, hi = model.actuator_ctrlrange.T
    for _ in range(2000):
        data.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_step(model, data)
        assert np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()
    assert [w.number for w in data.warning] == [0] * len(data.warning), [
        mujoco.mjtWarning(i).name for i, w in enumerate(data.warning) if w.number]


# --- the planner -------------------------------------------------------------------------------------------------

def _wrap(angle):
    return np.angle(np.exp(1j * np.asarray(angle)))


def _ik(x: np.ndarray, elbow: float) -> np.ndarray:
    """Closed-form inverse kinematics of poses (N, 3) on one elbow branch (sign of q2): the test's own, to pick
    lines the arm can follow inside its ranges and away from the singular set."""
    wrist = x[:, :2] - L3 * np.column_stack([np.cos(x[:, 2]), np.sin(x[:, 2])])
    c2 = (np.sum(wrist**2, axis=1) - L1**2 - L2**2) / (2 * L1 * L2)
    q2 = elbow * np.arccos(np.clip(c2, -1.0, 1.0))
    q1 = np.unwrap(np.arctan2(wrist[:, 1], wrist[:, 0]) - np.arctan2(L2 * np.sin(q2), L1 + L2 * np.cos(q2)))
    q = np.column_stack([q1, q2, x[:, 2] - q1 - q2])
    return q, c2


@cache
def _random_lines(seed: int, count: int):
    """(start q, goal point, goal phi) of lines the exact inverse kinematics follows with |q2| in [25, 155] deg
    and every joint 5 deg inside its range."""
    rng = np.random.default_rng(seed)
    margin, away = np.deg2rad(5.0), np.deg2rad(25.0)
    s = np.linspace(0.0, 1.0, 401)
    lines = []
    while len(lines) < count:
        q0, q1 = _random_q(rng, 2)
        x0, x1 = ROBOT.pose(np.array([q0, q1]))
        x1[2] = x0[2] + _wrap(x1[2] - x0[2])  # the planner turns the shorter way
        if np.linalg.norm(x1[:2] - x0[:2]) < 0.05:
            continue
        q, c2 = _ik(x0 + s[:, None] * (x1 - x0), np.sign(q0[1]))
        if np.abs(c2).max() > np.cos(away) or not np.allclose(q[0], q0):
            continue
        if ((q < ROBOT.lower + margin) | (q > ROBOT.upper - margin)).any():
            continue
        lines.append((q0, x1[:2], float(x1[2])))
    return lines


def _scenario(start, goal, goal_phi, **task):
    """What the planner reads of a scenario: the task validated by its own schema (SI units, the start checked
    against the ranges), the timing and the analysis tolerances. Built directly while scenario.parse_scenario
    does not yet read simbench.api's registry; once it does, this is parse_scenario(raw, "test") with raw =
    {"robot": "planar3r", "planner": "dls_line", "task": ..., "timing": ...}."""
    raw = {"start": [float(v) for v in start], "goal": [float(v) for v in goal], "goal_phi": goal_phi, **task}
    return SimpleNamespace(task=PLANNER.task.model_validate(raw, context={"robot": ROBOT, "units": Units()}),
                           timing=Timing(law="quintic", duration=3.0, hold=0.5), analysis=Thresholds(), units=Units())


@pytest.mark.parametrize("index", range(24))
def test_planner_follows_lines_away_from_the_singular_set(index):
    start, goal, goal_phi = _random_lines(seed=4, count=24)[index]
    scenario = _scenario(start, goal, goal_phi)
    traj = PLANNER.plan(scenario, ROBOT, _DT)
    tool = ROBOT.fk(traj.q_ref)
    a = ROBOT.fk(start)[0, :2]
    assert segment_distance(tool[:, :2], a, goal).max() < 1e-3
    assert np.linalg.norm(tool[-1, :2] - goal) < 1e-4
    assert abs(_wrap(ROBOT.pose(traj.q_ref[-1])[0, 2] - goal_phi)) < 1e-4
    assert ((traj.q_ref >= ROBOT.lower) & (traj.q_ref <= ROBOT.upper)).all()
    np.testing.assert_allclose(traj.tool_ref[0, :2], a, atol=1e-12)
    np.testing.assert_allclose(traj.tool_ref[-1, :2], goal, atol=1e-12)
    np.testing.assert_allclose(np.diff(traj.q_ref, axis=0), _DT * traj.qd_ref[:-1], atol=1e-12)  # Euler steps
    assert traj.violations == () and traj.warnings == ()


def test_planner_check_refuses_a_goal_out_of_reach_and_a_zero_length_line():
    far = PLANNER.check(_scenario([0.0, 1.0, 1.0], [0.95, 0.0], 0.0), ROBOT)  # wrist 0.75 m out, beyond L1 + L2
    near = PLANNER.check(_scenario([0.0, 1.0, 1.0], [0.2, 0.0], 0.0), ROBOT)  # wrist at 0: nearer than q2 allows
    for problem in (far, near):
        assert problem is not None and problem[0] == "task.goal" and "out of reach" in problem[1]
    start = np.array([0.3, 1.0, -0.5])
    x = ROBOT.pose(start)[0]
    assert PLANNER.check(_scenario(start, x[:2], float(x[2])), ROBOT) == ("task.goal", "equals the start's pose: "
                                                                          "a zero-length line")
    assert PLANNER.check(_scenario(start, [0.5, 0.1], 0.3), ROBOT) is None


def test_planner_reports_the_deviation_near_the_stretched_elbow():
    # A line inside the reach whose exact solution comes within 5 deg of q2 = 0: strong damping cuts the corner.
    start = np.deg2rad([-85.0, 40.0, 70.0])
    near = _scenario(start, [0.1, -0.46], float(np.deg2rad(105.0)), damping=0.1)
    traj = PLANNER.plan(near, ROBOT, _DT)
    deviation = segment_distance(ROBOT.fk(traj.q_ref)[:, :2], ROBOT.fk(start)[0, :2], np.array([0.1, -0.46]))
    assert deviation.max() > near.analysis.path_tolerance
    assert traj.info["max_line_deviation"] == pytest.approx(deviation.max(), abs=1e-9)
    assert [v["kind"] for v in traj.violations] == ["off_path"]
    assert traj.warnings and "stretched" in traj.warnings[0]


@pytest.mark.parametrize("name", ["line", "near_stretch"])
def test_packaged_scenarios_load(name):
    from simbench.core.errors import ScenarioError

    path = ROBOT.scene.parent.parent / "scenarios" / f"{name}.yaml"
    try:
        scenario = load_scenario(path)
    except ScenarioError as err:
        if "unknown robot 'planar3r'" in str(err):
            pytest.skip("scenario.py does not read simbench.api's registry (entry points) yet")
        raise
    assert (scenario.robot, scenario.planner) == ("planar3r", "dls_line")
    traj = PLANNER.plan(scenario, ROBOT, _DT)
    assert [v["kind"] for v in traj.violations] == (["off_path"] if name == "near_stretch" else [])


def test_the_arm_named_by_its_mjcf_alone_runs_ok_with_the_coded_robot_s_joints_and_ranges(tmp_path):
    scenario = Path(__file__).parents[2] / "examples" / "planar3r" / "scenarios_no_code" / "joint_move.yaml"
    run = subprocess.run([sys.executable, "-P", "-m", "simbench", "run", str(scenario), "--out", str(tmp_path / "out"),
                          "--no-video"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0 and "status: ok" in run.stdout, run.stderr
    derived = load_scenario(scenario).robot_def
    assert derived.joints == ROBOT.joints and derived.kinds == ROBOT.kinds
    assert derived.lower == pytest.approx(ROBOT.lower, abs=1e-12)
    assert derived.upper == pytest.approx(ROBOT.upper, abs=1e-12)
    assert derived.qd_max == pytest.approx(ROBOT.qd_max) and derived.tool_site == ROBOT.tool_site
