"""cartesian_path beyond a held line (issue 35): an arc followed on its true circle, a goal orientation reached by
slerp, and a 7-joint arm keeping its start posture in the null space, each checked against a truth computed apart
(the circle's geometry, scipy's slerp, numpy's SVD of MuJoCo's Jacobian), with the tool placed by MuJoCo itself."""

import json
import os
from importlib.metadata import distribution
from xml.etree import ElementTree

import dm_control
import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

import simbench.planners.cartesian_path as cartesian_path
import simbench.planners.resolved_rates as resolved_rates
from simbench.cli import main
from simbench.commands.pipeline import check_plan
from simbench.scenario import load_scenario

JACO = os.path.join(os.path.dirname(dm_control.__file__), "third_party", "kinova", "jaco_arm.xml")
START = [24.4, 133.3, 286.9, -28.9, 70.8, 177.6]  # deg
TOOL0 = np.array([478.22158345, -163.10697508, 307.57903728])  # mm: the wristsite at START (MuJoCo's)
PANDA = (distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data")
         / "robots" / "panda_description" / "urdf" / "panda.urdf")


def _jaco(folder, path: str, orientation: str = "hold", duration: float = 3.0, name: str = "shape"):
    """A cartesian_path scenario on the Jaco (degrees, millimetres) from START along `path` (its YAML lines)."""
    file = folder / f"{name}.yaml"
    file.write_text(f"""robot:
  model: {JACO}
  tool: {{site: wristsite}}
  speed_limits: [36, 36, 36, 48, 48, 48]
planner: cartesian_path
units: {{angle: deg, length: mm}}
task:
  start: {START}
  path:
{path}  orientation: {orientation}
timing: {{duration: {duration}, hold: 0.3}}
""")
    return file


