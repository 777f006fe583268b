"""The robots a bench runs, each as the arm derived from its model (robots.model_arm), so that every method drives
the same MuJoCo arm and every run measures the same singular gap (rank_loss); and, for the task generator, the
robot's own singular measure (`gap`, rad) and a way to put a configuration on its singular set (`singular`).

An arm of fewer than six joints cannot hold its tool's orientation along a path: its tasks ask the tool's point
alone (holds), example-robot-data's SO-100 and the spherical arm among the shipped ones. The planar 3R is the
exception: its paths lie in its plane, where its three joints hold the tool's orientation about the plane's normal.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from simbench.core.errors import ScenarioError
from simbench.robots.rank_loss import unit_jacobian

SINGULAR_TOL = 1e-4  # rad: a configuration found by minimising rank_loss counts as singular below this gap


@dataclass(frozen=True)
class BenchRobot:
    """A robot of a bench: its `robot:` mapping (SI, absolute paths), what its tasks look like, its own singular
    measure and the paper's planner for it (a method named `paper`), if any."""

    name: str
    mapping: dict
    gap: Callable[[object, np.ndarray], np.ndarray] | None = None  # (arm, q (N, dof)) -> (N,); None: rank_loss
    singular: Callable[[np.ndarray], np.ndarray] | None = None  # q within the ranges -> q on the set; None: search
    hold: bool = True  # the tool's orientation is held along the path (False: the point alone is asked; holds())
    boundary: bool = False  # the set bounds the reach: a task meets it at the path's end, not midway
    shapes: tuple[str, ...] = ("line", "arc")
    speed: float = 0.1  # m/s: the tool's mean speed along a task
    floor: float | None = None  # m: the path kept this high above z = 0 (a derived scene's floor)
    plane: bool = False  # the tool moves in the plane z = const: paths in it
    paper: str | None = None
    cache: dict = field(default_factory=dict, compare=False, repr=False)  # the derived arm, made on first use

    def model_arm(self):
        """The arm derived from `mapping` (once)."""
        if "arm" not in self.cache:
            from simbench.scenario.robot_mapping import load_robot
            from simbench.scenario.schema import Units

            self.cache["arm"] = load_robot(self.mapping, f"bench robot {self.name}", Units())
        return self.cache["arm"]

    def model_hash(self) -> str:
        """A digest of the model by content: the model, the files it includes and those its assets name (meshes,
        textures), the same for the same files on any machine (robots.model_file.content_hash)."""
        from simbench.robots.model_file import content_hash

        return content_hash(self.mapping["model"], self.mapping.get("packages"))

    def gap_of(self, q: np.ndarray) -> np.ndarray:
        """The robot's own singular gap (rad) at configurations q (N, dof)."""
        arm = self.model_arm()
        return self.gap(arm, q) if self.gap is not None else rank_loss_gap(arm, q)


def rank_loss_gap(arm, q: np.ndarray) -> np.ndarray:
    """Least singular value of [Jp / L; Jr] at each of q (N, dof): rank_loss's gap (robots.model_arm)."""
    ju = unit_jacobian(arm.jacobian(np.atleast_2d(q)), arm.reach)
    return np.linalg.svd(ju, compute_uv=False)[:, -1]


def _set(index: int, value: float) -> Callable[[np.ndarray], np.ndarray]:
    def put(q: np.ndarray) -> np.ndarray:
        q = np.array(q, float)
        q[index] = value
        return q
    return put


def _puma() -> BenchRobot:
    from simbench.core.resources import models_dir
    from simbench.robots import puma600

    return BenchRobot("puma600", {"model": str(models_dir() / "puma600" / "puma600.xml"), "tool": {"site": "tool"},
                                  "speed_limits": puma600.QD_MAX.tolist()},
                      gap=lambda arm, q: puma600.wrist_gap(q), singular=_set(4, 0.0), speed=0.15,
                      paper="decoupled_path")


def _spherical() -> BenchRobot:
    from simbench.core.resources import models_dir
    from simbench.robots import spherical_arm

    return BenchRobot("spherical_arm", {"model": str(models_dir() / "spherical_arm" / "spherical_arm.xml"),
                                        "tool": {"site": "tool"}, "speed_limits": spherical_arm.QD_MAX.tolist()},
                      gap=lambda arm, q: np.abs(np.arcsin(np.cos(np.atleast_2d(q)[:, 2]))),
                      singular=_set(2, np.pi / 2), hold=False, shapes=("line",), floor=0.01,
                      paper="safe_straight_path")


