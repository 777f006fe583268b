"""The shipped suites of example-robot-data's arms (issue 47): the UR3, UR5, UR10, xArm7, Z1 and SO-100 beside the
Panda, each mapped as a user maps it (its URDF untouched, the tool a body, the chain's joints). Truths: MuJoCo's own
compile of the untouched URDF (test_derived_plant.raw_model) and its mj_kinematics and mj_jacBody on a fresh MjData;
the speed limits as the URDF's text states them (ElementTree); the files' bytes (hashlib).

  - each arm's tasks start and end with the tool on the path's ends (and at the orientation held, where held) by
    MuJoCo's kinematics, and a `through` anchor is singular by MuJoCo's Jacobian (least singular value of
    [Jp / L; Jr] under SINGULAR_TOL);
  - an arm of fewer than six joints (the SO-100: five, its jaw's left out) has tasks of the point alone, its
    methods' scenarios `orientation: free`; every shipped arm follows that rule but the planar 3R (its plane);
  - the speed limits are the URDF's; `all` lists every arm; an arm whose package is missing is refused in one line.
"""

import hashlib
import shutil
import xml.etree.ElementTree as ET
from importlib.metadata import PackageNotFoundError, distribution
from pathlib import Path

import pytest

try:
    distribution("example-robot-data")
except PackageNotFoundError:
    pytest.skip("example-robot-data (the [test] extra) holds these arms' URDFs", allow_module_level=True)

import mujoco
import numpy as np

from simbench.cli import main
from simbench.commands.bench import load_suite
from simbench.commands.bench.methods import METHODS
from simbench.commands.bench.robots import SHIPPED, SINGULAR_TOL, BenchRobot
from simbench.commands.bench.tasks import draw_one
from tests.robots.test_derived_plant import ROBOTS, raw_model, tool_pose

UR = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]
ARMS = {  # name: the URDF under example-robot-data's robots/, the tool body and the chain's joints a user picks
    "ur3": ("ur_description/urdf/ur3_robot.urdf", "tool0", UR),
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "tool0", UR),
    "ur10": ("ur_description/urdf/ur10_robot.urdf", "tool0", UR),
    "xarm7": ("xarm_description/urdf/xarm7.urdf", "link_eef", [f"joint{i}" for i in range(1, 8)]),
    "z1": ("z1_description/urdf/z1.urdf", "gripperStator", [f"joint{i}" for i in range(1, 7)]),
    "so100": ("so_arm_description/urdf/so100.urdf", "gripper",
              ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"]),
}
INDICES, SEED = (0, 2), 2  # each arm's tasks 0 and 2 at seed 2: a `through` and a `far` line (a near one costs
# as much as a through one again, and test_bench checks the near band on the PUMA)


def _arc_point(arc: dict, angle: float) -> np.ndarray:
    """The point of a scenario's arc at `angle` (rad from its ref, about its normal)."""
    ref, normal = np.array(arc["ref"]), np.array(arc["normal"]) / np.linalg.norm(arc["normal"])
    return np.array(arc["center"]) + arc["radius"] * (np.cos(angle) * ref + np.sin(angle) * np.cross(normal, ref))


def _ends(segment: dict) -> tuple[np.ndarray, np.ndarray]:
    if "line" in segment:
        return np.array(segment["line"]["start"]), np.array(segment["line"]["end"])
    arc = segment["arc"]
    return _arc_point(arc, arc["start"]), _arc_point(arc, arc["end"])


def _turn(a: np.ndarray, b: np.ndarray) -> float:
    """The angle (rad) between two rotation matrices."""
    return float(np.arccos(np.clip((np.trace(a.T @ b) - 1) / 2, -1, 1)))


@pytest.fixture(scope="module", params=list(ARMS))
def arm(request):
    """An arm's name, its shipped robot, MuJoCo's compile of its untouched URDF and its tasks INDICES at SEED."""
    robot = SHIPPED[request.param]()
    return (request.param, robot, raw_model(ROBOTS / ARMS[request.param][0]),
            [draw_one(robot, i, SEED) for i in INDICES])


