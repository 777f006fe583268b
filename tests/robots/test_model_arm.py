"""An arm from its MJCF with zero code (issue 35, first slice), on the Kinova Jaco that dm-control bundles (read from
its install, untouched): what is derived equals MuJoCo's own arrays and functions, a velocity-actuated copy is
converted (and said so), never run as position servos, a scene without cameras renders, and the CLI runs it."""

import json
import os
import shutil

import dm_control
import imageio.v2 as imageio
import mujoco
import numpy as np
import pytest

from simbench.cli import main
from simbench.outputs.render import render_video
from simbench.scenario import load_scenario

KINOVA = os.path.join(os.path.dirname(dm_control.__file__), "third_party", "kinova")
JACO = os.path.join(KINOVA, "jaco_arm.xml")
START, GOAL = [30, 205, 100, -85, -80, 85], [40, 240, 90, -65, -115, 60]  # deg, away from the singular set


def _scenario(folder, model=JACO, robot_extra="", **fields):
    """A joint_move scenario on the arm of `model`, in degrees."""
    text = f"""robot:
  model: {model}
  tool: {{site: wristsite}}
{robot_extra}planner: joint_move
units: {{angle: deg}}
task: {{start: {START}, goal: {GOAL}}}
timing: {{duration: 2.0, hold: 0.3}}
render: {{width: 96, height: 64, fps: 5}}
"""
    for key, value in fields.items():
        text += f"{key}: {value}\n"
    path = folder / "jaco_move.yaml"
    path.write_text(text)
    return path


SPEEDS = "  speed_limits: [36, 36, 36, 48, 48, 48]\n"


@pytest.fixture(scope="module")
def jaco(tmp_path_factory):
    return load_scenario(_scenario(tmp_path_factory.mktemp("jaco"), robot_extra=SPEEDS)).robot_def


@pytest.fixture(scope="module")
def raw():
    return mujoco.MjModel.from_xml_path(JACO)


def _random_q(robot, n, seed=0):
    rng = np.random.default_rng(seed)
    lo = np.where(np.isfinite(robot.lower), robot.lower, -np.pi)
    hi = np.where(np.isfinite(robot.upper), robot.upper, np.pi)
    return rng.uniform(lo, hi, (n, robot.dof))


