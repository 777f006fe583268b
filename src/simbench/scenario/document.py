"""Scenario files: the schema, loading, and validation whose errors name the file, the field and what is expected.

A scenario is a YAML mapping (docs/guide/scenarios.md, field by field): a robot, a planner and its `task:`, and how
to time, simulate, analyse and render it. Everything is converted to SI (radians, metres) while it is validated.
"""

from __future__ import annotations

import os
from functools import cache
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field, PrivateAttr, ValidationError, ValidationInfo, create_model, field_validator, model_validator

from simbench import api
from simbench.api import registry
from simbench.api.events import KINDS
from simbench.core.errors import ScenarioError
from simbench.maths.timing import TimeLaw
from simbench.scenario import robot_mapping
from simbench.scenario.schema import (Gains, Name, PositiveAngle, PositiveLength, SimbenchModel, Units, file_name,
                                      seconds)
from simbench.scenario.validation import describe, did_you_mean, kind_of, read_yaml


class Timing(SimbenchModel):
    """The time law along the path, its duration, and how long to hold the goal afterwards."""

    law: Literal["cubic", "quintic", "4567", "trapezoidal"] = "quintic"
    duration: seconds(0.01, 86_400.0)
    hold: seconds(0.0, 60.0) = 0.5
    accel_fraction: Annotated[float, Field(ge=1e-6, le=0.5)] = 0.25  # below, 1 / (f (1 - f)) may overflow

    def law_fn(self) -> TimeLaw:
        """The time law s(t)."""
        return TimeLaw(self.law, self.duration, self.accel_fraction)


class Sim(SimbenchModel):
    """Physics settings (the guide's Scenarios page, `sim`); the timestep is also the control period."""

    timestep: seconds(1e-5, 0.01) | None = None
    settle: seconds(0.0, 10.0) = 0.2
    velocity_feedforward: bool = True
    kp: Gains | None = None
    kv: Gains | None = None
    force_limits: bool = True
    gravity_compensation: bool = True
    record_every: Annotated[int, Field(ge=1, le=1_000_000)] = 1


class Thresholds(SimbenchModel):
    """The `analysis:` section: what counts as near a singular set or a joint limit, and the tolerances a run must
    keep to end `ok` (the guide's Scenarios page, `analysis`)."""

    near_angle: PositiveAngle = float(np.deg2rad(2.0))
    near_length: PositiveLength = 0.002
    limit_angle: PositiveAngle = float(np.deg2rad(0.5))
    limit_length: PositiveLength = 0.0005
    path_tolerance: PositiveLength = 0.005
    goal_tolerance: PositiveLength = 0.001
    orientation_tolerance: PositiveAngle = float(np.deg2rad(2.0))
    goal_orientation_tolerance: PositiveAngle = float(np.deg2rad(0.5))


class Render(SimbenchModel):
    """Video settings. `pretty` (shadows, reflections, multisampling) costs several times `fast` on a CPU."""

    width: Annotated[int, Field(ge=64, le=1920, multiple_of=2)] = 640
    height: Annotated[int, Field(ge=64, le=1080, multiple_of=2)] = 480
    fps: Annotated[int, Field(ge=1, le=120)] = 30
    camera: str | None = None
    quality: Literal["fast", "pretty"] = "fast"
    trace: bool = True


class Expect(SimbenchModel):
    """A scenario meant to show a failure says which: the status and the kinds of violation (simbench.api.events.KINDS)
    the run must end with, and why. The run's status stays what it is; the CLI exits 0 if it is as expected."""

    status: Literal["ok", "limits"] = "limits"
    violations: list[str] = []
    reason: str = ""

    @field_validator("violations")
    @classmethod
    def _known(cls, kinds: list[str], info: ValidationInfo) -> list[str]:
        robot = (info.context or {}).get("robot")
        known = list(KINDS) + list(robot.breaking if robot is not None else ())
        for kind in kinds:
            if kind not in known:
                raise ValueError(f"unknown violation {kind!r} (expected one of: {', '.join(known)})"
                                 f"{did_you_mean(kind, known)}")
        return kinds

    @model_validator(mode="after")
    def _consistent(self) -> "Expect":
        if (self.status == "ok") == bool(self.violations):
            raise ValueError("status 'limits' needs the violations expected, and 'ok' none")
        return self


class Scenario(SimbenchModel):
    """A scenario, validated and in SI: what a scenario file holds (see the guide's Scenarios page).

    The fields every scenario has; `task` is added per planner (an instance of its `Planner.task`), and
    `control` is an instance of its controller's `Controller.settings`.

    Attributes:
        name: The scenario's name (default: the file's stem), naming its output folder.
        description: One line on what it shows.
        robot: A registered robot's name, or the name of the arm a robot mapping derives (`robot: {model: ...}`).
        planner: A registered planner's name.
        units: How the file writes angles and lengths.
        timing: The time law, its duration and the hold at the goal.
        sim: The physics: timestep, gains, force limits, recording stride.
        analysis: What counts as near, and the tolerances a run must keep to end `ok`.
        control: The `control:` section: which controller, and its own fields.
        render: The video's settings.
        expect: What the scenario expects of its run (status, violations), or None.
    """

    name: Name | None = None
    description: str = ""
    robot: str  # a registered robot's name, or the name of the arm a robot mapping derives (robots.robot_mapping)
    planner: str
    units: Units = Units()
    timing: Timing
    sim: Sim = Sim()
    analysis: Thresholds = Thresholds()
    control: api.ControlSettings = api.ControlSettings()
    render: Render = Render()
    expect: Expect | None = None
    _source: str | None = PrivateAttr(None)
    _robot: api.Robot | None = PrivateAttr(None)  # the arm derived from a robot mapping; None: a registered robot

    @property
    def source(self) -> str | None:
        """The file this scenario was read from, if any."""
        return self._source

    @property
    def robot_def(self) -> api.Robot:
        """The Robot this scenario runs."""
        return self._robot if self._robot is not None else registry.robots()[self.robot]

    @property
    def planner_def(self) -> api.Planner:
        """The Planner this scenario uses."""
        return registry.planners()[self.planner]

    @property
    def controller_def(self) -> type[api.Controller]:
        """The Controller class this scenario runs with."""
        return registry.controllers()[self.control.controller]


