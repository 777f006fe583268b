"""Physics: position actuators track a JointTrajectory in MuJoCo, and every step is recorded.

The arm starts at rest at the first reference, holds it while it settles, then tracks. Each actuator is a
position servo, force = kp (ctrl - q) - kv qd. With velocity feed-forward the command is
ctrl = q_ref + ((kv + b) / kp) qd_ref, which makes the same servo a PD on both errors that also cancels the
joint's viscous friction b on the plan: kp (q_ref - q) + kv (qd_ref - qd) + b qd_ref, as an industrial joint
controller with friction compensation is. Commands are clamped to the
actuators' control ranges (the joint ranges), as the servo's own limits would.

The steps run in C through `mujoco.rollout` with the controls computed beforehand, in chunks; a chunk stops at
the first MuJoCo warning, which is recorded, and a warning that means the state blew up ends the run. Planned
switches (an electromagnet's weld going on or off) split the run into segments, and are applied between them.
"""

from __future__ import annotations

import copy
import sys
from dataclasses import dataclass, field
from functools import cache

import mujoco
import numpy as np
from mujoco import rollout
from tqdm import tqdm

from simbench.errors import RunError
from simbench.robots import Robot
from simbench.trajectory import JointTrajectory, Switch

_CHUNK = 5000
_FATAL = {mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
          mujoco.mjtWarning.mjWARN_BADCTRL}


@dataclass(frozen=True)
class Recording:
    """The simulated run on the trajectory's time grid: row k is the state at t[k] (t = 0 after settling)."""

    t: np.ndarray
    qpos: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    ctrl: np.ndarray
    tool: np.ndarray
    timestep: float
    warnings: tuple[dict, ...] = ()
    sensors: dict = field(default_factory=dict)
    eq_active: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Plant:
    """A robot's compiled model with the indices the simulator needs."""

    model: mujoco.MjModel
    robot: Robot
    qpos_adr: np.ndarray
    dof_adr: np.ndarray
    actuators: np.ndarray
    sensors: dict[str, slice]

    @classmethod
    def load(cls, robot: Robot, timestep: float | None = None) -> "Plant":
        """The robot's compiled scene (a fresh copy: a run changes its model); actuators are named after the joints
        they drive."""
        model = copy.copy(_compiled(str(robot.scene)))
        if timestep is not None:
            model.opt.timestep = timestep
        joints = [model.joint(name) for name in robot.joints]
        sensors = {}
        for name in (robot.tool_sensor, *robot.sensors):
            sensor = model.sensor(name)
            sensors[name] = slice(int(sensor.adr[0]), int(sensor.adr[0] + sensor.dim[0]))
        return cls(model=model, robot=robot,
                   qpos_adr=np.array([j.qposadr[0] for j in joints]),
                   dof_adr=np.array([j.dofadr[0] for j in joints]),
                   actuators=np.array([model.actuator(name).id for name in robot.joints]),
                   sensors=sensors)

    def initial_qpos(self, q: np.ndarray) -> np.ndarray:
        """Full qpos for actuated joints q: the model's reference pose, q, and any passive joints assembled."""
        qpos = self.model.qpos0.copy()
        qpos[self.qpos_adr] = q
        if self.robot.assemble is not None:
            for name, value in self.robot.assemble(q).items():
                qpos[self.model.joint(name).qposadr[0]] = value
        return qpos

    def commands(self, q_ref: np.ndarray, qd_ref: np.ndarray, feedforward: bool) -> np.ndarray:
        """Actuator controls (N, nu) for joint references, clamped to the control ranges."""
        m = self.model
        ctrl = np.zeros((q_ref.shape[0], m.nu))
        act = self.actuators
        ctrl[:, act] = q_ref
        if feedforward:
            kp = m.actuator_gainprm[act, 0]
            kv = -m.actuator_biasprm[act, 2] + m.dof_damping[self.dof_adr]
            ctrl[:, act] += qd_ref * (kv / kp)
        limited = m.actuator_ctrllimited.astype(bool)
        lo, hi = m.actuator_ctrlrange.T
        ctrl[:, limited] = np.clip(ctrl[:, limited], lo[limited], hi[limited])
        return ctrl


@cache
def _compiled(scene: str) -> mujoco.MjModel:
    """A scene compiled once per process (compiling costs about as much as simulating a short scenario)."""
    return mujoco.MjModel.from_xml_path(scene)


def _state_slices(model: mujoco.MjModel) -> dict[str, slice]:
    """Where time, qpos and qvel sit in a full physics state vector."""
    slices, start = {}, 0
    spec = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
    for bit in range(int(mujoco.mjtState.mjNSTATE)):
        part = 1 << bit
        if spec & part:
            size = mujoco.mj_stateSize(model, part)
            slices[mujoco.mjtState(part).name] = slice(start, start + size)
            start += size
    return slices


def _warnings(data: mujoco.MjData) -> list[int]:
    return [i for i in range(len(data.warning)) if data.warning[i].number > 0]


