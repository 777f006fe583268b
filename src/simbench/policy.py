"""A user's policy as a controller: a Python object named in the scenario, asked for an action every step.

    control:
      controller: policy
      policy: mypackage.module:make_policy    # a factory, called with the loaded Scenario
      action: torque                          # or position: targets for the scene's position servos

The factory returns a callable; every control step it gets the observation (simbench.observation: the measured
joints and tool, the plan's references now and ahead) and returns one action per robot joint: torques or forces
on the joints' actuators made motors, or position targets of the scene's servos. A name that does not import
or a factory that raises is refused before the run (ScenarioError naming control.policy); an action that is not
a finite vector of the robot's joint count stops the run with the time (ControlError).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field

from simbench.api import Array, Controller, ControlSettings, State
from simbench.errors import ScenarioError
from simbench.observation import observation
from simbench.plant import Plant
from simbench.scenario import Scenario
from simbench.trajectory import JointTrajectory

_TARGET = r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*:[A-Za-z_][A-Za-z0-9_]*$"


class PolicySettings(ControlSettings):
    """The `control:` fields of policy."""

    policy: Annotated[str, Field(pattern=_TARGET, max_length=300)]
    action: Literal["torque", "position"] = "torque"


class Policy(Controller):
    """Every step, the observation to the user's callable, and its action to the joints' actuators."""

    name = "policy"
    description = "a Python callable named in the scenario (package.module:factory), torques or position targets"
    reads_past = False  # the observation's references are the step's and those ahead of it
    settings = PolicySettings

    def __init__(self, act: Callable[[dict], Any], action: Literal["torque", "position"] = "torque",
                 target: str = "callable"):
        self.act = act
        self.actuation = action
        self.target = target

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> Policy:
        settings = scenario.control
        assert isinstance(settings, PolicySettings)
        return cls(make(settings.policy, scenario), settings.action, settings.policy)

    def bind(self, plant: Plant, trajectory: JointTrajectory) -> None:
        self.plant = plant
        self.q_ref, self.qd_ref, self.tool_ref = trajectory.q_ref, trajectory.qd_ref, trajectory.tool_ref

    def commands(self, state: State) -> Array:
        obs = observation(self.plant, state, self.q_ref, self.qd_ref, self.tool_ref)
        action = np.asarray(self.act(obs), dtype=float)
        dof = self.plant.robot.dof
        if action.shape != (dof,):
            raise ValueError(f"the policy's action has shape {action.shape}; ({dof},) expected, one per joint "
                             f"({', '.join(self.plant.robot.joints)})")
        ctrl = np.zeros(self.plant.model.nu)
        ctrl[self.plant.actuators] = action
        return ctrl

    def revise(self, k0: int, q_ref: Array, qd_ref: Array) -> None:
        self.q_ref, self.qd_ref = q_ref, qd_ref

    def gains(self) -> dict[str, Any]:
        return {"policy": self.target, "action": self.actuation}


def make(target: str, scenario: Scenario) -> Callable[[dict], Any]:
    """The callable the factory `package.module:name` makes for the scenario; ScenarioError saying what failed."""
    module_name, _, attr = target.partition(":")
    where = scenario.source or scenario.name or "scenario"
    try:
        factory = getattr(importlib.import_module(module_name), attr)
    except Exception as err:  # any failure of the user's import: named, not a traceback
        raise ScenarioError(where, "control.policy", f"cannot import {target}: {type(err).__name__}: {err}") \
            from None
    try:
        act = factory(scenario)
    except Exception as err:  # the user's factory
        raise ScenarioError(where, "control.policy", f"{target} raised {type(err).__name__}: {err}") from None
    if not callable(act):
        raise ScenarioError(where, "control.policy", f"{target} returned {type(act).__name__}, not a callable "
                                                     "taking the observation")
    return act
