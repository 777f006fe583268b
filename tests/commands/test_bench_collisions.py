"""`simbench bench` draws no task that starts or ends in self-collision. Truth: MuJoCo's own contacts (mj_forward on
a fresh MjData) in an independent compile of the arm's URDF, beyond the pairs already touching at its qpos0 (the
Panda's closed fingers)."""

from importlib.metadata import distribution

import mujoco
import numpy as np

from simbench.commands.bench import load_suite
from simbench.commands.bench.tasks import draw

PACKAGE = distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data")
UR5 = PACKAGE / "robots" / "ur_description" / "urdf" / "ur5_robot.urdf"
PANDA = PACKAGE / "robots" / "panda_description" / "urdf" / "panda.urdf"


def _raw(urdf) -> mujoco.MjModel:
    """MuJoCo's own compile of the URDF, its package:// prefix replaced by the package's folder here."""
    return mujoco.MjModel.from_xml_string(urdf.read_text().replace("package://example-robot-data", str(PACKAGE)))


def _contacts(model: mujoco.MjModel, joints, q=None) -> set[tuple[str, str]]:
    """The pairs of bodies in contact with the named joints at q (the others at qpos0), on a fresh MjData."""
    data = mujoco.MjData(model)
    if q is not None:
        data.qpos[[model.joint(name).qposadr[0] for name in joints]] = q
    mujoco.mj_forward(model, data)
    names = [model.body(model.geom_bodyid[g]).name for g in range(model.ngeom)]
    return {tuple(sorted((names[c.geom1], names[c.geom2]))) for c in data.contact}


def _check(suite, urdf, tasks: int) -> set[tuple[str, str]]:
    """Every drawn task's start and goal against the raw model; the pairs touching at qpos0."""
    robot = suite.robots[0]
    joints = robot.model_arm().joints
    model = _raw(urdf)
    reference = _contacts(model, joints)
    for task in draw(robot, tasks, suite.seed):
        for which, q in (("start", task.start), ("goal", task.goal)):
            extra = _contacts(model, joints, np.array(q)) - reference
            assert not extra, f"{task.id} {which} collides: {sorted(extra)}"
    return reference


def test_a_ur5_suites_tasks_start_and_end_free_of_self_collision(tmp_path):
    path = tmp_path / "suite.yaml"
    path.write_text(f"seed: 0\ntasks: 6\nrobots:\n  - {{name: ur5, model: {UR5}, tool: {{body: wrist_3_link, "
                    f"offset: [0, 0.0823, 0]}}}}\n")
    assert _check(load_suite(path), UR5, 6) == set()


def test_the_pandas_tasks_are_free_of_self_collision_beyond_its_closed_fingers():
    reference = _check(load_suite("panda"), PANDA, 1)
    assert ("panda_leftfinger", "panda_rightfinger") in reference
