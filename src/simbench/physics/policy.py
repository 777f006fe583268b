"""A user's policy as a controller: a factory of callables a scenario names (`control.policy`: a registered name,
or `package.module:factory`), asked every step for one action per joint (torques, or position targets) from the
observation (simbench.physics.observation).

A scenario is data: one that names a module is run only when allowed (`--allow-code`, `allow_code=True`), checked
before anything is imported (`refuse_code`). A factory that cannot be made is refused before the run
(ScenarioError); a bad action stops the run at its time (ControlError).
"""

from __future__ import annotations

import difflib
import importlib
from collections.abc import Callable
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field, field_validator

from simbench.api import Array, Controller, ControlSettings, State, registry
from simbench.api.trajectory import JointTrajectory
from simbench.core import interrupts
from simbench.core.errors import ScenarioError, described
from simbench.core.plant import Plant
from simbench.physics.observation import observation
from simbench.scenario import Scenario

_IDENTIFIER = r"[A-Za-z_][A-Za-z0-9_]*"
# A registered name, or a module path: package.module:factory.
_TARGET = rf"^{_IDENTIFIER}((\.{_IDENTIFIER})*:{_IDENTIFIER})?$"


class PolicySettings(ControlSettings):
    """The `control:` fields of policy."""

    policy: Annotated[str, Field(pattern=_TARGET, max_length=300)]
    action: Literal["torque", "position"] = "torque"

    @field_validator("policy")
    @classmethod
    def _registered(cls, name: str) -> str:
        """A name must be a registered policy's; a module path is checked when the run is allowed to import it."""
        if is_code(name):
            return name
        if name in registry.broken("policy"):
            raise ValueError(registry.broken("policy")[name])
        known = registry.policies()
        if name not in known:
            hint = difflib.get_close_matches(name, known, n=1)
            raise ValueError(f"unknown policy {name!r} (expected a registered one: {', '.join(sorted(known)) or 'none'}"
                             f"{f'; did you mean {hint[0]!r}?' if hint else ''}; or package.module:factory, "
                             "imported only with --allow-code)")
        return name


class Policy(Controller):
    """Every step, the observation to the user's callable, and its action to the joints' actuators."""

    name = "policy"
    description = "a registered policy (or with --allow-code a package.module:factory), torques or position targets"
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


def is_code(target: str) -> bool:
    """Whether a control.policy names a module to import (package.module:factory) rather than a registered name."""
    return ":" in target


def refuse_code(scenario: Scenario, allow_code: bool) -> None:
    """ScenarioError if the scenario's policy is a module path and running code it names is not allowed: importing
    it runs that module's code with the user's rights. Nothing is imported here."""
    settings = scenario.control
    if allow_code or not isinstance(settings, PolicySettings) or not is_code(settings.policy):
        return
    raise ScenarioError(scenario.source or scenario.name or "scenario", "control.policy",
                        f"{settings.policy} names Python code to import and run; allow it with --allow-code "
                        "(Python: allow_code=True), or register the policy and name it "
                        "(simbench.api.registry.register_policy)")


def make(target: str, scenario: Scenario) -> Callable[[dict], Any]:
    """The callable the registered policy `target`, or the factory `package.module:name`, makes for the scenario;
    ScenarioError saying what failed. Whatever the user's code raises is its failure, but the user's Ctrl-C."""
    where = scenario.source or scenario.name or "scenario"
    try:
        factory = _factory(target)
    except BaseException as err:  # any failure of the user's import: named, not a traceback
        if interrupts.is_press(err):
            raise
        raise ScenarioError(where, "control.policy", f"cannot import {target}: {described(err)}") from None
    try:
        act = factory(scenario)
    except BaseException as err:  # the user's factory
        if interrupts.is_press(err):
            raise
        raise ScenarioError(where, "control.policy", f"{target} raised {described(err)}") from None
    if not callable(act):
        raise ScenarioError(where, "control.policy", f"{target} returned {type(act).__name__}, not a callable "
                                                     "taking the observation")
    return act


def _factory(target: str) -> Callable[[Scenario], Any]:
    """The registered policy's factory, or the module path's (imported)."""
    if not is_code(target):
        return registry.policies()[target].make
    module_name, _, attr = target.partition(":")
    return getattr(importlib.import_module(module_name), attr)
