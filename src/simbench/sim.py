"""Physics: position actuators track a JointTrajectory in MuJoCo, and every step is recorded.

The arm starts at rest at the first reference, holds it while it settles, then tracks. Each actuator is a
position servo, force = kp (ctrl - q) - kv qd. With velocity feed-forward the command is
ctrl = q_ref + ((kv + b) / kp) qd_ref, which makes the same servo a PD on both errors that also cancels the
joint's viscous friction b on the plan: kp (q_ref - q) + kv (qd_ref - qd) + b qd_ref, as an industrial joint
controller with friction compensation is. Commands are clamped to the
actuators' control ranges (the joint ranges), as the servo's own limits would.

The steps run in C through `mujoco.rollout` with the controls computed beforehand, in chunks; a chunk stops at
the first MuJoCo warning, which is recorded, and a warning that means the state blew up ends the run.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field

import mujoco
import numpy as np
from mujoco import rollout
from tqdm import tqdm

from simbench.errors import RunError
from simbench.robots import Robot
from simbench.trajectory import JointTrajectory

_CHUNK = 5000
_FATAL = {mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL}


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
        """Compile the robot's scene; actuators are named after the joints they drive."""
        model = mujoco.MjModel.from_xml_path(str(robot.scene))
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


def _roll(model, data, state0, controls, state_out, sensor_out, warmstart, t0: float, progress=None) -> list[dict]:
    """Step through `controls`, chunk by chunk, from state0; returns the warnings met. Fills the outputs."""
    found, k, n = [], 0, controls.shape[0]
    spec = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
    ctrl_spec = int(mujoco.mjtState.mjSTATE_CTRL)
    state = state0
    while k < n:
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
        state = np.empty(mujoco.mj_stateSize(model, spec))
        mujoco.mj_getState(model, data, state, spec)
        warmstart = data.qacc_warmstart.copy()
    return found


def simulate(plant: Plant, traj: JointTrajectory, settle: float = 0.2, feedforward: bool = True,
             progress: bool = False) -> Recording:
    """Settle at traj's first reference, then track it; one recorded row per control sample."""
    model = plant.model
    if not np.isclose(model.opt.timestep, traj.dt, rtol=1e-9, atol=0.0):
        raise ValueError(f"trajectory dt {traj.dt} differs from the model timestep {model.opt.timestep}")
    data = mujoco.MjData(model)
    spec = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
    nstate = mujoco.mj_stateSize(model, spec)
    sl = _state_slices(model)
    ctrl = plant.commands(traj.q_ref, traj.qd_ref, feedforward)

    data.qpos[:] = plant.initial_qpos(traj.q_ref[0])
    data.ctrl[:] = ctrl[0]
    mujoco.mj_forward(model, data)
    state0 = np.empty(nstate)
    mujoco.mj_getState(model, data, state0, spec)

    n_settle = int(round(settle / model.opt.timestep))
    n_track = traj.t.size - 1
    states = np.empty((n_settle + n_track, nstate))
    sensors = np.empty((n_settle + n_track, model.nsensordata))
    controls = np.concatenate([np.repeat(ctrl[:1], n_settle, axis=0), ctrl[:-1]])
    t0 = n_settle * model.opt.timestep
    with tqdm(total=controls.shape[0], desc="simulate", unit="step", disable=not (progress and sys.stderr.isatty()), leave=False) as bar:
        warnings = _roll(model, data, state0, controls, states, sensors, np.zeros(model.nv), t0, bar)

    # Row 0 is the state at the end of settling (the start state itself when there is no settling). MuJoCo
    # computes sensors before it integrates, so the sensor row of step k belongs to the state before it.
    first_state = states[n_settle - 1] if n_settle else state0
    track = np.concatenate([first_state[None], states[n_settle:]])
    mujoco.mj_forward(model, data)
    readings = np.concatenate([sensors[n_settle:], data.sensordata[None]])
    recorded = {name: readings[:, where] for name, where in plant.sensors.items()}
    qpos = track[:, sl["mjSTATE_QPOS"]]
    qvel = track[:, sl["mjSTATE_QVEL"]]
    return Recording(t=traj.t.copy(), qpos=qpos, q=qpos[:, plant.qpos_adr], qd=qvel[:, plant.dof_adr],
                     ctrl=ctrl, tool=recorded.pop(plant.robot.tool_sensor), timestep=float(model.opt.timestep),
                     warnings=tuple(warnings), sensors=recorded)
