"""A robot mapping's tool frame turned by `rpy` or `quat` (issue 46), its errors naming the union member the mapping
picks by its key, and its `name:`. The turned frame is checked against MuJoCo's own kinematics of the untouched file
(a plain compile of the URDF or MJCF, as tests/planners/test_cartesian_path_damping.py's Kinematics does), and URDF's
rpy
against MuJoCo's URDF reader itself: a fixed link added at the same origin and rpy."""

import json
import re
from importlib.metadata import distribution
from pathlib import Path

import dm_control
import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import simbench
from simbench.cli import main
from simbench.scenario.robot_mapping import load_robot
from simbench.scenario.schema import Units
from tests.robots.test_derived_plant import tool_pose

ROBOTS = Path(str(distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data"))) / "robots"
UR5 = ROBOTS / "ur_description" / "urdf" / "ur5_robot.urdf"
JACO = Path(dm_control.__file__).parent / "third_party" / "kinova" / "jaco_arm.xml"
RPY = [20.0, -35.0, 50.0]  # deg: a turn about all three axes, so that a wrong order or sense shows
OFFSET = [0.0, 0.0, 150.0]  # mm
QUAT = [2.0, 1.0, -1.0, 0.5]  # w x y z, not of unit length
START = [0.834, 0.0016, -1.8601, -0.0508, -1.263, -1.6155]  # rad: a UR5 pose at mid-reach, clear of contacts
DEG, MM = Units(angle="deg", length="mm"), 1e-3


def ur5_with_torch() -> mujoco.MjModel:
    """MuJoCo's own compile of the UR5's URDF, meshes left out and fixed links kept as bodies, with a link `torch`
    fixed to tool0 at OFFSET and RPY: URDF's rpy as MuJoCo's URDF reader takes it."""
    text = re.sub(r"<(visual|collision)\b.*?</\1>", "", UR5.read_text(), flags=re.DOTALL)
    text = re.sub(r"(<robot\b[^>]*>)", r'\1<mujoco><compiler fusestatic="false"/></mujoco>', text, count=1)
    x, y, z = np.array(OFFSET) * MM
    r, p, w = np.deg2rad(RPY)
    torch = (f'<link name="torch"/><joint name="torch_joint" type="fixed"><parent link="tool0"/><child link="torch"/>'
             f'<origin xyz="{x:.17g} {y:.17g} {z:.17g}" rpy="{r:.17g} {p:.17g} {w:.17g}"/></joint>')
    return mujoco.MjModel.from_xml_string(text.replace("</robot>", torch + "</robot>"))


def random_joints(robot, n: int, seed: int) -> np.ndarray:
    """n joint values uniform within the ranges (a continuous joint within a turn)."""
    return np.random.default_rng(seed).uniform(np.maximum(robot.lower, -np.pi), np.minimum(robot.upper, np.pi),
                                               (n, robot.dof))


def test_a_bodys_tool_turned_by_rpy_is_the_bodys_frame_times_urdfs_rpy():
    """tool: {body: tool0, offset, rpy} (deg, mm): simbench's tool point and orientation at random joints are
    MuJoCo's tool0 frame times the offset and scipy's fixed-axes x-y-z rotation, and MuJoCo's own frame of a URDF
    link fixed there with that origin and rpy, to 1e-9."""
    robot = load_robot({"model": str(UR5), "tool": {"body": "tool0", "offset": OFFSET, "rpy": RPY}}, "src", DEG)
    raw = ur5_with_torch()
    q = random_joints(robot, 50, seed=46)
    body_points, body_rotations = tool_pose(raw, {"body": "tool0"}, robot.joints, q)
    torch_points, torch_rotations = tool_pose(raw, {"body": "torch"}, robot.joints, q)
    turn = Rotation.from_euler("xyz", RPY, degrees=True).as_matrix()
    np.testing.assert_allclose(robot.tool_rotation(q), body_rotations @ turn, rtol=0, atol=1e-9)
    np.testing.assert_allclose(robot.tool_rotation(q), torch_rotations, rtol=0, atol=1e-9)
    np.testing.assert_allclose(robot.fk(q), body_points + body_rotations @ (np.array(OFFSET) * MM), rtol=0, atol=1e-9)
    np.testing.assert_allclose(robot.fk(q), torch_points, rtol=0, atol=1e-9)


def test_a_sites_tool_turned_by_quat_is_the_sites_frame_times_the_rotation():
    """tool: {site: wristsite, quat} on the Jaco's MJCF (its site stated by a quat of its own): simbench's tool
    orientation at random joints is MuJoCo's site frame times the normalised quaternion's rotation (scipy's), to
    1e-9, its point the site's; the mapping's `speed_limits` in deg/s."""
    robot = load_robot({"model": str(JACO), "tool": {"site": "wristsite", "quat": QUAT},
                        "speed_limits": [36] * 6}, "src", DEG)
    raw = mujoco.MjModel.from_xml_path(str(JACO))
    q = random_joints(robot, 50, seed=47)
    points, rotations = tool_pose(raw, {"site": "wristsite"}, robot.joints, q)
    turn = Rotation.from_quat(QUAT, scalar_first=True).as_matrix()
    assert np.abs(turn - np.eye(3)).max() > 0.5
    np.testing.assert_allclose(robot.tool_rotation(q), rotations @ turn, rtol=0, atol=1e-9)
    np.testing.assert_allclose(robot.fk(q), points, rtol=0, atol=1e-9)


def test_a_line_with_the_orientation_held_holds_the_turned_frame_and_the_report_names_the_arm(tmp_path):
    """A robot file (its own units, deg and mm, and `name:`) with the turned tool, run on a 150 mm line with
    `orientation: hold` from a scenario in SI: the orientation asked at every sample is the turned frame at the
    start (MuJoCo's, of the URDF's fixed link); MuJoCo's frame at the recorded joints stays within 0.2 deg of it,
    as report.json's orientation error says, and its point within 0.5 mm of the line; report.json, the page and
    `derived_arm` name the arm by its `name:`, the tool as turned."""
    raw = ur5_with_torch()
    joints = [raw.joint(j).name for j in range(raw.njnt)]
    (p0,), (r0,) = tool_pose(raw, {"body": "torch"}, joints, START)
    end = p0 + [0.0, 0.15, 0.0]
    (tmp_path / "torch.yaml").write_text(json.dumps({"model": str(UR5), "name": "ur5-torch",
                                                     "units": {"angle": "deg", "length": "mm"},
                                                     "tool": {"body": "tool0", "offset": OFFSET, "rpy": RPY}}))
    scenario = tmp_path / "line.yaml"
    scenario.write_text(f"robot: torch.yaml\nplanner: cartesian_path\ntask:\n  start: {START}\n  path:\n"
                        f"    - line: {{end: {end.tolist()}}}\n  orientation: hold\n"
                        "timing: {duration: 2.0, hold: 0.2}\n")
    result = simbench.run(simbench.load_scenario(scenario), out=tmp_path / "out", video=False)
    report = result.report
    assert report["status"] == "ok", report["violations"]
    ts = np.load(tmp_path / "out" / "timeseries.npz")
    asked = Rotation.from_quat(ts["tool_orientation_ref"], scalar_first=True).as_matrix()
    assert np.abs(asked - r0).max() < 1e-9
    points, rotations = tool_pose(raw, {"body": "torch"}, joints, ts["q"])
    turned = Rotation.from_matrix(np.einsum("nji,jk->nik", rotations, r0)).magnitude()
    assert np.rad2deg(turned.max()) < 0.2, f"{np.rad2deg(turned.max()):.3f} deg from the held frame"
    np.testing.assert_allclose(report["tracking"]["orientation_max"], turned.max(), atol=2e-4)
    along = np.clip((points - p0) @ (end - p0) / 0.15 ** 2, 0, 1)
    assert np.linalg.norm(points - (p0 + along[:, None] * (end - p0)), axis=1).max() < 0.5e-3
    assert report["robot"] == "ur5-torch" and "ur5-torch" in (tmp_path / "out" / "index.html").read_text()
    assert report["derived_arm"]["tool"].startswith("body 'tool0' at offset [0.0, 0.0, 0.15] m, turned by quat")


ERRORS = [  # (tool, the one line's field and message)
    ({"body": "tool0", "offset": OFFSET, "flip": True},
     "robot.tool.flip: unknown field (expected one of: body, offset, rpy, quat)"),
    ({"site": "wristsite", "offset": OFFSET}, "robot.tool.offset: unknown field (expected one of: site, rpy, quat)"),
    ({"bdy": "tool0"},
     "robot.tool.bdy: unknown field (expected one of: site, rpy, quat, body, offset); did you mean 'body'?"),
    ({"body": "tool0", "rpy": [0, 90]}, "robot.tool.rpy: expected [roll, pitch, yaw], got 2 values"),
    ({"body": "tool0", "rpy": "x"}, "robot.tool.rpy: expected a valid list, got 'x'"),
    ({"site": "wristsite", "quat": [1, 0, 0]}, "robot.tool.quat: expected a quaternion [w, x, y, z], got 3 values"),
    ({"body": "tool0", "quat": [0, 0, 0, 0]}, "robot.tool.quat: expected a quaternion, got a zero vector"),
    ({"body": "tool0", "rpy": [0, 0, 0], "quat": [1, 0, 0, 0]}, "robot.tool: expected rpy or quat, not both"),
    ({"body": "tool0", "rpy": [0, 4000, 0]}, "robot.tool.rpy[1]: expected an angle in [-3600, 3600] deg, got 4000 deg"),
]


@pytest.mark.parametrize("tool, message", ERRORS)
def test_a_bad_tool_is_one_line_naming_the_field_of_the_member_its_key_picks(tmp_path, capsys, tool, message):
    """Bad input, exit 2, one line: an unknown field of `{body: ...}` is told of body's fields, not blamed on
    `body` as unknown to `{site}` (as before); a field no member has, of every member's."""
    path = tmp_path / "bad.yaml"
    path.write_text(f"robot: {json.dumps({'model': str(UR5), 'tool': tool})}\nunits: {{angle: deg, length: mm}}\n"
                    f"planner: joint_move\ntask: {{start: [0, 0, 0, 0, 0, 0], goal: [10, 0, 0, 0, 0, 0]}}\n")
    assert main(["validate", str(path)]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [f"error: {path}: {message}"]


def test_a_robot_files_bad_name_is_one_line_naming_the_file_and_the_field(tmp_path, capsys):
    """`name:` names the arm in outputs: held to the rule of a scenario's name."""
    robot = tmp_path / "arm.yaml"
    robot.write_text(json.dumps({"model": str(UR5), "name": "my ur5", "tool": {"body": "tool0"}}))
    path = tmp_path / "run.yaml"
    path.write_text("robot: arm.yaml\nplanner: joint_move\n"
                    "task: {start: [0, 0, 0, 0, 0, 0], goal: [0.1, 0, 0, 0, 0, 0]}\n")
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {robot}: name: expected letters, digits")
    assert err[0].endswith("got 'my ur5'")
