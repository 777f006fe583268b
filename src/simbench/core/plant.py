"""A robot's scene compiled as simbench runs it: force sensors on every actuator, the scenario's timestep and
servo gains, position or torque actuation (the joints' actuators made motors within the same force limits), and
the indices of the robot's joints, actuators (found by transmission, not name) and sensors.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cache
from typing import TYPE_CHECKING, Literal

import mujoco
import numpy as np

from simbench.core.errors import RegistryError

if TYPE_CHECKING:
    from simbench.api import Robot

FORCE_SENSOR = "simbench/force/"  # prefix of the actuator-force sensors added to every scene (scene_spec)
UNNAMED_ACTUATOR = "simbench/actuator"  # an actuator the file leaves unnamed is named this and its index (scene_spec)
Actuation = Literal["position", "torque"]

# While plants are reused (reused_plants): the last Plant built and the arguments it was built from; else None.
_kept: list[tuple[tuple, Plant]] | None = None
# Scenes built in code rather than read from a file (a robot derived from a model: robots.model_scene), by the key
# that stands for them where a scene's path is asked for (Robot.scene); see register_scene.
_built: dict[str, Callable[[], mujoco.MjSpec]] = {}


@dataclass(frozen=True)
class Plant:
    """A robot's compiled model with the indices the simulator needs.

    Attributes:
        model: The compiled scene, set up for the run (its own copy).
        robot: The robot.
        qpos_adr: Each actuated joint's index into qpos (dof,).
        dof_adr: Each actuated joint's index into qvel (dof,).
        actuators: Each actuated joint's actuator (dof,).
        sensors: Each recorded sensor's slice of sensordata, by name.
        force_sensors: Each actuator's force sensor's index into sensordata (dof,).
        actuation: `"position"` (position servos) or `"torque"` (motors).
    """

    model: mujoco.MjModel
    robot: Robot
    qpos_adr: np.ndarray
    dof_adr: np.ndarray
    actuators: np.ndarray
    sensors: dict[str, slice]
    force_sensors: np.ndarray
    actuation: Actuation = "position"

    @classmethod
    def load(cls, robot: Robot, timestep: float | None = None, kp: list[float] | None = None,
             kv: list[float] | None = None, force_limits: bool = True, gravity_compensation: bool = True,
             actuation: Actuation = "position") -> "Plant":
        """The robot's compiled scene set up as asked: a fresh copy, since a run changes its model.

        Within `reused_plants()`, the same arguments as the last call's give that call's Plant.

        Args:
            robot: The robot.
            timestep: The physics timestep (s); None: the scene's.
            kp: The position servos' stiffness per joint, SI; None: the scene's.
            kv: Their damping per joint, SI; None: the scene's.
            force_limits: Whether the scene's force limits hold.
            gravity_compensation: Whether the scene's gravity compensation holds.
            actuation: `"position"`, or `"torque"`: the joint actuators made motors, their force limits kept.

        Returns:
            The plant.
        """
        key = (robot, timestep, _items(kp), _items(kv), force_limits, gravity_compensation, actuation)
        if _kept and _kept[0][0] == key:
            return _kept[0][1]
        plant = cls._build(robot, timestep, kp, kv, force_limits, gravity_compensation, actuation)
        if _kept is not None:
            _kept[:] = [(key, plant)]
        return plant

    @classmethod
    def _build(cls, robot: Robot, timestep: float | None, kp: list[float] | None, kv: list[float] | None,
               force_limits: bool, gravity_compensation: bool, actuation: Actuation) -> "Plant":
        """load() for a Plant not kept: a fresh copy of the compiled scene, set up as asked."""
        model = copy.copy(compiled_scene(str(robot.scene)))
        if timestep is not None:
            model.opt.timestep = timestep
        joints = [model.joint(name) for name in robot.joints]
        act = np.array([_actuator_of(model, robot, joint.id) for joint in joints])
        _set_gains(model, act, kp, kv)
        if not force_limits:
            model.actuator_forcelimited[:] = 0
            model.jnt_actfrclimited[:] = 0
        if not gravity_compensation:
            model.body_gravcomp[:] = 0
        if actuation == "torque":
            _make_motors(model, act)
        return cls(model=model, robot=robot,
                   qpos_adr=np.array([j.qposadr[0] for j in joints]),
                   dof_adr=np.array([j.dofadr[0] for j in joints]),
                   actuators=act,
                   sensors=_sensor_slices(model, (robot.tool_sensor, *robot.sensors)),
                   force_sensors=np.array([model.sensor(FORCE_SENSOR + model.actuator(a).name).adr[0]
                                           for a in act]),
                   actuation=actuation)

    def force_limit(self) -> np.ndarray:
        """Each joint's actuator force bound: the tighter of the actuator's and the joint's.

        Returns:
            The bounds (dof,), SI; inf where there is none.
        """
        m = self.model
        bound = np.where(m.actuator_forcelimited[self.actuators].astype(bool),
                         np.abs(m.actuator_forcerange[self.actuators]).min(axis=1), np.inf)
        jnt = m.actuator_trnid[self.actuators, 0]
        joint_bound = np.where(m.jnt_actfrclimited[jnt].astype(bool), np.abs(m.jnt_actfrcrange[jnt]).min(axis=1),
                               np.inf)
        return np.minimum(bound, joint_bound)

    def initial_qpos(self, q: np.ndarray) -> np.ndarray:
        """The full qpos of actuated joint values: the model's reference pose, q, and any passive joints assembled.

        Args:
            q: The actuated joints' values (dof,), or rows of them (N, dof).

        Returns:
            MuJoCo's qpos (nq,), or a row each (N, nq).
        """
        rows = np.atleast_2d(q)
        qpos = np.repeat(self.model.qpos0[None], len(rows), axis=0)
        qpos[:, self.qpos_adr] = rows
        for pose, row in zip(qpos, rows):  # a closed chain's passive joints (none for a serial arm)
            for name, value in self.robot.assemble(row).items():
                pose[self.model.joint(name).qposadr[0]] = value
        return qpos if np.ndim(q) == 2 else qpos[0]

    def gains(self) -> dict[str, list[float]]:
        """The position servos' gains as the model holds them.

        Returns:
            `kp` and `kv`, one per joint, SI; empty under torque actuation.
        """
        if self.actuation == "torque":
            return {}
        m = self.model
        return {"kp": m.actuator_gainprm[self.actuators, 0].tolist(),
                "kv": (-m.actuator_biasprm[self.actuators, 2]).tolist()}


@contextmanager
def reused_plants() -> Iterator[None]:
    """Within the block, Plant.load asked again with the last call's arguments returns that call's Plant: for
    callers that leave the model as it is, such as a sweep's runs in a worker. Only the last Plant is kept."""
    global _kept
    outer, _kept = _kept, []
    try:
        yield
    finally:
        _kept = outer


