"""An arm from its URDF with zero code (issue 35): the UR5 that example-robot-data ships (read from its install,
untouched, its meshes under package:// URIs) against an independent compile of the same file by MuJoCo; and a small
URDF written here for what the UR5 does not show: a visual COLLADA mesh dropped, a colliding one refused, the
`packages:` map, and a URDF without speed limits."""

import json
import struct
from importlib.metadata import distribution

import mujoco
import numpy as np
import pytest

from simbench.cli import main
from simbench.scenario import load_scenario

PACKAGE = distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data")
UR5 = PACKAGE / "robots" / "ur_description" / "urdf" / "ur5_robot.urdf"
OFFSET = [0.0, 0.0823, 0.0]  # m: the UR5's tool0 flange in wrist_3_link's frame
START, GOAL = [0, -60, 60, -90, -90, 0], [30, -80, 90, -100, -60, 40]  # deg


def _scenario(folder, robot: str, start=START, goal=GOAL) -> str:
    """A joint_move scenario (degrees) on `robot`, a robot mapping in YAML's flow style."""
    path = folder / "move.yaml"
    path.write_text(f"robot: {robot}\nplanner: joint_move\nunits: {{angle: deg}}\n"
                    f"task: {{start: {start}, goal: {goal}}}\ntiming: {{duration: 2.0, hold: 0.3}}\n")
    return str(path)


def _ur5_robot() -> str:
    return f"{{model: {UR5}, tool: {{body: wrist_3_link, offset: {OFFSET}}}}}"


@pytest.fixture(scope="module")
def ur5(tmp_path_factory):
    return load_scenario(_scenario(tmp_path_factory.mktemp("ur5"), _ur5_robot())).robot_def


@pytest.fixture(scope="module")
def raw():
    """MuJoCo's own compile of the UR5's URDF, its package:// prefix replaced by the package's folder here."""
    text = UR5.read_text().replace("package://example-robot-data", str(PACKAGE))
    return mujoco.MjModel.from_xml_string(text)


