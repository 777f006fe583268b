"""A scenario's `robot:` given as a mapping, or as the path of a YAML robot file holding one: an arm derived from
its MJCF or URDF model (robots.model_scene, robots.model_file), with no code of its own.

    robot:
      model: arms/jaco_arm.xml                 # an MJCF or a URDF, relative to the scenario's folder (or absolute)
      name: jaco                               # optional: the arm's name in outputs (default: the model's own)
      tool: {site: wristsite}                  # or {body: b_6, offset: [0, 0, 160]} (the scenario's length unit);
                                               # either turned: rpy: [r, p, y] (its angle unit) or quat: [w, x, y, z]
      speed_limits: [36, 36, 36, 48, 48, 48]   # the scenario's angle (or length) unit per second, one per joint
                                               # (optional for a URDF whose joints state their `velocity`)
      packages: {ur_description: ../ur}        # optional: the folders of a URDF's package:// meshes
      joints: [joint_1, ...]                   # optional: the chain's joints to drive, in this order
      force_limits: [30, 30, 30, 10, 10, 10]   # optional: N m or N (SI), one per joint or one for all
      servo: {bandwidth: 50, damping_ratio: 1} # optional: the added servos' least bandwidth (rad/s)
      gravity_compensation: true               # optional: gravcomp on the bodies the chain moves

A robot file's relative paths are relative to its own folder, and it may state its own `units:` (default: the
scenario's). Reading the model runs no code (robots.model_file), and what is derived from it is kept for the
process keyed by the content of its files, never by its path alone: a model edited between two loads is read anew.
"""

from __future__ import annotations

from dataclasses import replace
from functools import cache
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import AfterValidator, Field, ValidationError, model_validator

from simbench.core.errors import ScenarioError, os_words
from simbench.maths.rotations import axis_rotation, matrix_to_quat
from simbench.robots.chain import IDENTITY, ArmError, Tool
from simbench.robots.model_arm import ModelArm
from simbench.robots.model_file import fingerprint, is_urdf, urdf_limits
from simbench.robots.model_scene import ArmOptions, DerivedArm, derive
from simbench.robots.model_size import file_problem
from simbench.scenario.schema import Angle, Name, Position, SimbenchModel, Units, _finite_norm
from simbench.scenario.validation import describe, kind_of, read_yaml

_Positive = Annotated[float, Field(gt=0, le=1e6)]


def _sized(size: int, shape: str):
    """A list of `size` values, or ValueError naming the shape expected."""
    def check(value: list) -> list:
        if len(value) != size:
            raise ValueError(f"expected {shape}, got {len(value)} values")
        return value
    return AfterValidator(check)


def _unit_quat(value: list[float]) -> list[float]:
    norm = _finite_norm(value, "a quaternion")
    return [v / norm for v in value]


Rpy = Annotated[list[Angle], _sized(3, "[roll, pitch, yaw]")]
"""Angles in the file's unit about the fixed x, y and z axes in turn, URDF's rpy: R = Rz(yaw) Ry(pitch) Rx(roll)."""
Quat = Annotated[list[float], _sized(4, "a quaternion [w, x, y, z]"), AfterValidator(_unit_quat)]
"""A rotation as a quaternion [w, x, y, z] of any non-zero length, a unit one once loaded."""


class _Turned(SimbenchModel):
    """A tool frame turned after the site's or the body's by `rpy` or `quat` (its subclasses' fields), not both."""

    @model_validator(mode="after")
    def _one_rotation(self) -> _Turned:
        if self.rpy is not None and self.quat is not None:
            raise ValueError("expected rpy or quat, not both")
        return self

    def rotation(self) -> tuple[float, float, float, float]:
        """The rotation as a unit quaternion w x y z (the identity where none is given)."""
        if self.quat is not None:
            return tuple(self.quat)
        if self.rpy is None:
            return IDENTITY
        rz, ry, rx = axis_rotation(np.eye(3)[::-1], np.array(self.rpy)[::-1])
        return tuple(matrix_to_quat(rz @ ry @ rx)[0].tolist())


class ToolSite(_Turned):
    """The tool at a site of the model, its frame turned by `rpy` or `quat`."""

    site: str
    rpy: Rpy | None = None
    quat: Quat | None = None


class ToolBody(_Turned):
    """The tool at a point of a body, `offset` in its frame (the file's length unit), its frame the body's turned
    by `rpy` or `quat`."""

    body: str
    offset: Position = [0.0, 0.0, 0.0]
    rpy: Rpy | None = None
    quat: Quat | None = None


