"""Building blocks of the scenario schema: strict models and quantities converted to SI at load time.

A scenario states its units once (`units: {angle: deg, length: mm}`); values are converted while validated, so
that everything downstream is SI, and an error quotes the value in the file's own units.
"""

from __future__ import annotations

import re
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import AfterValidator, Field, ValidationInfo, model_validator

from simbench.api import PRISMATIC, REVOLUTE, Robot
from simbench.core.errors import ScenarioError
from simbench.core.frozen import SimbenchModel

_DEG = np.pi / 180.0

# The ranges of the schema's quantities, in SI: wide enough for any desk-size mechanism and its tasks, narrow
# enough that nothing overflows or runs for ever on the way. A value outside is a typo or a unit mix-up.
MAX_ANGLE = 2 * np.pi * 10  # rad: ten turns
MAX_LENGTH = 10.0  # m: the workspace's scale
MIN_LENGTH = 1e-6  # m: below what the simulation resolves
MAX_COMPONENT = 1e6  # items of a vector that is normalised (a direction, a quaternion)
MIN_NORM = 1e-6  # and its least length
MAX_GAIN = 1e9  # servo gains, SI
MAX_NAME = 100  # characters of a name (it names a folder)


class Units(SimbenchModel):
    """How the scenario file writes angles and lengths (`units: {angle: deg, length: mm}`).

    Attributes:
        angle: `rad` (default) or `deg`.
        length: `m` (default) or `mm`.
    """

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
        """SI per file unit for a joint of this kind.

        Args:
            kind: `REVOLUTE` or `PRISMATIC`.

        Returns:
            Radians per angle unit, or metres per length unit.
        """
        return self.angle_factor if kind == REVOLUTE else self.length_factor

    def name(self, kind: str) -> str:
        """The file's unit for a joint of this kind.

        Args:
            kind: `REVOLUTE` or `PRISMATIC`.

        Returns:
            `rad` or `deg`, or `m` or `mm`.
        """
        return self.angle if kind == REVOLUTE else self.length


def _units(info: ValidationInfo) -> Units:
    return (info.context or {}).get("units", Units())


def _bounded(value: float, factor: float, lo: float, hi: float, unit: str, what: str,
             low_open: bool = False) -> float:
    """`value` in the file's unit converted to SI (x `factor`), or ValueError quoting the range in that unit."""
    si = value * factor
    if not ((lo < si) if low_open else (lo <= si)) or not si <= hi:
        bracket = "(" if low_open else "["
        raise ValueError(f"expected {what} in {bracket}{lo / factor:.6g}, {hi / factor:.6g}] {unit}, got "
                         f"{value:.6g} {unit}")
    return si


def _quantity(kind: str, lo: float, hi: float, low_open: bool = False):
    """An angle (REVOLUTE) or a length in the file's unit, converted to SI and kept within [lo, hi]."""
    def convert(value: float, info: ValidationInfo) -> float:
        units = _units(info)
        what = "an angle" if kind == REVOLUTE else "a length"
        return _bounded(value, units.factor(kind), lo, hi, units.name(kind), what, low_open)
    return AfterValidator(convert)


def _to_position(value: list[float], info: ValidationInfo) -> list[float]:
    if len(value) != 3:
        raise ValueError(f"expected a point [x, y, z], got {len(value)} values")
    units = _units(info)
    return [_bounded(v, units.length_factor, -MAX_LENGTH, MAX_LENGTH, units.length, "coordinates") for v in value]


def _finite_norm(value: list[float], what: str) -> float:
    """The length of a vector to normalise: items within +-MAX_COMPONENT (a finite length), the length at least
    MIN_NORM (a direction, not rounding noise)."""
    if any(abs(v) > MAX_COMPONENT for v in value):
        raise ValueError(f"expected {what} with items within +-{MAX_COMPONENT:g} (it is normalised), got "
                         f"{max(value, key=abs):.6g}")
    norm = float(np.linalg.norm(value))
    if norm == 0:
        raise ValueError(f"expected {what}, got a zero vector")
    if norm < MIN_NORM:
        raise ValueError(f"expected {what} of length at least {MIN_NORM:g} (it is normalised), got length "
                         f"{norm:.3g}")
    return norm


def _to_direction(value: list[float]) -> list[float]:
    if len(value) != 3:
        raise ValueError(f"expected a direction [x, y, z], got {len(value)} values")
    norm = _finite_norm(value, "a direction")
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
        scale = MAX_ANGLE if kind == REVOLUTE else MAX_LENGTH  # a joint without limits turns a few times at most
        lo, hi = max(lo, -scale), min(hi, scale)
        k = units.factor(kind)
        si = v * k
        if not lo - 1e-12 <= si <= hi + 1e-12:
            unit = units.name(kind)
            raise ValueError(f"{name} = {v:g} {unit} is outside the joint range [{lo / k:g}, {hi / k:g}] {unit}"
                             + _other_unit_hint(v, kind, lo, hi, units))
        q.append(si)
    return q


def _check_name(value: str) -> str:
    if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,99}", value):
        raise ValueError(f"expected letters, digits, '_', '.' or '-', starting with a letter or digit (it names "
                         f"the output folder), got {value!r}")
    return value


