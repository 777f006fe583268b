"""The computed-torque controller: the joints' actuators as motors, commanded the model's inverse dynamics at the
plan plus PD on the joint errors,

    tau = tau_ff + Kp (q_ref - q) + Kd (qd_ref - qd)

For a serial arm tau_ff is `mj_inverse` at the planned q_ref, qd_ref, qdd_ref, computed once before the run. With
an equality constraint in the scene (a closed chain, a gripped part) the plan fixes only the actuated joints, so
tau_ff is the effective inertia (a diagonal approximation) times qdd_ref plus the bias force at the measured state.
Default gains per joint: Kp = I w^2, Kd = 2 zeta I w, zeta `damping_ratio`. For a serial arm they are designed for
the plan (simbench.robots.servo_design): I the largest inertia over the planned motion, w `bandwidth` (rad/s) capped
where
the explicit PD would not be stable at the timestep. With a constraint, I is the effective inertia at the plan's
start and w `bandwidth`. MuJoCo clamps the commands to the
actuators' force ranges.
"""

from __future__ import annotations

from typing import Annotated, Any

import mujoco
import numpy as np
from pydantic import Field

from simbench.api import Array, Controller, ControlSettings, State
from simbench.api.trajectory import JointTrajectory, gradient_rows
from simbench.core.plant import Plant
from simbench.physics.switches import at_start
from simbench.robots.servo_design import design, pd_gains, plan_dynamics
from simbench.scenario.schema import Gains


class ComputedTorqueSettings(ControlSettings):
    """The `control:` fields of computed_torque."""

    kp: Gains | None = None
    kd: Gains | None = None
    bandwidth: Annotated[float, Field(gt=0, le=1e4)] = 100.0  # rad/s, for the default gains
    damping_ratio: Annotated[float, Field(gt=0, le=10)] = 1.0


