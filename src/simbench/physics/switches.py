"""Planned switches (an RSMG electromagnet's weld going on or off) applied to a running model, and the model
and data a run starts from."""

from __future__ import annotations

import copy

import mujoco
import numpy as np

from simbench.api.trajectory import JointTrajectory, Switch
from simbench.core.plant import Plant


def relative_pose(model: mujoco.MjModel, data: mujoco.MjData, eq: int) -> np.ndarray:
    """A weld's reference (relpos, relquat) putting body2 where it is now in body1's frame."""
    b1, b2 = model.eq_obj1id[eq], model.eq_obj2id[eq]
    r1 = data.xmat[b1].reshape(3, 3)
    pos = r1.T @ (data.xpos[b2] - data.xpos[b1])
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, (r1.T @ data.xmat[b2].reshape(3, 3)).ravel())
    return np.concatenate([pos, quat])


def apply_switch(model: mujoco.MjModel, data: mujoco.MjData, switch: Switch) -> None:
    """Turn an equality on (a weld's reference set to the current relative pose, so that nothing snaps) or off,
    and the released part's holding servos the other way."""
    eq = model.equality(switch.equality).id
    if switch.active:
        mujoco.mj_kinematics(model, data)
        if model.eq_type[eq] == mujoco.mjtEq.mjEQ_WELD:
            model.eq_data[eq, 3:10] = relative_pose(model, data, eq)
    model.eq_active0[eq] = switch.active
    data.eq_active[eq] = switch.active
    if switch.servo_group is not None:
        bit = 1 << switch.servo_group
        model.opt.disableactuator = (model.opt.disableactuator | bit) if switch.active else \
            (model.opt.disableactuator & ~bit)


def switch_steps(model: mujoco.MjModel, traj: JointTrajectory) -> np.ndarray:
    """The control step of each of the plan's switches (0: before the first step)."""
    return np.rint(np.array([w.t for w in traj.switches]) / model.opt.timestep).astype(int)


def at_start(plant: Plant, traj: JointTrajectory) -> tuple[mujoco.MjModel, mujoco.MjData, np.ndarray]:
    """The model (a copy if the plan switches), data posed at the plan's start, and each switch's step."""
    model = copy.copy(plant.model) if traj.switches else plant.model
    data = mujoco.MjData(model)
    return model, data, pose_start(plant, traj, model, data)


def pose_start(plant: Plant, traj: JointTrajectory, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """Pose `data` (reset first) at the plan's start, the switches of its step 0 applied to `model` (the plant's
    model or a copy of it, edited in place); each switch's step."""
    mujoco.mj_resetData(model, data)
    data.qpos[:] = plant.initial_qpos(traj.q_ref[0])
    for name, value in traj.initial.items():
        adr = model.joint(name).qposadr[0]
        data.qpos[adr:adr + len(value)] = value
    steps = switch_steps(model, traj)
    for switch in (w for w, k in zip(traj.switches, steps) if k == 0):
        apply_switch(model, data, switch)
    return steps
