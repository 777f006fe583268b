"""Closed-loop control from outside simbench: a controller class registered through the entry-point group
`simbench.controllers`, and a policy factory registered through `simbench.policies` (PD_POLICY), which a scenario
names as `policy: joint_pd_policy`.

Both are the same law, a joint-space PD with velocity feed-forward on torque actuation,

    tau = Kp (q_ref - q) + Kd (qd_ref - qd),

the first written against simbench.api.Controller (it sees the measured State every step), the second as a
plain callable on the observation dictionary (what a learned policy would get).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any

import numpy as np
from pydantic import Field
from simbench.api import Array, Controller, ControlSettings, Plant, PolicyFactory, State
from simbench.api.trajectory import JointTrajectory

if TYPE_CHECKING:  # simbench.api names the scenario's type for annotations; at run time it is simbench.Scenario
    from simbench.api import Scenario

KP = (300.0, 150.0, 40.0)  # N m/rad: the example's servo stiffness (models/planar3r.xml)
KD = (12.0, 4.0, 1.0)  # N m s/rad


class JointPDSettings(ControlSettings):
    """The `control:` fields of joint_pd: one scale on both gains (1: the servos' own)."""

    scale: Annotated[float, Field(gt=0, le=100)] = 1.0


class JointPD(Controller):
    """Joint PD on torque actuation, registered from this package's entry point."""

    name = "joint_pd"
    description = "joint PD on torques (simbench_planar3r example)"
    settings = JointPDSettings
    actuation = "torque"

    def __init__(self, settings: JointPDSettings):
        self.scale = settings.scale

    def bind(self, plant: Plant, trajectory: JointTrajectory) -> None:
        self.actuators, self.nu = plant.actuators, plant.model.nu
        self.q_ref, self.qd_ref = trajectory.q_ref, trajectory.qd_ref

    def commands(self, state: State) -> Array:
        ctrl = np.zeros(self.nu)
        ctrl[self.actuators] = self.scale * (np.array(KP) * (self.q_ref[state.k] - state.q)
                                             + np.array(KD) * (self.qd_ref[state.k] - state.qd))
        return ctrl

    def revise(self, k0: int, q_ref: Array, qd_ref: Array) -> None:
        self.q_ref, self.qd_ref = q_ref, qd_ref

    def gains(self) -> dict[str, Any]:
        return {"kp": [self.scale * k for k in KP], "kd": [self.scale * k for k in KD]}


def make_pd_policy(scenario: Scenario):
    """A policy for `scenario`: the observation's joint errors to torques (the scenario says action: torque)."""
    kp, kd = np.array(KP), np.array(KD)

    def act(observation: dict[str, np.ndarray]) -> np.ndarray:
        return kp * (observation["q_ref"] - observation["q"]) + kd * (observation["qd_ref"] - observation["qd"])

    return act


PD_POLICY = PolicyFactory("joint_pd_policy", "joint PD on torques as a policy (simbench_planar3r example)",
                          make_pd_policy)
