"""`simbench inspect` says where the tool is (issue 46): at `--at`, at a scenario's task.start or at the model's
qpos0, its position, orientation and singular measures, judged against MuJoCo's own compile of example-robot-data's
UR5 URDF, untouched (its meshes left out, its fixed links kept as bodies), never through simbench:

  - the tool's position and rotation equal MuJoCo's to 1e-9 (--json), and to the digits printed in the text; the
    zyx angles and the quaternion are that rotation; sigma_min, manipulability, sigma_min_unit and
    inverse_condition are those of MuJoCo's Jacobian at the tool, L the chain's length through the joints' anchors;
  - --at is read in the file's units (a scenario's `units: {angle: deg}`; --units deg) as task.start is;
  - the bare URDF, whose chain ends in two links (ee_link and tool0), lists its joints with the URDF's speed limits
    and both candidate tools with their poses, and says how to choose, exit 0 (before: refused, exit 2); a bare
    URDF with one end (the xArm7) shows the URDF's speed limits too (before: none);
  - a bad --at or --units is one line naming the file and the option, exit 2.
"""

import json
import re
import xml.etree.ElementTree as ET
from importlib.metadata import distribution

import mujoco
import numpy as np
import pytest

from simbench.cli import main

ROBOTS = distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data") / "robots"
UR5 = ROBOTS / "ur_description" / "urdf" / "ur5_robot.urdf"
XARM7 = ROBOTS / "xarm_description" / "urdf" / "xarm7.urdf"
JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
          "wrist_3_joint")
Q = np.array([0.3, -1.0, 1.0, -1.0, 1.0, 0.3])  # rad, inside the ranges, away from a rank loss
AT = ",".join(str(float(v)) for v in Q)


class Kinematics:
    """MuJoCo's compile of the UR5's URDF, its meshes left out and its fixed links kept as bodies."""

    def __init__(self):
        text = re.sub(r"<(visual|collision)\b.*?</\1>", "", UR5.read_text(), flags=re.DOTALL)
        text = re.sub(r"(<robot\b[^>]*>)", r'\1<mujoco><compiler fusestatic="false"/></mujoco>', text, count=1)
        self.model = mujoco.MjModel.from_xml_string(text)
        self.data = mujoco.MjData(self.model)
        self.adr = [self.model.joint(name).qposadr[0] for name in JOINTS]
        self.dofs = [self.model.joint(name).dofadr[0] for name in JOINTS]

    def pose(self, q, body: str) -> tuple[np.ndarray, np.ndarray]:
        self.data.qpos[:] = self.model.qpos0
        self.data.qpos[self.adr] = q
        mujoco.mj_kinematics(self.model, self.data)
        b = self.model.body(body).id
        return self.data.xpos[b].copy(), self.data.xmat[b].reshape(3, 3).copy()

    def measures(self, q, body: str) -> dict[str, float]:
        """The measures as model_arm's docstring defines them, from MuJoCo's Jacobian at the body's origin."""
        point, _ = self.pose(q, body)
        mujoco.mj_comPos(self.model, self.data)
        jacp, jacr = np.zeros((3, self.model.nv)), np.zeros((3, self.model.nv))
        mujoco.mj_jac(self.model, self.data, jacp, jacr, point, self.model.body(body).id)
        jac = np.vstack([jacp[:, self.dofs], jacr[:, self.dofs]])
        self.data.qpos[:] = self.model.qpos0
        mujoco.mj_kinematics(self.model, self.data)
        anchors = np.vstack([self.data.xanchor[[self.model.joint(n).id for n in JOINTS]],
                             self.data.xpos[self.model.body(body).id]])
        reach = np.linalg.norm(np.diff(anchors, axis=0), axis=1).sum()
        raw = np.linalg.svd(jac, compute_uv=False)
        unit = np.linalg.svd(np.vstack([jac[:3] / reach, jac[3:]]), compute_uv=False)
        return {"sigma_min": raw[-1], "manipulability": raw.prod(), "sigma_min_unit": unit[-1],
                "inverse_condition": unit[-1] / unit[0]}


@pytest.fixture(scope="module")
def mj():
    return Kinematics()


def _robot_file(folder, units: str = "") -> str:
    """A robot file naming the UR5's tool0 as its tool, with `units` (a YAML line) if given."""
    path = folder / f"ur5{'_units' * bool(units)}.yaml"
    path.write_text(f"model: {UR5}\ntool: {{body: tool0}}\n{units}")
    return str(path)