class ComputedTorque(Controller):
    """Inverse-dynamics feed-forward plus joint PD, on torque actuation."""

    name = "computed_torque"
    description = "torque actuation: inverse dynamics of the model at the plan (mj_inverse) plus joint PD"
    settings = ComputedTorqueSettings
    actuation = "torque"

    def __init__(self, settings: ComputedTorqueSettings | None = None):
        self.config = settings or ComputedTorqueSettings(controller=self.name)
        self.kp = self.kd = np.zeros(0)
        self.tau_ff: Array | None = None  # (N, dof) for a serial arm; None where it is measured each step
        self.design: list = []  # the joints' designed gains (servo_design.JointServo), for a serial arm

    def bind(self, plant: Plant, trajectory: JointTrajectory) -> None:
        self.plant = plant
        self.q_ref, self.qd_ref = trajectory.q_ref, trajectory.qd_ref
        self.constrained = plant.model.neq > 0
        self.inertia = effective_inertia(plant, trajectory)
        c = self.config
        kp, kd = pd_gains(self.inertia, c.bandwidth, c.damping_ratio)
        if not self.constrained:
            self.design = design(plant, trajectory, plan_dynamics(plant, trajectory), np.ones(plant.robot.dof, bool),
                                 None, c.bandwidth, c.damping_ratio, feedforward=True)
            kp, kd = np.array([s.kp for s in self.design]), np.array([s.kv for s in self.design])
        self.kp = np.array(c.kp) if c.kp is not None else kp
        self.kd = np.array(c.kd) if c.kd is not None else kd
        self.qdd_ref = np.gradient(trajectory.qd_ref, float(plant.model.opt.timestep), axis=0)
        self.tau_ff = None if self.constrained else self._inverse_dynamics(trajectory.q_ref, trajectory.qd_ref,
                                                                           self.qdd_ref)
        self.ctrl = np.zeros(plant.model.nu)

    def _inverse_dynamics(self, q_ref: Array, qd_ref: Array, qdd_ref: Array) -> Array:
        """tau_ff (N, dof): mj_inverse at every planned sample, the other DOFs at rest."""
        plant, model = self.plant, self.plant.model
        data = mujoco.MjData(model)
        tau = np.empty_like(q_ref)
        for k in range(len(q_ref)):
            data.qpos[:] = plant.initial_qpos(q_ref[k])
            data.qvel[:] = 0
            data.qacc[:] = 0
            data.qvel[plant.dof_adr] = qd_ref[k]
            data.qacc[plant.dof_adr] = qdd_ref[k]
            mujoco.mj_inverse(model, data)
            tau[k] = data.qfrc_inverse[plant.dof_adr]
        return tau

    def commands(self, state: State) -> Array:
        k, dof = state.k, self.plant.dof_adr
        if self.tau_ff is not None:
            ff = self.tau_ff[k]
        else:
            assert state.data is not None, "computed_torque needs the live data of a constrained plant"
            ff = self.inertia * self.qdd_ref[k] + state.data.qfrc_bias[dof] - state.data.qfrc_passive[dof]
        self.ctrl[self.plant.actuators] = (ff + self.kp * (self.q_ref[k] - state.q)
                                           + self.kd * (self.qd_ref[k] - state.qd))
        return self.ctrl.copy()

    def revise(self, k0: int, q_ref: Array, qd_ref: Array) -> None:
        self.revise_rows(k0, len(q_ref), q_ref, qd_ref)

    def revise_rows(self, k0: int, k1: int, q_ref: Array, qd_ref: Array) -> None:
        """The planned acceleration, and a serial arm's inverse dynamics, redone only at the rows k0 - 1 to k1 that
        np.gradient's differences reach: the numbers of binding afresh, without redoing every row at each re-grip."""
        self.q_ref, self.qd_ref = q_ref, qd_ref
        a, b = max(k0 - 1, 0), min(k1 + 1, len(qd_ref))  # the differences at rows k0 - 1 .. k1
        self.qdd_ref[a:b] = gradient_rows(qd_ref, a, b, float(self.plant.model.opt.timestep))
        if self.tau_ff is not None:
            self.tau_ff[a:b] = self._inverse_dynamics(q_ref[a:b], qd_ref[a:b], self.qdd_ref[a:b])

    def gains(self) -> dict[str, Any]:
        feedforward = ("effective inertia x planned acceleration + bias forces at the measured state "
                       "(constrained mechanism)" if self.constrained
                       else "inverse dynamics at the planned state")
        designed = ({"design": [{"joint": s.joint, "bandwidth": s.bandwidth, "reason": s.reason,
                                 "inertia": s.inertia} for s in self.design]}
                    if self.design and self.config.kp is None and self.config.kd is None else {})
        return {"kp": self.kp.tolist(), "kd": self.kd.tolist(), "feedforward": feedforward,
                "bandwidth": self.config.bandwidth, "damping_ratio": self.config.damping_ratio, **designed}


def effective_inertia(plant: Plant, trajectory: JointTrajectory) -> Array:
    """Each actuated joint's inertia as its actuator feels it at the plan's start, the mechanism's constraints
    included (a closed chain's other legs, a gripped rotor): the diagonal of G^-1, where column i of G is the
    joints' acceleration per unit of torque on joint i (MuJoCo's forward dynamics at rest, at the start pose
    and grips). For a serial arm this is the diagonal of the joint-space inertia matrix."""
    model, data, _ = at_start(plant, trajectory)
    mujoco.mj_forward(model, data)
    rest = data.qacc[plant.dof_adr].copy()
    response = np.empty((plant.robot.dof, plant.robot.dof))
    for i, dof in enumerate(plant.dof_adr):
        data.qfrc_applied[:] = 0
        data.qfrc_applied[dof] = 1.0
        mujoco.mj_forward(model, data)
        response[:, i] = data.qacc[plant.dof_adr] - rest
    return np.diag(np.linalg.inv(response)).copy()