def _planar3r() -> BenchRobot:
    try:
        import simbench_planar3r
    except ImportError:
        raise ScenarioError("planar3r", None, "the planar 3R is the example package simbench-planar3r, which is "
                                              "not installed (pip install -e examples/planar3r)") from None
    model = Path(simbench_planar3r.__file__).parent / "models" / "scene.xml"
    return BenchRobot("planar3r", {"model": str(model), "tool": {"site": "tool"},
                                   "speed_limits": [np.pi, 2 * np.pi, 2 * np.pi]},
                      gap=lambda arm, q: np.abs(np.angle(np.exp(1j * np.atleast_2d(q)[:, 1]))),
                      singular=_set(1, 0.0), boundary=True, speed=0.15, plane=True)


def _jaco() -> BenchRobot:
    try:
        import dm_control
    except ImportError:
        raise ScenarioError("jaco", None, "the Jaco's model comes with dm-control, which is not installed") from None
    model = Path(dm_control.__file__).parent / "third_party" / "kinova" / "jaco_arm.xml"
    return BenchRobot("jaco", {"model": str(model), "tool": {"site": "wristsite"},
                               "speed_limits": np.deg2rad([36, 36, 36, 48, 48, 48]).tolist()}, floor=0.05)


FULL_POSE = 6  # joints an arm needs to hold its tool's orientation along a path: fewer, and its tasks ask the point


def holds(dof: int) -> bool:
    """Whether an arm of `dof` joints has tasks that hold the tool's orientation (else they ask its point alone)."""
    return dof >= FULL_POSE


def _example_robot(name: str, urdf: str, tool: str, joints: list[str]) -> Callable[[], BenchRobot]:
    """An arm of example-robot-data, read from its install untouched: its URDF (robots/`urdf` in the package's share
    folder), the tool a body's origin, the chain's `joints` (its speed limits the URDF's own), lines and arcs above
    a floor at z = 0, the orientation held where it has six joints or more (holds)."""
    def robot() -> BenchRobot:
        from importlib.metadata import PackageNotFoundError, distribution

        try:
            share = distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data")
        except PackageNotFoundError:
            raise ScenarioError(name, None, f"the {name} model comes with example-robot-data, which is not "
                                            "installed (pip install example-robot-data)") from None
        model = Path(str(share)) / "robots" / urdf
        return BenchRobot(name, {"model": str(model), "tool": {"body": tool}, "joints": list(joints)}, floor=0.05,
                          hold=holds(len(joints)))
    return robot


_UR_JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
              "wrist_3_joint"]
EXAMPLE_ROBOTS: dict[str, Callable[[], BenchRobot]] = {
    "panda": _example_robot("panda", "panda_description/urdf/panda.urdf", "panda_link8",
                            [f"panda_joint{i}" for i in range(1, 8)]),
    "ur3": _example_robot("ur3", "ur_description/urdf/ur3_robot.urdf", "tool0", _UR_JOINTS),
    "ur5": _example_robot("ur5", "ur_description/urdf/ur5_robot.urdf", "tool0", _UR_JOINTS),
    "ur10": _example_robot("ur10", "ur_description/urdf/ur10_robot.urdf", "tool0", _UR_JOINTS),
    "xarm7": _example_robot("xarm7", "xarm_description/urdf/xarm7.urdf", "link_eef",
                            [f"joint{i}" for i in range(1, 8)]),
    "z1": _example_robot("z1", "z1_description/urdf/z1.urdf", "gripperStator", [f"joint{i}" for i in range(1, 7)]),
    "so100": _example_robot("so100", "so_arm_description/urdf/so100.urdf", "gripper",
                            ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"]),
}
"""example-robot-data's arms, each with the tool a user picks: the Panda's flange (panda_link8, its fingers left
out), a UR's tool0 flange, the xArm7's link_eef, the Z1's gripper stator (its gripper's joint left out) and the
SO-100's gripper body (its jaw's joint left out: five joints, so its tasks ask the tool's point alone)."""

SHIPPED: dict[str, Callable[[], BenchRobot]] = {"puma600": _puma, "spherical_arm": _spherical,
                                                 "planar3r": _planar3r, "jaco": _jaco, **EXAMPLE_ROBOTS}


def custom(name: str, mapping: dict, dof: int, speed: float = 0.1) -> BenchRobot:
    """A suite file's own arm of `dof` joints: rank_loss, lines and arcs above a floor at z = 0, its orientation
    held where it has six joints or more (an arm of fewer cannot hold it along a line: its tasks ask the tool's
    point alone)."""
    return BenchRobot(name, mapping, speed=speed, floor=0.05, hold=holds(dof))