class ServoGains(SimbenchModel):
    """The added position servos, designed for each plan (simbench.robots.servo_design): their least bandwidth w (rad/s;
    default servo_design.DEFAULT_BANDWIDTH, raised where the plan's torques ask, capped where the timestep or the
    force limits do) and damping ratio zeta (Kp = I w^2, Kd = 2 zeta I w, I the plan's largest inertia)."""

    bandwidth: Annotated[float, Field(gt=0, le=1e4)] | None = None
    damping_ratio: Annotated[float, Field(gt=0, le=10)] = 1.0


class RobotMapping(SimbenchModel):
    """The fields of a robot mapping (the module's docstring)."""

    model: str
    name: Name | None = None
    tool: ToolSite | ToolBody | None = None
    speed_limits: list[_Positive] | None = None
    joints: list[str] | None = None
    force_limits: _Positive | list[_Positive] | None = None
    servo: ServoGains = ServoGains()
    gravity_compensation: bool = True
    packages: dict[str, str] = {}
    units: Units | None = None


def is_mapping(value: Any) -> bool:
    """Whether a scenario's `robot:` names an arm by its model (a mapping or a robot file), not a registered
    robot."""
    return isinstance(value, dict) or (isinstance(value, str) and value.endswith((".yaml", ".yml")))


def anchored(value: Any, folder: str | Path) -> Any:
    """A scenario's `robot:` with its relative paths (a robot file's, a mapping's model and packages) made absolute
    against `folder`, the scenario's own: what a copy of the scenario read from elsewhere (a sweep's runs) needs to
    name the same files. Anything else is returned as it is, for the schema to judge."""
    def absolute(text: Any) -> Any:
        if not isinstance(text, str) or Path(text).is_absolute():
            return text
        try:
            return str(Path(folder, text).resolve())
        except (OSError, RuntimeError, ValueError):  # a symlink loop, a NUL byte: refused, named, where it is read
            return str(Path(folder, text))

    if isinstance(value, str):
        return absolute(value) if is_mapping(value) else value
    if not isinstance(value, dict):
        return value
    value = {**value, "model": absolute(value["model"])} if "model" in value else dict(value)
    if isinstance(value.get("packages"), dict):
        value["packages"] = {name: absolute(folder_) for name, folder_ in value["packages"].items()}
    return value


def load_robot(value: dict | str, source: str, units: Units) -> ModelArm:
    """The arm a scenario's `robot:` describes (`source`: the scenario file); ScenarioError naming the file and the
    field at fault."""
    raw, source, field = _mapping(value, source)
    units = units_of(raw, source, field) or units
    try:
        mapping = RobotMapping.model_validate(raw, context={"units": units})
    except ValidationError as err:
        raise ScenarioError(source, *describe(err, RobotMapping, raw, prefix=field)) from None
    where = ".".join(field)
    try:
        path = model_path(mapping.model, source, where)
        choices = _stamped(path, options(mapping, source))
        return _arm(path, choices, _speed_limits(mapping.speed_limits, path, _derived(path, choices), units))
    except ArmError as err:
        raise ScenarioError(source, ".".join((*field, err.field)), str(err)) from None


def units_of(raw: Any, source: str, field: tuple[str, ...] = ()) -> Units | None:
    """The `units:` a mapping (a scenario, a robot file) states, None where it states none; ScenarioError naming
    the field where they are not units."""
    if not isinstance(raw, dict) or not isinstance(raw.get("units"), dict):
        return None
    try:
        return Units.model_validate(raw["units"])
    except ValidationError as err:
        raise ScenarioError(source, *describe(err, Units, raw["units"], prefix=(*field, "units"))) from None


def _mapping(value: dict | str, source: str) -> tuple[dict, str, tuple[str, ...]]:
    """The robot mapping, the file it is in, and the field path of its fields there."""
    if isinstance(value, dict):
        return value, source, ("robot",)
    path = Path(value) if Path(value).is_absolute() else Path(source).parent / value
    if "\0" in str(path):  # read_yaml says what else a path may be in the way of
        raise ScenarioError(source, "robot", "expected a path without a NUL byte")
    raw = read_yaml(path, "robot mapping")
    if not isinstance(raw, dict):
        raise ScenarioError(str(path), None, f"expected a robot mapping (model, tool, speed_limits), got "
                                             f"{kind_of(raw)}")
    return raw, str(path), ()