def _scenario_class(planner_name: str, controller_name: str = "servo") -> type[Scenario]:
    """The schema of a scenario with this planner's `task:` and this controller's `control:` section: one class a
    pair, however it is asked for (pickle checks that the class it finds by name is the scenario's)."""
    return _made_class(planner_name, controller_name)


@cache
def _made_class(planner_name: str, controller_name: str) -> type[Scenario]:
    """The class `_scenario_class` gives, made once a pair."""
    task = registry.planners()[planner_name].task
    settings = registry.controllers()[controller_name].settings
    return create_model(f"{_CLASS_PREFIX}{planner_name}_{controller_name}", __base__=Scenario, task=(task, ...),
                        control=(settings, Field(default_factory=settings)))


_CLASS_PREFIX = "Scenario_"


def __getattr__(name: str) -> type[Scenario]:
    """A scenario class by the name `_scenario_class` gave it (`Scenario_<planner>_<controller>`), made anew in
    a process that has not made it yet: pickle finds a scenario's class by its name in this module."""
    if name.startswith(_CLASS_PREFIX):
        parts = name[len(_CLASS_PREFIX):]
        for cut in (i for i, char in enumerate(parts) if char == "_"):  # names may hold "_": try each split
            planner_name, controller_name = parts[:cut], parts[cut + 1:]
            if planner_name in registry.planners() and controller_name in registry.controllers():
                return _scenario_class(planner_name, controller_name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file.

    Args:
        path: The scenario file (YAML).

    Returns:
        The scenario, in SI.

    Raises:
        ScenarioError: The file cannot be used; the error names the field at fault and what is expected.
    """
    path = Path(path)
    scenario = parse_scenario(read_yaml(path), str(path), default_name=path.stem)
    scenario._source = str(path)
    return scenario


def as_scenario(value: Scenario | str | os.PathLike, caller: str) -> Scenario:
    """A Scenario, or the one in the file at a path; TypeError saying what to pass for anything else."""
    if isinstance(value, Scenario):
        return value
    if isinstance(value, (str, os.PathLike)):
        return load_scenario(value)
    raise TypeError(f"{caller} expects a Scenario (simbench.load_scenario(path)) or the path of a scenario file, "
                    f"got {type(value).__name__}")


def parse_scenario(raw: Any, source: str, default_name: str = "scenario") -> Scenario:
    """Validate a scenario already read into Python objects."""
    if not isinstance(raw, dict):
        raise ScenarioError(source, None, f"expected a mapping of scenario fields, got {kind_of(raw)}")
    try:
        units = Units.model_validate(raw.get("units", {}))
    except ValidationError as err:
        raise ScenarioError(source, *describe(err, Units, raw.get("units"), prefix=("units",))) from None
    derived = robot_mapping.is_mapping(raw.get("robot"))
    robot = (robot_mapping.load_robot(raw["robot"], source, units) if derived
             else registry.robots()[_name_field(raw, "robot", registry.robots(), source)])
    planner = registry.planners()[_name_field(raw, "planner", registry.planners(), source)]
    refusal = planner.refuses(robot)
    if refusal:
        raise ScenarioError(source, "planner", refusal)
    cls = _scenario_class(planner.name, _controller_name(raw, source))
    try:
        scenario = cls.model_validate({**raw, "robot": robot.name} if derived else raw,
                                      context={"robot": robot, "units": units})
    except ValidationError as err:
        raise ScenarioError(source, *describe(err, cls, raw)) from None
    if scenario.name is None:
        scenario = scenario.model_copy(update={"name": file_name(default_name, source)})
    if derived:
        scenario._robot = robot
    cameras = robot.cameras()
    if scenario.render.camera is not None and scenario.render.camera not in cameras:
        raise ScenarioError(source, "render.camera", f"no camera '{scenario.render.camera}' in the "
                                                     f"{robot.name} scene (expected one of: {', '.join(cameras)})")
    problem = planner.check(scenario, robot)
    if problem:
        raise ScenarioError(source, *problem)
    return scenario


def _controller_name(raw: dict, source: str) -> str:
    """The controller the `control:` section names (default servo), checked against the registry."""
    control = raw.get("control", {})
    if not isinstance(control, dict):
        raise ScenarioError(source, "control", f"expected a mapping (controller: name, and its fields), got "
                                               f"{kind_of(control)}")
    if "controller" not in control:
        return "servo"
    return _name_field(control, "controller", registry.controllers(), source, path="control.controller")


def _name_field(raw: dict, field: str, known: dict, source: str, path: str | None = None) -> str:
    """raw[field], a registered name; ScenarioError naming `path` (default the field) if missing, unknown or broken."""
    value, path = raw.get(field), path or field
    options = ", ".join(sorted(known))
    if value is None:
        raise ScenarioError(source, path, f"missing: this field is required (one of: {options})")
    if isinstance(value, str) and value in registry.broken(field):
        raise ScenarioError(source, path, registry.broken(field)[value])
    if not isinstance(value, str) or value not in known:
        raise ScenarioError(source, path, f"unknown {field} {value!r} (expected one of: {options})"
                                          f"{did_you_mean(str(value), known)}")
    return value