def _inspect(capsys, *args) -> str:
    code = main(["inspect", *map(str, args)])
    out, err = capsys.readouterr()
    assert code == 0 and err == "", err
    return out


def _rz(a):
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


def _ry(a):
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


def _rx(a):
    return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])


def _assert_pose(tool: dict, point, rotation):
    """The JSON tool's position and rotation are MuJoCo's, and its zyx angles and quaternion that rotation."""
    assert np.abs(np.array(tool["position"]) - point).max() < 1e-9
    assert np.abs(np.array(tool["rotation"]) - rotation).max() < 1e-9
    yaw, pitch, roll = np.radians(tool["zyx_deg"])
    assert np.abs(_rz(yaw) @ _ry(pitch) @ _rx(roll) - rotation).max() < 1e-9
    w, x, y, z = tool["quat_wxyz"]
    assert np.abs(np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
                  - rotation).max() < 1e-9


def test_at_gives_the_tools_pose_and_measures_as_mujoco_has_them(tmp_path, capsys, mj):
    robot = _robot_file(tmp_path)
    found = json.loads(_inspect(capsys, robot, "--at", AT, "--json"))
    assert found["at"] == {"given": "--at", "q": Q.tolist()}
    point, rotation = mj.pose(Q, "tool0")
    _assert_pose(found["tool"], point, rotation)
    truth = mj.measures(Q, "tool0")
    for name, value in truth.items():
        assert found["tool"]["measures"][name] == pytest.approx(value, rel=1e-9), name
    assert [j["name"] for j in found["joints"]] == list(JOINTS)
    text = _inspect(capsys, robot, "--at", AT)  # the text: to its 6 decimals
    shown = re.search(r"position: \[([^]]*)\] m", text).group(1)
    assert np.abs(np.array(shown.split(", "), float) - point).max() <= 5e-7
    assert "sigma_min_unit" in text and "zyx [yaw, pitch, roll]" in text


def test_the_joints_order_changes_neither_the_reach_nor_the_measures(tmp_path, capsys, mj):
    """A robot file's `joints:` in another order (reversed) drives the same arm: at the same pose (--at in that
    order) the same tool pose and the same measures as MuJoCo's, L the chain's length from the world on whatever
    the order; and a path end past the reach is refused naming the joint nearest the world."""
    order = list(reversed(JOINTS))
    path = tmp_path / "ur5_reversed.yaml"
    path.write_text(f"model: {UR5}\ntool: {{body: tool0}}\njoints: [{', '.join(order)}]\n")
    at = ",".join(str(float(v)) for v in Q[::-1])
    found = json.loads(_inspect(capsys, path, "--at", at, "--json"))
    point, rotation = mj.pose(Q, "tool0")
    _assert_pose(found["tool"], point, rotation)
    for name, value in mj.measures(Q, "tool0").items():
        assert found["tool"]["measures"][name] == pytest.approx(value, rel=1e-9), name
    scenario = tmp_path / "far.yaml"
    scenario.write_text(f"robot: {path.name}\nplanner: cartesian_path\ntiming: {{duration: 2}}\n"
                        f"task:\n  start: {Q[::-1].tolist()}\n  path:\n    - line: {{end: [3.0, 0.0, 0.5]}}\n")
    assert main(["validate", str(scenario)]) == 2
    assert "mm from shoulder_pan_joint's anchor, beyond the arm's reach" in capsys.readouterr().err


def test_at_takes_values_that_begin_with_a_minus_sign(tmp_path, capsys, mj):
    """`--at -0.3,...` (argparse alone takes the value for an option) poses the tool as `--at=-0.3,...` does, at
    MuJoCo's pose."""
    q = Q * np.array([-1, 1, 1, 1, 1, 1])
    at = ",".join(str(float(v)) for v in q)
    robot = _robot_file(tmp_path)
    apart = json.loads(_inspect(capsys, robot, "--at", at, "--json"))
    assert apart == json.loads(_inspect(capsys, robot, f"--at={at}", "--json"))
    _assert_pose(apart["tool"], *mj.pose(q, "tool0"))


