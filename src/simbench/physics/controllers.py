"""The shipped position servo (simbench.api.Controller); computed torque is simbench.physics.computed_torque, a user's
policy simbench.physics.policy.

`servo`: each actuator a position servo, force = kp (ctrl - q) - kv qd. With velocity feed-forward the command
ctrl = q_ref + ((kv + b) / kp) qd_ref makes it a PD on both errors that also cancels the joint's viscous friction b
on the plan, as an industrial joint controller does. Commands are clamped to the control ranges and depend on the
plan alone: the servo is open-loop, stepped through `mujoco.rollout` a chunk of commands at a time (api.Commands).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from simbench.api import Array, Commands, Controller, State
from simbench.api.trajectory import JointTrajectory

if TYPE_CHECKING:
    from simbench.core.plant import Plant
    from simbench.scenario import Scenario


class Servo(Controller):
    """The MJCF's position servos with velocity feed-forward (`sim.velocity_feedforward`); commands found as the
    run asks for them (_Targets), not held for every step."""

    name = "servo"
    description = "position servo with velocity feed-forward (the MJCF's position actuators)"

    def __init__(self, feedforward: bool = True):
        self.feedforward = feedforward
        self._plant: Plant | None = None
        self._refs: tuple[Array, Array] | None = None  # (q_ref, qd_ref): the plan's, or as its feedback revised them

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> Servo:
        return cls(scenario.sim.velocity_feedforward)

    def bind(self, plant: Plant, trajectory: JointTrajectory) -> None:
        self._plant = plant
        self._refs = trajectory.q_ref, trajectory.qd_ref

    def open_loop(self) -> Commands:
        assert self._refs is not None, "bind() first"
        return _Targets(self)

    def commands(self, state: State) -> Array:
        assert self._refs is not None, "bind() first"
        q_ref, qd_ref = self._refs
        k = min(state.k, len(q_ref) - 1)
        return self.targets(q_ref[k:k + 1], qd_ref[k:k + 1])[0]

    def revise(self, k0: int, q_ref: Array, qd_ref: Array) -> None:
        self._refs = q_ref, qd_ref  # the commands follow the references they are given, every row

    def gains(self) -> dict[str, Any]:
        assert self._plant is not None, "bind() first"
        return {**self._plant.gains(), "velocity_feedforward": self.feedforward}

    def targets(self, q_ref: Array, qd_ref: Array) -> Array:
        """Actuator controls (N, nu) for joint references, clamped to the control ranges."""
        assert self._plant is not None, "bind() first"
        plant = self._plant
        m = plant.model
        ctrl = np.zeros((q_ref.shape[0], m.nu))
        act = plant.actuators
        ctrl[:, act] = q_ref
        if self.feedforward:
            kp = m.actuator_gainprm[act, 0]
            kv = -m.actuator_biasprm[act, 2] + m.dof_damping[plant.dof_adr]
            ctrl[:, act] += qd_ref * (kv / kp)
        limited = m.actuator_ctrllimited.astype(bool)
        lo, hi = m.actuator_ctrlrange.T
        ctrl[:, limited] = np.clip(ctrl[:, limited], lo[limited], hi[limited])
        return ctrl


class _Targets(Commands):
    """Servo.targets of the references (as revised so far) at the rows asked for; the last slice asked for is kept
    while the references are the same (a run checks, steps and records the same chunk in turn)."""

    def __init__(self, servo: Servo):
        self.servo = servo
        self._kept: tuple[tuple, int, Array] | None = None  # (the references, the first row, their commands)

    @property
    def shape(self) -> tuple[int, int]:
        assert self.servo._plant is not None and self.servo._refs is not None
        return len(self.servo._refs[0]), self.servo._plant.model.nu

    def rows(self, k):
        refs = self.servo._refs
        n = len(refs[0])
        kept = self._kept if self._kept is not None and self._kept[0] is refs else None
        if isinstance(k, slice):
            first, stop, step = k.indices(n)
            if step == 1 and stop > first:
                if kept is not None and kept[1] <= first and stop <= kept[1] + len(kept[2]):
                    return kept[2][first - kept[1]:stop - kept[1]].copy()
                found = self.servo.targets(refs[0][k], refs[1][k])
                self._kept = refs, first, found.copy()  # the one returned is the caller's to change
                return found
        elif kept is not None and k.size:
            local = np.where(k < 0, k + n, k) - kept[1]
            if local.min() >= 0 and local.max() < len(kept[2]):
                return kept[2][local]
        return self.servo.targets(refs[0][k], refs[1][k])