def file_name(stem: str, source: str) -> str:
    """The name of a scenario without a `name:` field: its file's stem, held to the rule of a `name:`.

    A file `..yaml` would otherwise name `renders/` itself.

    Args:
        stem: The file's stem.
        source: The file, for the error.

    Returns:
        The stem.

    Raises:
        ScenarioError: The stem cannot name an output folder.
    """
    try:
        return _check_name(stem)
    except ValueError as err:
        raise ScenarioError(source, "name", f"not given, and the file's name cannot stand in for it: {err}; add a "
                                            "name: field or rename the file") from None


def _to_gains(value: float | list[float], info: ValidationInfo) -> list[float]:
    robot: Robot = info.context["robot"]
    values = [value] * robot.dof if isinstance(value, (int, float)) else value
    if len(values) != robot.dof:
        raise ValueError(f"expected one gain for every servo or {robot.dof} values, one per joint "
                         f"({', '.join(robot.joints)}), got {len(values)}")
    if any(not 0 <= v <= MAX_GAIN for v in values):
        bad = next(v for v in values if not 0 <= v <= MAX_GAIN)
        raise ValueError(f"expected gains in [0, {MAX_GAIN:g}], got {bad:.6g}")
    return [float(v) for v in values]


def seconds(lo: float, hi: float, low_open: bool = False) -> Any:
    """The type of a time in seconds within bounds.

    Args:
        lo: The least time (s).
        hi: The greatest time (s).
        low_open: Whether `lo` itself is refused.

    Returns:
        An annotated float type for a schema's field.
    """
    return Annotated[float, AfterValidator(lambda value: _bounded(value, 1.0, lo, hi, "s", "a time", low_open))]


Angle = Annotated[float, _quantity(REVOLUTE, -MAX_ANGLE, MAX_ANGLE)]
"""A joint or path angle in the file's angle unit, in radians once loaded: a few turns either way."""
PositiveAngle = Annotated[float, _quantity(REVOLUTE, 0.0, np.pi, low_open=True)]
"""An angle in (0, pi] rad (a radius, clearance or tolerance on a sphere), in the file's angle unit."""
NonNegativeAngle = Annotated[float, _quantity(REVOLUTE, 0.0, np.pi)]
"""An angle in [0, pi] rad, in the file's angle unit."""
PositiveLength = Annotated[float, _quantity(PRISMATIC, MIN_LENGTH, MAX_LENGTH)]
"""A length in the file's length unit, in metres once loaded, from a micrometre to the workspace's scale."""
Position = Annotated[list[float], AfterValidator(_to_position)]
"""A point [x, y, z] in the file's length unit, in metres once loaded."""
Direction = Annotated[list[float], AfterValidator(_to_direction)]
"""A direction [x, y, z] of any non-zero length, a unit vector once loaded."""
JointVector = Annotated[list[float], AfterValidator(_to_joints)]
"""One value per joint of the scenario's robot, each in the file's unit of its kind and within its range, SI once
loaded."""
Gains = Annotated[float | list[float], AfterValidator(_to_gains)]
"""Servo gains, SI whatever the file's units: one for every joint, or one per joint."""
Weight = Annotated[float, Field(ge=0, le=1e3)]
"""A weight of a cost's term, 0 to 1000."""
Name = Annotated[str, Field(max_length=MAX_NAME), AfterValidator(_check_name)]
"""A name that can name a file: letters, digits, '_', '.' or '-', starting with a letter or digit."""


class Orientation(SimbenchModel):
    """A rotation, as a task writes it; angles in the file's unit, radians once loaded.

    Attributes:
        convention: `zyx` [yaw, pitch, roll] (R = Rz(yaw) Ry(pitch) Rx(roll), intrinsic), `quat` [w, x, y, z] of
            any non-zero length, or `rotvec` (its length the angle).
        value: The rotation's numbers in that convention.
    """

    convention: Literal["zyx", "quat", "rotvec"]
    value: list[float]

    @model_validator(mode="after")
    def _check(self, info: ValidationInfo) -> "Orientation":
        size = 4 if self.convention == "quat" else 3
        if len(self.value) != size:
            raise ValueError(f"{self.convention} expects {size} values, got {len(self.value)}")
        if self.convention == "quat":
            _finite_norm(self.value, "a quaternion")
            return self
        units = _units(info)
        value = [_bounded(v, units.angle_factor, -MAX_ANGLE, MAX_ANGLE, units.angle, "angles")
                 for v in self.value]
        if self.convention == "rotvec" and np.linalg.norm(value) > MAX_ANGLE:
            raise ValueError(f"expected a rotation vector of length at most {MAX_ANGLE / units.angle_factor:.6g} "
                             f"{units.angle}, got {np.linalg.norm(value) / units.angle_factor:.6g}")
        object.__setattr__(self, "value", tuple(value))  # in radians from here on (the model is frozen)
        return self

    def matrix(self) -> np.ndarray:
        """The rotation as a matrix.

        Returns:
            The 3x3 rotation matrix.
        """
        from scipy.spatial.transform import Rotation  # scipy.spatial is large: loaded by the runs that ask only

        if self.convention == "zyx":
            return Rotation.from_euler("ZYX", self.value).as_matrix()
        if self.convention == "quat":
            return Rotation.from_quat(self.value, scalar_first=True).as_matrix()
        return Rotation.from_rotvec(self.value).as_matrix()