def test_at_is_read_in_the_files_units_or_as_units_says(tmp_path, capsys, mj):
    """--at in degrees: a robot file's units: {angle: deg}, or --units deg; the same pose as radians give."""
    point, rotation = mj.pose(Q, "tool0")
    degrees = ",".join(str(float(v)) for v in np.degrees(Q))
    for args in ([_robot_file(tmp_path, "units: {angle: deg}\n")], [_robot_file(tmp_path), "--units", "deg"]):
        found = json.loads(_inspect(capsys, *args, "--at", degrees, "--json"))
        _assert_pose(found["tool"], point, rotation)
        assert np.abs(np.array(found["at"]["q"]) - Q).max() < 1e-12  # SI in the JSON


def test_a_scenario_is_posed_at_its_task_start(tmp_path, capsys, mj):
    start = np.degrees(Q).round(3)
    path = tmp_path / "line.yaml"
    path.write_text(f"robot: {{model: {UR5}, tool: {{body: tool0}}}}\nplanner: joint_move\nunits: {{angle: deg}}\n"
                    f"task: {{start: {start.tolist()}, goal: [0, -90, 90, -90, 90, 0]}}\n"
                    "timing: {duration: 1.0}\n")
    found = json.loads(_inspect(capsys, path, "--json"))
    assert found["at"]["given"] == "task.start"
    _assert_pose(found["tool"], *mj.pose(np.radians(start), "tool0"))
    text = _inspect(capsys, path)
    assert f"pose at task.start: q = [{', '.join(f'{v:g}' for v in start)}] deg" in text


def _velocities(urdf) -> dict[str, float]:
    """Each URDF joint's `velocity` limit, as the file writes it."""
    return {j.get("name"): float(j.find("limit").get("velocity"))
            for j in ET.parse(urdf).getroot().iter("joint") if j.find("limit") is not None}


def test_a_bare_urdf_shows_its_speed_limits(capsys):
    """Before: none shown for a bare URDF, where a robot file on it took them from the file."""
    found = json.loads(_inspect(capsys, XARM7, "--json"))
    stated = _velocities(XARM7)
    assert len(found["joints"]) == 7 and all(j["speed_limit"] == stated[j["name"]] for j in found["joints"])


def test_the_bare_ur5_lists_its_joints_speed_limits_and_candidate_tools(capsys, mj):
    """Before: 'no single end of the model's longest chain (ee_link, tool0)', exit 2."""
    text = _inspect(capsys, UR5)
    stated = _velocities(UR5)
    for name in JOINTS:
        assert re.search(rf"^  {name} +revolute .*, speed limit {stated[name]:g}/s$", text, re.MULTILINE), name
    assert "the candidates: {body: ee_link}, {body: tool0}" in text and "    tool: {body: tool0}" in text
    found = json.loads(_inspect(capsys, UR5, "--json", "--at", AT))
    assert found["tool"] is None and [j["speed_limit"] for j in found["joints"]] == [stated[n] for n in JOINTS]
    assert [c["tool"] for c in found["candidates"]] == ["{body: ee_link}", "{body: tool0}"]
    for candidate, body in zip(found["candidates"], ("ee_link", "tool0")):
        _assert_pose(candidate, *mj.pose(Q, body))
    at_rest = json.loads(_inspect(capsys, UR5, "--json"))
    assert at_rest["at"]["given"].startswith("qpos0")
    _assert_pose(at_rest["candidates"][1], *mj.pose(np.zeros(6), "tool0"))


@pytest.mark.parametrize("args, says", [
    (["--at", "1,2"], "--at: expected 6 values, one per joint (shoulder_pan_joint, "),
    (["--at", "a,b,c,d,e,f"], "--at: expected 6 finite numbers separated by commas"),
    (["--at", "nan,0,0,0,0,0"], "--at: expected 6 finite numbers separated by commas"),
    (["--at", "0,,0,0,0,0"], "--at: expected 6 finite numbers separated by commas"),
    (["--at", "90,0,0,0,0,0"], ("--at: shoulder_pan_joint = 90 rad is outside the joint range [-6.28319, "
                                "6.28319] rad (written in degrees? say so with --units deg)")),
    (["--at", "0,0,200,0,0,0", "--units", "deg"], "--at: elbow_joint = 200 deg is outside the joint range"),
    (["--units", "furlong"], "--units: expected an angle unit (rad or deg), a length unit (m or mm)"),
])
def test_a_bad_at_or_units_is_one_line_exit_2(tmp_path, capsys, args, says):
    robot = _robot_file(tmp_path)
    assert main(["inspect", robot, *args]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and err.startswith(f"error: {robot}: ") and says in err, err