def test_joints_and_ranges_are_mujocos(jaco, raw):
    hinges = [j for j in range(raw.njnt) if raw.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    assert jaco.joints == tuple(raw.joint(j).name for j in hinges)
    assert set(jaco.kinds) == {"revolute"}
    for j, lo, hi in zip(hinges, jaco.lower, jaco.upper):
        if raw.jnt_limited[j]:
            assert (lo, hi) == tuple(raw.jnt_range[j])
        else:
            assert (lo, hi) == (-np.inf, np.inf)
    np.testing.assert_allclose(jaco.qd_max, np.deg2rad([36, 36, 36, 48, 48, 48]))


def test_fk_is_the_site_after_mj_forward(jaco, raw):
    q = _random_q(jaco, 20)
    data = mujoco.MjData(raw)
    for row, point in zip(q, jaco.fk(q)):
        data.qpos[:] = row
        mujoco.mj_forward(raw, data)
        np.testing.assert_allclose(point, data.site("wristsite").xpos, atol=1e-12)


def test_jacobian_is_the_derivative_of_fk_and_sigma_min_numpys(jaco, raw):
    q = _random_q(jaco, 5, seed=1)
    jac = jaco.jacobian(q)
    h = 1e-6
    for row, j in zip(q, jac):
        numeric = np.column_stack([(jaco.fk(row + h * e)[0] - jaco.fk(row - h * e)[0]) / (2 * h)
                                   for e in np.eye(jaco.dof)])
        np.testing.assert_allclose(j[:3], numeric, atol=1e-6)
    data = mujoco.MjData(raw)
    truth = []
    for row in q:
        data.qpos[:] = row
        mujoco.mj_forward(raw, data)
        jacp, jacr = np.zeros((3, raw.nv)), np.zeros((3, raw.nv))
        mujoco.mj_jacSite(raw, data, jacp, jacr, raw.site("wristsite").id)
        truth.append(np.linalg.svd(np.vstack([jacp, jacr]), compute_uv=False)[-1])
    rec = type("Rec", (), {"q": q})()
    np.testing.assert_allclose(jaco.measures(rec)["sigma_min"], truth, rtol=1e-9, atol=1e-12)


def test_joints_listed_out_of_the_files_order_pose_and_differentiate_as_mujoco(tmp_path, raw):
    """`joints:` in another order than the file's (their qpos and dof addresses no longer run in order): the tool's
    point, rotation and Jacobian columns at random joint values, each joint's value put at its own address, are
    MuJoCo's (mj_forward, mj_jacSite on the untouched file); and the file's order gives the same poses."""
    order = ["joint_3", "joint_1", "joint_6", "joint_2", "joint_5", "joint_4"]
    at = [int(name[-1]) - 1 for name in order]
    path = _scenario(tmp_path, robot_extra=f"  speed_limits: {[[36, 36, 36, 48, 48, 48][i] for i in at]}\n"
                                           f"  joints: {order}\n")
    start, goal = [START[i] for i in at], [GOAL[i] for i in at]  # in the listed order
    path.write_text(path.read_text().replace(f"task: {{start: {START}, goal: {GOAL}}}",
                                             f"task: {{start: {start}, goal: {goal}}}"))
    shuffled = load_scenario(path).robot_def
    assert shuffled.joints == tuple(order)
    assert not isinstance(shuffled._compiled()[2], slice)  # the addresses as an index array, not a slice
    data, site = mujoco.MjData(raw), raw.site("wristsite").id
    q = _random_q(shuffled, 12, seed=3)
    points, rotations, jac = shuffled.pose_jacobian(q)
    for row, point, rotation, j in zip(q, points, rotations, jac):
        for name, value in zip(order, row):
            data.qpos[raw.joint(name).qposadr[0]] = value
        mujoco.mj_forward(raw, data)
        jacp, jacr = np.zeros((3, raw.nv)), np.zeros((3, raw.nv))
        mujoco.mj_jacSite(raw, data, jacp, jacr, site)
        columns = [raw.joint(name).dofadr[0] for name in order]
        np.testing.assert_allclose(point, data.site_xpos[site], atol=1e-12)
        np.testing.assert_allclose(rotation, data.site_xmat[site].reshape(3, 3), atol=1e-12)
        np.testing.assert_allclose(j, np.vstack([jacp, jacr])[:, columns], atol=1e-12)
    (tmp_path / "in_order").mkdir()
    in_order = load_scenario(_scenario(tmp_path / "in_order", robot_extra=SPEEDS)).robot_def
    back = np.argsort([in_order.joints.index(name) for name in order])
    np.testing.assert_allclose(in_order.pose(q[:, back])[0], points, atol=1e-12)


def _velocity_jaco(folder):
    """A copy of dm-control's kinova folder with a model that includes the Jaco and drives every joint by a velocity
    servo."""
    shutil.copytree(KINOVA, folder / "kinova")
    actuators = "".join(f'<velocity name="v{i}" joint="joint_{i}" kv="20"/>' for i in range(1, 7))
    path = folder / "kinova" / "jaco_velocity.xml"
    path.write_text(f'<mujoco model="jaco_velocity"><include file="jaco_arm.xml"/>'
                    f"<actuator>{actuators}</actuator></mujoco>")
    return path


def test_velocity_servos_are_replaced_and_the_move_ends_at_its_goal(tmp_path, capsys):
    model = _velocity_jaco(tmp_path)
    kinds = mujoco.MjModel.from_xml_path(str(model))
    assert (kinds.actuator_biasprm[:, 1] == 0).all() and (kinds.actuator_biasprm[:, 2] == -20).all()  # velocity
    scenario = _scenario(tmp_path, model=model, robot_extra=SPEEDS)
    assert main(["run", str(scenario), "--out", str(tmp_path / "out"), "--no-video", "--quiet"]) == 0
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    notes = report["derived_arm"]["actuator_notes"]
    assert len(notes) == 6 and all("velocity servo 'v" in n and "replaced by a position servo" in n for n in notes)
    q = np.load(tmp_path / "out" / "timeseries.npz")["q"]
    np.testing.assert_allclose(np.rad2deg(q[-1]), GOAL, atol=0.05)
    plant_model = mujoco.MjModel.from_xml_path(str(model))
    assert plant_model.nu == 6  # the file itself is untouched


def test_a_scene_without_cameras_renders(tmp_path, jaco):
    scenario = _scenario(tmp_path, robot_extra=SPEEDS)
    assert main(["run", str(scenario), "--out", str(tmp_path / "out"), "--no-video", "--quiet"]) == 0
    series = np.load(tmp_path / "out" / "timeseries.npz")
    rec = type("Rec", (), {"t": series["t"], "qpos": series["qpos"], "tool": series["tool"]})()
    assert mujoco.MjModel.from_xml_path(JACO).ncam == 0
    info = render_video(JACO, rec, series["tool_ref"], tmp_path / "v.mp4", width=96, height=64, fps=3)
    frames = np.array(imageio.mimread(tmp_path / "v.mp4"))
    assert info["camera"] == "free" and len(frames) == info["frames"] >= 3
    assert frames.std() > 5  # not one colour


def test_cli_runs_and_inspects_the_jaco(tmp_path, capsys):
    scenario = _scenario(tmp_path, robot_extra=SPEEDS)
    assert main(["run", str(scenario), "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "jaco_arm / joint_move" in out and "status: ok" in out
    assert (tmp_path / "out" / "video.mp4").stat().st_size > 0
    assert main(["inspect", JACO]) == 0
    out = capsys.readouterr().out
    assert "joint_2      revolute  [0.820305, 5.46288]" in out and "joint_1      revolute  continuous" in out
    assert "no actuator: added a position servo" in out and "tool: site 'wristsite'" in out
    assert "qpos0: outside the range of joint_2, joint_3" in out


def test_a_mapping_without_speed_limits_is_bad_input(tmp_path, capsys):
    scenario = _scenario(tmp_path)
    assert main(["validate", str(scenario)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and str(scenario) in err and "robot.speed_limits" in err


@pytest.mark.parametrize("robot_file", [False, True], ids=["mapping", "robot_file"])
def test_a_sweep_resolves_the_models_relative_path_as_run_does(tmp_path, monkeypatch, robot_file):
    """A base scenario naming its model (or its robot file) relative to its own folder runs alike from a sweep
    file in another folder, the sweep started from a third."""
    scenarios, sweeps, elsewhere = (tmp_path / name for name in ("scenarios", "sweeps/of_jaco", "elsewhere"))
    for folder in (scenarios / "arms", sweeps, elsewhere):
        folder.mkdir(parents=True)
    if robot_file:  # the robot file's model relative to the robot file's folder
        (scenarios / "arms" / "jaco.yaml").write_text(f"model: {os.path.relpath(JACO, scenarios / 'arms')}\n"
                                                       f"tool: {{site: wristsite}}\n{SPEEDS.strip()}\n")
        base = _scenario(scenarios)
        base.write_text(base.read_text().replace(f"robot:\n  model: {JACO}\n  tool: {{site: wristsite}}\n",
                                                 "robot: arms/jaco.yaml\n"))
    else:
        base = _scenario(scenarios, model=os.path.relpath(JACO, scenarios), robot_extra=SPEEDS)
    assert f" {JACO}" not in base.read_text()
    (sweeps / "jaco.yaml").write_text("base: ../../scenarios/jaco_move.yaml\noutputs: report\n"
                                      "grid: {timing.duration: [2.0]}\n")
    monkeypatch.chdir(elsewhere)
    assert main(["sweep", "../sweeps/of_jaco/jaco.yaml", "--out", "out", "--quiet"]) == 0
    summary = json.loads((elsewhere / "out" / "summary.json").read_text())
    assert summary["status"]["ok"] == summary["runs"] == 1, summary
    report = json.loads(next((elsewhere / "out").rglob("report.json")).read_text())
    assert report["status"] == "ok" and report["derived_arm"]["model"] == "jaco_arm.xml"