def model_path(model: str, source: str, where: str) -> str:
    """The model file's absolute path; ScenarioError where it is not an MJCF or URDF file."""
    path = Path(model) if Path(model).is_absolute() else Path(source).parent / model
    field = f"{where}.model" if where else "model"
    if path.suffix.lower() not in (".xml", ".urdf"):
        raise ScenarioError(source, field, f"expected an MJCF (.xml) or URDF (.urdf) file, got {model!r}")
    problem = file_problem(path)
    if problem is not None:
        raise ScenarioError(source, field, problem)
    return str(path.resolve())


def options(mapping: RobotMapping, source: str) -> ArmOptions:
    """The mapping's choices about its model, SI (`source`: the file the mapping is in)."""
    tool = mapping.tool
    limits = mapping.force_limits
    return ArmOptions(
        name=mapping.name,
        tool=None if tool is None else (Tool(body="", site=tool.site, rotation=tool.rotation())
                                        if isinstance(tool, ToolSite)
                                        else Tool(body=tool.body, offset=tuple(tool.offset), rotation=tool.rotation())),
        joints=None if mapping.joints is None else tuple(mapping.joints),
        force_limits=None if limits is None else (tuple(limits) if isinstance(limits, tuple) else (limits,)),
        bandwidth=mapping.servo.bandwidth, damping_ratio=mapping.servo.damping_ratio,
        gravity_compensation=mapping.gravity_compensation,
        packages=tuple((name, _folder(name, Path(source).parent / folder))
                       for name, folder in sorted(mapping.packages.items())))


def _folder(name: str, folder: Path) -> str:
    """A package's folder made absolute; ArmError ('packages') for a path that names none."""
    try:
        return str(folder.resolve())
    except ValueError:
        raise ArmError("packages", f"{name}: expected a path without a NUL byte") from None
    except RuntimeError:  # Path.resolve's symlink loop
        raise ArmError("packages", f"{name}: {folder}: a symlink loop") from None
    except OSError as err:
        raise ArmError("packages", f"{name}: {folder}: {os_words(err)}") from None


def _speed_limits(values: list[float] | None, path: str, arm: DerivedArm, units: Units) -> tuple[float, ...]:
    """The speed limits in SI, one per joint of the chain: the mapping's, else the URDF's joints' `velocity`."""
    kinds = arm.chain.kinds
    if values is None:
        stated = urdf_limits(path) if is_urdf(path) else {}
        speeds = [stated.get(joint, (None, None))[0] for joint in arm.chain.joints]
        if None in speeds:
            missing = ", ".join(j for j, v in zip(arm.chain.joints, speeds) if v is None)
            raise ArmError("speed_limits", f"expected one per joint ({', '.join(arm.chain.joints)}): the model "
                                           f"states none for {missing}")
        return tuple(float(v) for v in speeds if v is not None)
    if len(values) != len(kinds):
        raise ArmError("speed_limits", f"expected {len(kinds)} values, one per joint ({', '.join(arm.chain.joints)}), "
                                       f"got {len(values)}")
    return tuple(v * units.factor(kind) for v, kind in zip(values, kinds))


def derived(path: str, arm_options: ArmOptions) -> DerivedArm:
    """The arm in the model at `path`, derived once per process for the same choices and the same content of the
    model's files (robots.model_file.fingerprint): a sweep's runs share it, an edited model is derived anew."""
    return _derived(path, _stamped(path, arm_options))


def _stamped(path: str, arm_options: ArmOptions) -> ArmOptions:
    """The options with the digest of the model's files now."""
    return replace(arm_options, digest=fingerprint(path, arm_options.packages))


@cache
def _derived(path: str, arm_options: ArmOptions) -> DerivedArm:
    """derived, keyed by options _stamped with the files' digest."""
    if arm_options.force_limits is not None and len(arm_options.force_limits) == 1:
        joints = derive(path, replace(arm_options, force_limits=None)).chain.joints
        arm_options = replace(arm_options, force_limits=arm_options.force_limits * len(joints))
    return derive(path, arm_options)


@cache
def _arm(path: str, arm_options: ArmOptions, qd_max: tuple[float, ...]) -> ModelArm:
    """One Robot per arm (its options holding the files' digest) and speed limits, so that runs of the same arm
    share their compiled scene and plant."""
    return ModelArm(_derived(path, arm_options), np.array(qd_max))