def _site(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The Jaco's wristsite points (N, 3) and orientations (N, 3, 3) at joint values q (N, 6), by mj_kinematics."""
    model = mujoco.MjModel.from_xml_path(JACO)
    data = mujoco.MjData(model)
    points, rotations = [], []
    for row in q:
        data.qpos[:] = row
        mujoco.mj_kinematics(model, data)
        points.append(data.site("wristsite").xpos.copy())
        rotations.append(data.site("wristsite").xmat.reshape(3, 3).copy())
    return np.array(points), np.array(rotations)


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The angles (rad) of the rotations between rotation matrices a and b (N, 3, 3)."""
    return (Rotation.from_matrix(a) * Rotation.from_matrix(b).inv()).magnitude()


def test_an_arc_is_followed_on_its_true_circle(tmp_path, capsys):
    """A 120 deg arc of radius 60 mm about a tilted normal, from the tool's point: the plan's tool (MuJoCo's
    kinematics) and the run's recorded tool lie on the circle, and sweep the arc's angles from start to end."""
    radius, normal = 60.0, np.array([0.0, 0.3, 1.0]) / np.linalg.norm([0.0, 0.3, 1.0])
    ref = np.cross(normal, np.cross([1.0, 0.0, 0.0], normal))  # x projected onto the plane: the arc's ref
    ref /= np.linalg.norm(ref)
    center = TOOL0 - radius * ref  # angle 0 at the tool's point
    path = (f"    - arc: {{center: {center.tolist()}, radius: {radius}, normal: {normal.tolist()}, start: 0, end: 120, "
            f"ref: {ref.tolist()}}}\n")
    scenario = _jaco(tmp_path, path)
    assert main(["run", str(scenario), "--out", str(tmp_path / "out"), "--no-video", "--quiet"]) == 0
    series = np.load(tmp_path / "out" / "timeseries.npz")
    c, n, r = center / 1e3, normal, radius / 1e3
    e2 = np.cross(n, ref)

    def off_circle(points):
        d = points - c
        out = d @ n
        return np.hypot(out, np.linalg.norm(d - out[:, None] * n, axis=1) - r), np.arctan2(d @ e2, d @ ref)

    planned, theta = off_circle(_site(series["q_ref"])[0])
    assert planned.max() < 1e-5  # measured: 3.8e-7 m
    assert np.rad2deg(theta[0]) == pytest.approx(0.0, abs=1e-3)
    assert np.rad2deg(theta[-1]) == pytest.approx(120.0, abs=1e-2)
    assert np.diff(np.unwrap(theta)).min() > -1e-6  # one way round; measured: -3e-8 rad
    run, _ = off_circle(series["tool"])
    assert run.max() < 0.5e-3  # measured: 0.14 mm


def test_a_goal_orientation_is_reached_by_slerp(tmp_path):
    """A 100 mm line while the tool turns 40 deg about a tilted axis: the recorded tool (MuJoCo's kinematics at the
    run's q) ends at the goal orientation and, at every sample, is scipy's slerp at the recorded path parameter."""
    r0 = _site(np.deg2rad([START]))[1][0]
    goal = Rotation.from_rotvec(np.deg2rad(40.0) * np.array([1.0, -1.0, 0.5]) / 1.5) * Rotation.from_matrix(r0)
    x, y, z, w = goal.as_quat().tolist()
    end = TOOL0 + [0.0, 100.0, 0.0]
    scenario = _jaco(tmp_path, f"    - line: {{end: {end.tolist()}}}\n",
                     orientation=f"{{convention: quat, value: {[w, x, y, z]}}}")
    assert main(["run", str(scenario), "--out", str(tmp_path / "out"), "--no-video", "--quiet"]) == 0
    assert json.loads((tmp_path / "out" / "report.json").read_text())["status"] == "ok"
    series = np.load(tmp_path / "out" / "timeseries.npz")
    slerp = Slerp([0.0, 1.0], Rotation.from_matrix([r0, goal.as_matrix()]))
    truth = slerp(series["s"]).as_matrix()
    planned, recorded = _site(series["q_ref"])[1], _site(series["q"])[1]
    assert _angle(planned, truth).max() < 1e-5  # rad; measured: 1.8e-6
    mid = int(np.argmin(np.abs(series["s"] - 0.5)))
    assert abs(series["s"][mid] - 0.5) < 1e-2
    assert np.rad2deg(_angle(recorded[mid:mid + 1], truth[mid:mid + 1])[0]) < 0.2  # measured: 0.015 deg
    assert np.rad2deg(_angle(recorded[-1:], goal.as_matrix()[None])[0]) < 0.05  # measured: 0.006 deg
    assert np.rad2deg(_angle(truth[-1:], goal.as_matrix()[None])[0]) < 1e-9


def test_a_seven_joint_arm_keeps_its_start_posture_in_the_null_space(tmp_path, monkeypatch):
    """The Panda (example-robot-data's URDF, 7 joints) round a triangle of lines back to its start: its joints
    move little in the null space of MuJoCo's Jacobian (numpy's SVD), and it ends in its start posture, where the
    pseudo-inverse alone (no null-space term) ends away from it."""
    file = tmp_path / "panda.yaml"
    a, b, c = [306.890567, 0.0, 486.882052], [306.890567, 150.0, 386.882052], [406.890567, 150.0, 486.882052]
    file.write_text(f"""robot:
  model: {PANDA}
  tool: {{body: panda_hand, offset: [0, 0, 103.4]}}
planner: cartesian_path
units: {{angle: deg, length: mm}}
task:
  start: [0, -45, 0, -135, 0, 90, 45]
  path:
    - line: {{end: {b}}}
    - line: {{start: {b}, end: {c}}}
    - line: {{start: {c}, end: {a}}}
timing: {{duration: 4.0, hold: 0.3}}
""")
    scenario = load_scenario(file)
    robot = scenario.robot_def
    assert robot.dof == 7
    q0 = np.array(scenario.task.start)
    np.testing.assert_allclose(robot.fk(q0[None])[0], np.array(a) / 1e3, atol=1e-9)
    plan = cartesian_path.PLANNER.plan(scenario, robot, 0.002)
    assert plan.violations == () and plan.info["plan_path_deviation_max"] < 1e-3  # measured: 0.43 mm at corners
    null = np.array([np.linalg.svd(robot.jacobian(q[None])[0])[2][-1] @ (q - q0) for q in plan.q_ref[::10]])
    moved = np.abs(plan.q_ref - q0).max()
    assert np.abs(null).max() < 0.15 * moved  # measured: 0.041 of 0.378 rad
    assert np.abs(plan.q_ref[-1] - q0).max() < 2e-3  # measured: 1.2e-3 rad
    monkeypatch.setattr(resolved_rates, "NULL_GAIN", 0.0)
    drifted = cartesian_path.PLANNER.plan(scenario, robot, 0.002).q_ref[-1]
    assert np.abs(drifted - q0).max() > 1e-2  # measured: 0.024 rad


def test_an_arc_that_does_not_start_at_the_tool_is_bad_input(tmp_path, capsys):
    center = TOOL0 - [50.0, 0.0, 0.0]
    path = f"    - arc: {{center: {center.tolist()}, radius: 40, normal: [0, 0, 1], start: 0, end: 90}}\n"
    scenario = _jaco(tmp_path, path)
    assert main(["validate", str(scenario)]) == 2
    err = capsys.readouterr().err.strip()
    assert "task.path[0].arc" in err and "starts 10.000 mm from the tool's point" in err


def test_the_plans_orientation_error_past_90_deg_is_its_angle(tmp_path):
    """A planar 3R arm asked to turn its tool 150 deg about an axis in its plane, which it cannot: the plan's
    `plan_orientation_error_max` is the largest angle between scipy's slerp and the tool's orientation at the
    plan's joints (MuJoCo's), 150 deg at the end, not the arcsine of its sine (30 deg)."""
    planar3r = pytest.importorskip("simbench_planar3r", reason="pip install -e examples/planar3r")
    scene = os.path.join(os.path.dirname(planar3r.__file__), "models", "scene.xml")
    model = mujoco.MjModel.from_xml_path(scene)
    data = mujoco.MjData(model)
    start = np.deg2rad([0.0, 60.0, 60.0])

    def rotations(q: np.ndarray) -> np.ndarray:
        out = []
        for row in q:
            data.qpos[:] = row
            mujoco.mj_kinematics(model, data)
            out.append(data.site("tool").xmat.reshape(3, 3).copy())
        return np.array(out)

    r0 = rotations(start[None])[0]
    goal = Rotation.from_rotvec(np.deg2rad(150.0) * np.array([1.0, 0.0, 0.0])) * Rotation.from_matrix(r0)
    x, y, z, w = goal.as_quat().tolist()
    data.qpos[:] = start
    mujoco.mj_kinematics(model, data)
    end = (data.site("tool").xpos + [0.0, 0.05, 0.0]) * 1e3
    file = tmp_path / "turn.yaml"
    file.write_text(f"""robot: {{model: {scene}, tool: {{site: tool}}, speed_limits: [180, 360, 360]}}
planner: cartesian_path
units: {{angle: deg, length: mm}}
task:
  start: {np.rad2deg(start).tolist()}
  path:
    - line: {{end: {end.tolist()}}}
  orientation: {{convention: quat, value: {[w, x, y, z]}}}
timing: {{duration: 2.0, hold: 0.3}}
""")
    plan = cartesian_path.PLANNER.plan(load_scenario(file), load_scenario(file).robot_def, 0.002)
    truth = Slerp([0.0, 1.0], Rotation.from_matrix([r0, goal.as_matrix()]))(np.clip(plan.s, 0.0, 1.0))
    angles = _angle(truth.as_matrix(), rotations(plan.q_ref))
    assert np.rad2deg(angles.max()) == pytest.approx(150.0, abs=0.01)
    assert plan.info["plan_orientation_error_max"] == pytest.approx(angles.max(), abs=1e-9)


def test_time_scaling_keeps_a_joint_held_at_its_limit_inside_its_range(tmp_path):
    """The Panda turning its hand 60 deg about its axis along a 50 mm line from a start with joint 7 near its upper
    limit: pinv's path holds joint 7 there and the others keep the tool on the path; time_scaling's plan stays
    inside every range the URDF states (the cubic spline through that path overshot joint 7's by 2.4e-5 rad, and
    the plan's verdict named a joint_limit 0.00 deg beyond it), and its verdict names none."""
    limits = {j.get("name"): (float(j.find("limit").get("lower")), float(j.find("limit").get("upper")))
              for j in ElementTree.parse(PANDA).getroot().findall("joint") if j.get("type") == "revolute"}
    start = [0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 2.6]  # rad
    file = tmp_path / "turn.yaml"
    file.write_text(f"robot: {{model: {PANDA}, tool: {{body: panda_hand_tcp}}}}\nplanner: cartesian_path\n"
                    f"task: {{start: {start}, path: [{{line: {{end: [0.0, 0.0, 0.0]}}}}]}}\n"
                    "timing: {duration: 3.0}\n")
    robot = load_scenario(file).robot_def
    tool0, r0 = robot.fk(np.array([start]))[0], robot.tool_rotation(np.array([start]))[0]
    x, y, z, w = (Rotation.from_matrix(r0) * Rotation.from_rotvec([0.0, 0.0, np.deg2rad(60.0)])).as_quat().tolist()
    file.write_text(file.read_text().replace(
        "path: [{line: {end: [0.0, 0.0, 0.0]}}]",
        f"path: [{{line: {{end: {(tool0 + [0.05, 0.0, 0.0]).tolist()}}}}}], method: time_scaling, "
        f"orientation: {{convention: quat, value: {[w, x, y, z]}}}"))
    plan, verdict = check_plan(load_scenario(file))
    lower, upper = np.array([limits[j] for j in robot.joints]).T
    assert plan.info["range_held_from"] is not None and np.abs(plan.q_ref[:, 6] - upper[6]).min() < 1e-9
    assert np.all((plan.q_ref >= lower) & (plan.q_ref <= upper))
    assert "joint_limit" not in {v.kind for v in verdict.violations}