def test_joints_ranges_and_limits_are_the_urdfs(ur5, raw):
    hinges = [j for j in range(raw.njnt) if raw.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    assert ur5.joints == tuple(raw.joint(j).name for j in hinges) == (
        "shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint")
    np.testing.assert_array_equal(np.column_stack([ur5.lower, ur5.upper]), raw.jnt_range[hinges])
    np.testing.assert_array_equal(ur5.qd_max, [3.15, 3.15, 3.15, 3.2, 3.2, 3.2])  # the joints' `velocity`
    assert [d.force_limit for d in ur5.arm.drives] == [150, 150, 150, 28, 28, 28]  # their `effort`
    np.testing.assert_array_equal(raw.jnt_actfrcrange[hinges, 1], [150, 150, 150, 28, 28, 28])
    assert ur5.arm.dropped == ()  # MuJoCo reads a URDF's collision meshes only, STL here


def test_fk_is_the_body_point_after_mj_forward(ur5, raw):
    rng = np.random.default_rng(0)
    q = rng.uniform(-np.pi, np.pi, (20, 6))
    data = mujoco.MjData(raw)
    for row, point in zip(q, ur5.fk(q)):
        data.qpos[:] = row
        mujoco.mj_forward(raw, data)
        body = data.body("wrist_3_link")
        np.testing.assert_allclose(point, body.xpos + body.xmat.reshape(3, 3) @ OFFSET, atol=1e-12)


def test_the_cli_moves_the_ur5_to_its_goal(tmp_path, capsys):
    scenario = _scenario(tmp_path, _ur5_robot())
    assert main(["run", scenario, "--out", str(tmp_path / "out"), "--no-video"]) == 0
    assert "ur5 / joint_move" in capsys.readouterr().out
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["status"] == "ok" and report["derived_arm"]["model"] == "ur5_robot.urdf"
    q = np.load(tmp_path / "out" / "timeseries.npz")["q"]
    np.testing.assert_allclose(np.rad2deg(q[-1]), GOAL, atol=0.05)


_CUBE = [((0, 0, -1), [(0, 0, 0), (1, 1, 0), (1, 0, 0)]), ((0, 0, -1), [(0, 0, 0), (0, 1, 0), (1, 1, 0)]),
         ((0, 0, 1), [(0, 0, 1), (1, 0, 1), (1, 1, 1)]), ((0, 0, 1), [(0, 0, 1), (1, 1, 1), (0, 1, 1)]),
         ((0, -1, 0), [(0, 0, 0), (1, 0, 0), (1, 0, 1)]), ((0, -1, 0), [(0, 0, 0), (1, 0, 1), (0, 0, 1)]),
         ((0, 1, 0), [(0, 1, 0), (1, 1, 1), (1, 1, 0)]), ((0, 1, 0), [(0, 1, 0), (0, 1, 1), (1, 1, 1)]),
         ((-1, 0, 0), [(0, 0, 0), (0, 0, 1), (0, 1, 1)]), ((-1, 0, 0), [(0, 0, 0), (0, 1, 1), (0, 1, 0)]),
         ((1, 0, 0), [(1, 0, 0), (1, 1, 0), (1, 1, 1)]), ((1, 0, 0), [(1, 0, 0), (1, 1, 1), (1, 0, 1)])]


def _binary_stl(size: float) -> bytes:
    """A cube of side `size` (m) as binary STL (MuJoCo reads no ASCII STL)."""
    facets = [struct.pack("<12fH", *normal, *(size * c for v in vertices for c in v), 0) for normal, vertices in _CUBE]
    return b"cube".ljust(80) + struct.pack("<I", len(facets)) + b"".join(facets)


def _toy(folder, collision: str = "cube.stl", velocity: str = ' velocity="2"'):
    """A 2-link URDF in folder/toy/urdf, its meshes in folder/toy/meshes under package://toy: a cube to collide and a
    COLLADA shell to see (kept by `discardvisual="false"`)."""
    (folder / "toy" / "meshes").mkdir(parents=True)
    (folder / "toy" / "urdf").mkdir()
    (folder / "toy" / "meshes" / "cube.stl").write_bytes(_binary_stl(0.05))
    (folder / "toy" / "meshes" / "shell.dae").write_text("<COLLADA/>")  # never read
    links = ""
    for i in (1, 2):
        links += f"""
  <joint name="j{i}" type="revolute"><parent link="l{i - 1}"/><child link="l{i}"/>
    <origin xyz="0 0 {0.3 if i == 2 else 0.1}"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="5"{velocity}/></joint>
  <link name="l{i}">
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><geometry><mesh filename="package://toy/meshes/shell.dae"/></geometry></visual>
    <collision><geometry><mesh filename="package://toy/meshes/{collision}"/></geometry></collision>
  </link>"""
    path = folder / "toy" / "urdf" / "toy.urdf"
    path.write_text(f'<robot name="toy"><mujoco><compiler discardvisual="false"/></mujoco><link name="l0"/>{links}'
                    "\n</robot>\n")
    return path


def _toy_scenario(folder, model, extra: str = "") -> str:
    """A joint_move scenario on the toy arm of `model`, the mapping's further fields `extra`."""
    return _scenario(folder, f"{{model: {model}, tool: {{body: l2, offset: [0, 0, 0.3]}}{extra}}}", [10, -20], [40, 30])


def test_a_visual_collada_mesh_is_dropped_with_a_note(tmp_path, capsys):
    scenario = _toy_scenario(tmp_path, _toy(tmp_path))
    assert main(["inspect", scenario]) == 0
    out = capsys.readouterr().out
    assert "dropped: visual mesh package://toy/meshes/shell.dae dropped: MuJoCo cannot decode .dae" in out
    assert "speed limit 2/s" in out and "force limit 5" in out
    assert main(["run", scenario, "--out", str(tmp_path / "out"), "--no-video", "--quiet"]) == 0
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["status"] == "ok" and len(report["derived_arm"]["dropped"]) == 1


def _error(tmp_path, capsys, model, extra: str = "") -> str:
    """The one line `simbench validate` prints for the toy scenario on `model`, which it refuses (exit 2)."""
    assert main(["validate", _toy_scenario(tmp_path, model, extra)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "move.yaml" in err
    return err


def test_a_colliding_collada_mesh_is_refused_with_the_way_out(tmp_path, capsys):
    err = _error(tmp_path, capsys, _toy(tmp_path, collision="shell.dae"))
    assert "robot.model" in err and "mesh package://toy/meshes/shell.dae of toy.urdf" in err
    assert "convert it to STL or OBJ" in err


def test_a_package_outside_the_urdfs_folders_is_named_in_packages(tmp_path, capsys):
    model = _toy(tmp_path / "elsewhere")
    moved = tmp_path / "arm.urdf"
    moved.write_text(model.read_text())
    err = _error(tmp_path, capsys, moved)
    assert "robot.packages" in err and "no folder 'toy' above the URDF" in err
    assert main(["validate", _toy_scenario(tmp_path, moved, ", packages: {toy: elsewhere/toy}")]) == 0


def test_a_urdf_without_velocity_limits_needs_speed_limits(tmp_path, capsys):
    model = _toy(tmp_path, velocity="")
    err = _error(tmp_path, capsys, model)
    assert "robot.speed_limits" in err and "the model states none for j1, j2" in err
    assert main(["validate", _toy_scenario(tmp_path, model, ", speed_limits: [90, 90]")]) == 0
