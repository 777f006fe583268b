"""Building blocks of the scenario schema: strict models and quantities converted to SI at load time.

A scenario states its units once (`units: {angle: deg, length: mm}`); every angle, length and joint vector is
converted while it is validated, so everything downstream is in radians and metres. Joint vectors are checked
against the robot's joint count and limits, and an error quotes the value in the file's own units.
"""

from __future__ import annotations

import re
from typing import Annotated, Literal

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationInfo, model_validator
from scipy.spatial.transform import Rotation

from simbench.robots import REVOLUTE, Robot

_DEG = np.pi / 180.0


class SimbenchModel(BaseModel):
    """Strict, frozen, no unknown fields, no NaN or infinity."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)


class Units(SimbenchModel):
    """How the scenario file writes angles and lengths."""

    angle: Literal["rad", "deg"] = "rad"
    length: Literal["m", "mm"] = "m"

    @property
    def angle_factor(self) -> float:
        """Radians per unit of the file's angles."""
        return _DEG if self.angle == "deg" else 1.0

    @property
    def length_factor(self) -> float:
        """Metres per unit of the file's lengths."""
        return 1e-3 if self.length == "mm" else 1.0

    def factor(self, kind: str) -> float:
        """SI per file unit for a joint of this kind."""
        return self.angle_factor if kind == REVOLUTE else self.length_factor

    def name(self, kind: str) -> str:
        """The file's unit for a joint of this kind."""
        return self.angle if kind == REVOLUTE else self.length


def _units(info: ValidationInfo) -> Units:
    return (info.context or {}).get("units", Units())


def _to_angle(value: float, info: ValidationInfo) -> float:
    return value * _units(info).angle_factor


def _to_length(value: float, info: ValidationInfo) -> float:
    return value * _units(info).length_factor


def _to_position(value: list[float], info: ValidationInfo) -> list[float]:
    if len(value) != 3:
        raise ValueError(f"expected a point [x, y, z], got {len(value)} values")
    return [v * _units(info).length_factor for v in value]


def _to_direction(value: list[float]) -> list[float]:
    if len(value) != 3:
        raise ValueError(f"expected a direction [x, y, z], got {len(value)} values")
    norm = float(np.linalg.norm(value))
    if norm < 1e-9:
        raise ValueError("expected a direction, got a zero vector")
    return [v / norm for v in value]


def _other_unit_hint(value: float, kind: str, lo: float, hi: float, units: Units) -> str:
    """A hint when the value fits the range in the other unit: degrees read as radians, or mm as m."""
    if kind == REVOLUTE and units.angle == "rad" and lo <= value * _DEG <= hi:
        return " (written in degrees? say so with units: {angle: deg})"
    if kind != REVOLUTE and units.length == "m" and lo <= value * 1e-3 <= hi:
        return " (written in millimetres? say so with units: {length: mm})"
    return ""


def _to_joints(value: list[float], info: ValidationInfo) -> list[float]:
    robot: Robot = info.context["robot"]
    units = _units(info)
    if len(value) != robot.dof:
        raise ValueError(f"expected {robot.dof} values, one per joint ({', '.join(robot.joints)}), got {len(value)}")
    q = []
    for name, kind, lo, hi, v in zip(robot.joints, robot.kinds, robot.lower, robot.upper, value):
        k = units.factor(kind)
        si = v * k
        if not lo - 1e-12 <= si <= hi + 1e-12:
            unit = units.name(kind)
            raise ValueError(f"{name} = {v:g} {unit} is outside the joint range [{lo / k:g}, {hi / k:g}] {unit}"
                             + _other_unit_hint(v, kind, lo, hi, units))
        q.append(si)
    return q


def _check_name(value: str) -> str:
    if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]*", value):
        raise ValueError(f"expected letters, digits, '_', '.' or '-', starting with a letter or digit (it names "
                         f"the output folder), got {value!r}")
    return value


def _to_gains(value: float | list[float], info: ValidationInfo) -> list[float]:
    robot: Robot = info.context["robot"]
    values = [value] * robot.dof if isinstance(value, (int, float)) else value
    if len(values) != robot.dof:
        raise ValueError(f"expected one gain for every servo or {robot.dof} values, one per joint "
                         f"({', '.join(robot.joints)}), got {len(values)}")
    if any(v < 0 for v in values):
        raise ValueError(f"expected gains >= 0, got {min(values):g}")
    return [float(v) for v in values]


Number = float
Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]
Angle = Annotated[float, AfterValidator(_to_angle)]
Length = Annotated[float, AfterValidator(_to_length)]
PositiveAngle = Annotated[float, Field(gt=0), AfterValidator(_to_angle)]
NonNegativeAngle = Annotated[float, Field(ge=0), AfterValidator(_to_angle)]
PositiveLength = Annotated[float, Field(gt=0), AfterValidator(_to_length)]
Position = Annotated[list[float], AfterValidator(_to_position)]
Direction = Annotated[list[float], AfterValidator(_to_direction)]
JointVector = Annotated[list[float], AfterValidator(_to_joints)]
Gains = Annotated[float | list[float], AfterValidator(_to_gains)]  # SI, whatever the file's units
Name = Annotated[str, Field(max_length=100), AfterValidator(_check_name)]


class Orientation(SimbenchModel):
    """A rotation, written in one of three conventions.

    zyx     [yaw, pitch, roll]: R = Rz(yaw) Ry(pitch) Rx(roll) (intrinsic Z-Y-X Euler angles), in the file's angle
            unit;
    quat    [w, x, y, z], any non-zero length (it is normalised);
    rotvec  rotation vector, its length the angle in the file's angle unit.
    """

    convention: Literal["zyx", "quat", "rotvec"]
    value: list[float]

    @model_validator(mode="after")
    def _check(self, info: ValidationInfo) -> "Orientation":
        size = 4 if self.convention == "quat" else 3
        if len(self.value) != size:
            raise ValueError(f"{self.convention} expects {size} values, got {len(self.value)}")
        if self.convention == "quat" and np.linalg.norm(self.value) < 1e-9:
            raise ValueError("a quaternion of zero length is no rotation")
        if self.convention == "quat":
            return self
        k = _units(info).angle_factor
        return self.model_copy(update={"value": [v * k for v in self.value]})

    def matrix(self) -> np.ndarray:
        """The 3x3 rotation matrix."""
        if self.convention == "zyx":
            return Rotation.from_euler("ZYX", self.value).as_matrix()
        if self.convention == "quat":
            w, x, y, z = self.value
            return Rotation.from_quat([x, y, z, w]).as_matrix()
        return Rotation.from_rotvec(self.value).as_matrix()