def _roll(model, data, controls, state_out, sensor_out, t0: float, progress=None) -> list[dict]:
    """Step through `controls`, chunk by chunk, from data's current state; returns the warnings met. Fills the
    outputs; data is left at the last state."""
    found, k, n = [], 0, controls.shape[0]
    spec = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
    ctrl_spec = int(mujoco.mjtState.mjSTATE_CTRL)
    state = np.empty(mujoco.mj_stateSize(model, spec))
    while k < n:
        mujoco.mj_getState(model, data, state, spec)
        warmstart = data.qacc_warmstart.copy()
        stop = min(k + _CHUNK, n)
        rollout.rollout(model, data, state[None], controls[None, k:stop], control_spec=ctrl_spec,
                        initial_warmstart=warmstart[None], state=state_out[None, k:stop],
                        sensordata=sensor_out[None, k:stop])
        codes = _warnings(data)
        if codes:
            time_now = data.time
            done = k + int(round((time_now - state[0]) / model.opt.timestep))
            for code in codes:
                found.append({"t": float(time_now - t0), "kind": mujoco.mjtWarning(code).name,
                              "count": int(data.warning[code].number)})
                data.warning[code].number = 0
            if set(codes) & {int(c) for c in _FATAL}:
                raise RunError(f"physics diverged at t = {time_now - t0:.4f} s: "
                               + ", ".join(mujoco.mjtWarning(c).name for c in codes))
            k = max(done, k + 1)
        else:
            if progress is not None:
                progress.update(stop - k)
            k = stop
    return found


def relative_pose(model: mujoco.MjModel, data: mujoco.MjData, eq: int) -> np.ndarray:
    """A weld's reference (relpos, relquat) putting body2 where it is now in body1's frame."""
    b1, b2 = model.eq_obj1id[eq], model.eq_obj2id[eq]
    r1 = data.xmat[b1].reshape(3, 3)
    pos = r1.T @ (data.xpos[b2] - data.xpos[b1])
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, (r1.T @ data.xmat[b2].reshape(3, 3)).ravel())
    return np.concatenate([pos, quat])


def apply_switch(model: mujoco.MjModel, data: mujoco.MjData, switch: Switch) -> None:
    """Turn an equality on (first setting a weld's reference to the current relative pose, so nothing snaps) or
    off, and the released part's holding servos the other way. rollout() starts each call from eq_active0."""
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


def simulate(plant: Plant, traj: JointTrajectory, settle: float = 0.2, feedforward: bool = True,
             progress: bool = False) -> Recording:
    """Settle at traj's first reference, then track it, applying the planned switches at their steps; one
    recorded row per control sample. The plant's model is copied, since switching edits it."""
    model = copy.copy(plant.model)
    if not np.isclose(model.opt.timestep, traj.dt, rtol=1e-9, atol=0.0):
        raise ValueError(f"trajectory dt {traj.dt} differs from the model timestep {model.opt.timestep}")
    data = mujoco.MjData(model)
    spec = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
    nstate = mujoco.mj_stateSize(model, spec)
    sl = _state_slices(model)
    ctrl = plant.commands(traj.q_ref, traj.qd_ref, feedforward)
    bad = ~np.isfinite(ctrl).all(axis=1)
    if bad.any():
        raise RunError(f"the plan has no finite reference at t = {traj.t[np.argmax(bad)]:.4f} s")

    data.qpos[:] = plant.initial_qpos(traj.q_ref[0])
    for name, value in traj.initial.items():
        adr = model.joint(name).qposadr[0]
        data.qpos[adr:adr + len(value)] = value
    data.ctrl[:] = ctrl[0]
    steps = np.rint(np.array([w.t for w in traj.switches]) / model.opt.timestep).astype(int)
    for switch in (w for w, k in zip(traj.switches, steps) if k == 0):
        apply_switch(model, data, switch)
    mujoco.mj_forward(model, data)
    first_state = np.empty(nstate)
    mujoco.mj_getState(model, data, first_state, spec)

    n_settle = int(round(settle / model.opt.timestep))
    n_track = traj.t.size - 1
    states = np.empty((n_settle + n_track, nstate))
    sensors = np.empty((n_settle + n_track, model.nsensordata))
    controls = np.concatenate([np.repeat(ctrl[:1], n_settle, axis=0), ctrl[:-1]])
    t0 = n_settle * model.opt.timestep
    # eq_active[r]: the constraints in force from row r's time on (after the switches at that step).
    eq_active = np.empty((traj.t.size, model.neq), bool)
    bounds = sorted({int(k) + n_settle for k in steps if 0 < k < n_track}) + [n_settle + n_track]
    warnings, done = [], 0
    with tqdm(total=controls.shape[0], desc="simulate", unit="step", disable=not (progress and sys.stderr.isatty()),
              leave=False) as bar:
        for stop in bounds:
            eq_active[max(done - n_settle, 0):stop - n_settle] = data.eq_active
            warnings += _roll(model, data, controls[done:stop], states[done:stop], sensors[done:stop], t0, bar)
            for switch in (w for w, k in zip(traj.switches, steps) if 0 < k and k + n_settle == stop):
                apply_switch(model, data, switch)
            done = stop
    eq_active[-1] = data.eq_active
    if n_settle:
        first_state = states[n_settle - 1]

    # Row 0 is the state at the end of settling (the start state itself when there is no settling). MuJoCo
    # computes sensors before it integrates, so the sensor row of step k belongs to the state before it.
    track = np.concatenate([first_state[None], states[n_settle:]])
    mujoco.mj_forward(model, data)
    readings = np.concatenate([sensors[n_settle:], data.sensordata[None]])
    recorded = {name: readings[:, where] for name, where in plant.sensors.items()}
    qpos = track[:, sl["mjSTATE_QPOS"]]
    qvel = track[:, sl["mjSTATE_QVEL"]]
    return Recording(t=traj.t.copy(), qpos=qpos, q=qpos[:, plant.qpos_adr], qd=qvel[:, plant.dof_adr],
                     ctrl=ctrl, tool=recorded.pop(plant.robot.tool_sensor), timestep=float(model.opt.timestep),
                     warnings=tuple(warnings), sensors=recorded,
                     eq_active={model.equality(i).name: eq_active[:, i] for i in range(model.neq)})