def test_each_arm_is_mapped_as_a_user_maps_it_its_speed_limits_the_urdfs(arm):
    """The mapping names the URDF, the tool body and the joints, nothing else; the derived arm's speed limits are the
    URDF's `velocity` of each joint, read from the file's text."""
    name, robot, _, _ = arm
    urdf, tool, joints = ARMS[name]
    assert robot.mapping == {"model": str(ROBOTS / urdf), "tool": {"body": tool}, "joints": joints}
    stated = {j.get("name"): float(j.find("limit").get("velocity"))
              for j in ET.parse(ROBOTS / urdf).getroot().iter("joint") if j.find("limit") is not None}
    np.testing.assert_array_equal(robot.model_arm().qd_max, [stated[j] for j in joints])


def test_tasks_start_and_end_on_the_path_by_mujocos_kinematics(arm):
    """The tool at the start and goal joints (mj_kinematics of the untouched URDF) is on the path's two ends within
    1 um; at the orientation held (within 1e-5 rad) where the arm holds it, at the start where the point alone is
    asked (the task's orientation is the start's)."""
    name, robot, raw, tasks = arm
    _, tool, joints = ARMS[name]
    for task in tasks:
        (p0, p1), (r0, r1) = tool_pose(raw, {"body": tool}, joints, np.array([task.start, task.goal]))
        a, b = _ends(task.segment)
        assert np.linalg.norm(p0 - a) < 1e-6 and np.linalg.norm(p1 - b) < 1e-6, task.id
        held = np.zeros(9)
        mujoco.mju_quat2Mat(held, np.array(task.orientation))
        assert _turn(r0, held.reshape(3, 3)) < 1e-5, task.id
        if robot.hold:
            assert _turn(r1, held.reshape(3, 3)) < 1e-5, task.id


def test_a_through_anchor_is_singular_by_mujocos_jacobian(arm):
    """At each `through` anchor, [Jp / L; Jr] of mj_jacBody (the tool body's origin, the chain's columns; L the
    arm's reach) has its least singular value under SINGULAR_TOL; the tool there is on the path (a line's, within
    1e-9 m); a `far` anchor's gap is the task's, to 1e-9."""
    name, robot, raw, tasks = arm
    _, tool, joints = ARMS[name]
    data = mujoco.MjData(raw)
    columns = [raw.jnt_dofadr[raw.joint(j).id] for j in joints]
    kinds = set()
    for task in tasks:
        data.qpos[[raw.jnt_qposadr[raw.joint(j).id] for j in joints]] = task.anchor
        mujoco.mj_kinematics(raw, data)
        mujoco.mj_comPos(raw, data)
        jp, jr = np.zeros((3, raw.nv)), np.zeros((3, raw.nv))
        mujoco.mj_jacBody(raw, data, jp, jr, raw.body(tool).id)
        unit = np.vstack([jp[:, columns] / robot.model_arm().reach, jr[:, columns]])
        gap = np.linalg.svd(unit, compute_uv=False)[-1]
        if task.kind == "through":
            assert gap < SINGULAR_TOL, (task.id, gap)
        else:
            assert gap == pytest.approx(task.anchor_gap, abs=1e-9), task.id
        a, b = _ends(task.segment)
        point = data.body(tool).xpos
        assert np.linalg.norm(np.cross(point - a, b - a)) / np.linalg.norm(b - a) < 1e-9, task.id
        kinds.add(task.kind)
    assert kinds == {"through", "far"}


def test_an_arm_of_fewer_than_six_joints_asks_the_point_alone(arm):
    """The SO-100 (five joints driven, its jaw's left out) asks the tool's point alone: every cartesian_path
    method's scenario says `orientation: free`; the others (six or seven joints) hold it."""
    name, robot, _, tasks = arm
    free = len(ARMS[name][2]) < 6
    assert free == (name == "so100") and robot.hold is not free
    assert robot.model_arm().dof == len(ARMS[name][2])
    for method in ("dls_adaptive", "pinv", "time_scaling"):
        document = METHODS[method].document(tasks[0], robot)
        assert document["task"]["orientation"] == ("free" if free else "hold")


