"""The bounds of an environment's actions and position targets: a joint's range, or, for a joint without one, the
plan's span widened by CONTINUOUS_SPAN; under torque actuation its force limit."""

from __future__ import annotations

import mujoco
import numpy as np

from simbench.api import Array, JointTrajectory
from simbench.core.plant import Plant

CONTINUOUS_SPAN = {mujoco.mjtJoint.mjJNT_HINGE: np.pi, mujoco.mjtJoint.mjJNT_SLIDE: 0.1}
"""How far (rad for a hinge, m for a slide) a joint without a range may be commanded beyond the plan's span."""


def action_bounds(model: mujoco.MjModel, plant: Plant, plan: JointTrajectory) -> tuple[Array, Array]:
    """Each joint's action bounds: under position actuation its range (a joint with none: the plan's span
    widened by CONTINUOUS_SPAN either side), under torque +-its force limit; within the actuator's control range
    where it has one."""
    act = plant.actuators
    if plant.actuation == "torque":
        limit = plant.force_limit()
        lo, hi = -limit, limit
    else:
        lo, hi = joint_bounds(model, plant, plan)
    ctrl = model.actuator_ctrllimited[act].astype(bool)
    lo = np.where(ctrl, np.maximum(lo, model.actuator_ctrlrange[act, 0]), lo)
    hi = np.where(ctrl, np.minimum(hi, model.actuator_ctrlrange[act, 1]), hi)
    if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
        raise ValueError(f"the {plant.robot.name}'s actuators have no force limits: a torque action needs them")
    return lo.astype(float), hi.astype(float)


def joint_bounds(model: mujoco.MjModel, plant: Plant, plan: JointTrajectory) -> tuple[Array, Array]:
    """Each joint's range; a joint with none: the plan's span widened by CONTINUOUS_SPAN either side."""
    jnt = model.actuator_trnid[plant.actuators, 0]
    span = np.array([CONTINUOUS_SPAN[mujoco.mjtJoint(t)] for t in model.jnt_type[jnt]])
    limited = model.jnt_limited[jnt].astype(bool)
    lo = np.where(limited, model.jnt_range[jnt, 0], plan.q_ref.min(axis=0) - span)
    hi = np.where(limited, model.jnt_range[jnt, 1], plan.q_ref.max(axis=0) + span)
    return lo, hi