def _items(values: list[float] | None) -> tuple[float, ...] | None:
    """Per-joint values as a hashable, comparable key part."""
    return None if values is None else tuple(values)


def _actuator_of(model: mujoco.MjModel, robot: Robot, joint: int) -> int:
    """The one actuator whose transmission is `joint`; RegistryError if there is none or more than one."""
    found = [i for i in range(model.nu)
             if model.actuator_trntype[i] == mujoco.mjtTrn.mjTRN_JOINT and model.actuator_trnid[i, 0] == joint]
    if len(found) != 1:
        raise RegistryError(f"robot '{robot.name}': joint '{model.joint(joint).name}' is driven by {len(found)} "
                            "actuators in its scene; exactly one joint actuator is expected")
    return found[0]


def _set_gains(model: mujoco.MjModel, act: np.ndarray, kp: list[float] | None, kv: list[float] | None) -> None:
    """A position servo's force = kp ctrl - kp q - kv qd: its gain and bias terms."""
    if kp is not None:
        model.actuator_gainprm[act, 0] = kp
        model.actuator_biasprm[act, 1] = -np.asarray(kp)
    if kv is not None:
        model.actuator_biasprm[act, 2] = -np.asarray(kv)


def _make_motors(model: mujoco.MjModel, act: np.ndarray) -> None:
    """Position servos turned into motors (force = ctrl) whose control range is their force range."""
    model.actuator_gaintype[act] = mujoco.mjtGain.mjGAIN_FIXED
    model.actuator_gainprm[act] = 0
    model.actuator_gainprm[act, 0] = 1
    model.actuator_biastype[act] = mujoco.mjtBias.mjBIAS_NONE
    model.actuator_biasprm[act] = 0
    limited = model.actuator_forcelimited[act].astype(bool)
    model.actuator_ctrllimited[act] = limited
    model.actuator_ctrlrange[act] = np.where(limited[:, None], model.actuator_forcerange[act], 0)


def _sensor_slices(model: mujoco.MjModel, names: tuple[str, ...]) -> dict[str, slice]:
    """Where each named sensor's reading sits in sensordata."""
    slices = {}
    for name in names:
        sensor = model.sensor(name)
        slices[name] = slice(int(sensor.adr[0]), int(sensor.adr[0] + sensor.dim[0]))
    return slices


def register_scene(key: str, build: Callable[[], mujoco.MjSpec]) -> None:
    """Make `key` stand, wherever a scene's path is asked for, for the scene `build()` makes in code."""
    _built[key] = build


def scene_spec(scene: str) -> mujoco.MjSpec:
    """A scene (an MJCF, or a key of register_scene) with an actuator-force sensor on every actuator, so that the
    recording holds the force MuJoCo really applied."""
    spec = _built[scene]() if scene in _built else mujoco.MjSpec.from_file(scene)
    for i, actuator in enumerate(spec.actuators):
        if not actuator.name:  # (a sensor names its actuator: the file's may have none)
            actuator.name = f"{UNNAMED_ACTUATOR}{i}"
        spec.add_sensor(name=FORCE_SENSOR + actuator.name, type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                        objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname=actuator.name)
    return spec


@cache
def compiled_scene(scene: str) -> mujoco.MjModel:
    """A scene compiled once per process (compiling costs about as much as simulating a short scenario)."""
    return scene_spec(scene).compile()