def test_every_shipped_arm_but_the_planar_one_holds_its_orientation_with_six_joints_or_more():
    """hold is the rule of a suite file's own arm (six joints or more) for every shipped arm but the planar 3R, whose
    paths lie in its plane, where three joints hold the orientation about its normal."""
    for name, make in SHIPPED.items():
        robot = make()
        if name != "planar3r":
            assert robot.hold == (robot.model_arm().dof >= 6), name


def urdf_hash(urdf: Path, share: Path = ROBOTS.parent) -> str:
    """The first 16 hex digits of SHA-256 over the SHA-256 of the URDF's bytes (a URDF includes no file), then, for
    each <mesh> in document order, its filename, a NUL byte and the SHA-256 of the file it names (a package://
    example-robot-data/ URI is a path in the package's `share` folder)."""
    digest = hashlib.sha256(hashlib.sha256(urdf.read_bytes()).digest())
    for mesh in ET.parse(urdf).getroot().iter("mesh"):
        named = mesh.get("filename")
        file = share / named.removeprefix("package://example-robot-data/")
        digest.update(named.encode() + b"\0" + hashlib.sha256(file.read_bytes()).digest())
    return digest.hexdigest()[:16]


def test_all_covers_every_arm_and_its_model_hash_is_the_urdfs_and_meshes_bytes():
    """`all` lists every shipped arm, example-robot-data's among them; each one's model hash covers its URDF and
    every mesh file it names, by their bytes (urdf_hash)."""
    names = [r.name for r in load_suite("all").robots]
    assert set(ARMS) | {"panda", "jaco", "puma600", "spherical_arm", "planar3r"} == set(names)
    for name, (urdf, _, _) in ARMS.items():
        assert SHIPPED[name]().model_hash() == urdf_hash(ROBOTS / urdf), name


def test_a_changed_mesh_changes_the_model_hash(tmp_path):
    """A copy of the UR5's URDF and meshes in a folder of the package's name hashes as the original (names, not
    paths, enter the hash); one byte of one collision mesh changed in the copy changes the copy's hash, and the
    recomputation's."""
    urdf = "ur_description/urdf/ur5_robot.urdf"
    package = tmp_path / "example-robot-data" / "robots"
    shutil.copytree(ROBOTS / "ur_description/meshes/ur5", package / "ur_description/meshes/ur5")
    (package / "ur_description/urdf").mkdir()
    shutil.copy(ROBOTS / urdf, package / urdf)
    copy = BenchRobot("ur5", {"model": str(package / urdf), "tool": {"body": "tool0"}, "joints": UR})
    assert copy.model_hash() == SHIPPED["ur5"]().model_hash() == urdf_hash(ROBOTS / urdf)
    mesh = package / "ur_description/meshes/ur5/collision/forearm.stl"
    data = bytearray(mesh.read_bytes())
    data[100] ^= 1
    mesh.write_bytes(bytes(data))
    assert copy.model_hash() != SHIPPED["ur5"]().model_hash()
    assert copy.model_hash() == urdf_hash(package / urdf, package.parent)


def test_an_arm_whose_package_is_missing_is_refused_in_one_line(monkeypatch, tmp_path, capsys):
    """Without example-robot-data, `simbench bench ur5` (and `all`) ends with exit 2 and one line saying so."""
    import importlib.metadata

    found = importlib.metadata.distribution

    def missing(name):
        if name == "example-robot-data":
            raise PackageNotFoundError(name)
        return found(name)

    monkeypatch.setattr(importlib.metadata, "distribution", missing)
    for suite in ("ur5", "all"):
        assert main(["bench", suite, "--out", str(tmp_path / suite), "--quiet"]) == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and "example-robot-data, which is not installed" in lines[0], lines
    assert not any(Path(tmp_path).iterdir())
