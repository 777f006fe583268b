"""Physics: position actuators track a JointTrajectory in MuJoCo, and every step is recorded.

The arm starts at rest at the first reference, holds it while it settles, then tracks. Each actuator is a
position servo, force = kp (ctrl - q) - kv qd. With velocity feed-forward the command is
ctrl = q_ref + ((kv + b) / kp) qd_ref, which makes the same servo a PD on both errors that also cancels the
joint's viscous friction b on the plan: kp (q_ref - q) + kv (qd_ref - qd) + b qd_ref, as an industrial joint
controller with friction compensation is. Commands are clamped to the
actuators' control ranges (the joint ranges), as the servo's own limits would.

The steps run in C through `mujoco.rollout` with the controls computed beforehand, in chunks. Planned switches
(an electromagnet's weld going on or off) split the run into segments, and are applied between them. After each
chunk the run is checked: MuJoCo's warnings that the state blew up (NaN, infinite or huge position, velocity,
acceleration or control), that its constraint or contact buffer overflowed, and any speed above _MAX_SPEED
(no joint of a manipulator turns at 1000 rad/s: the integration is diverging, long before MuJoCo's own 1e10
bound) end the run. The chunk is then replayed step by step to find the first step at fault, and the run stops
there with a PhysicsError that carries the recording up to the last sound state. MuJoCo's own printing of
warnings (and its MUJOCO_LOG.TXT) is silenced while simbench steps: they are read from the data and reported.
"""

from __future__ import annotations

import copy
import sys
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from functools import cache

import mujoco
import numpy as np
from mujoco import rollout
from tqdm import tqdm

from simbench.errors import PhysicsError, RunError
from simbench.api import Controller, Robot
from simbench.controllers import Servo
from simbench.trajectory import JointTrajectory, Switch

_CHUNK = 5000
_W = mujoco.mjtWarning
_FATAL = {int(w) for w in (_W.mjWARN_BADQACC, _W.mjWARN_BADQPOS, _W.mjWARN_BADQVEL, _W.mjWARN_BADCTRL,
                           _W.mjWARN_CNSTRFULL, _W.mjWARN_CONTACTFULL)}
_MAX_SPEED = 1e3  # rad/s or m/s, any DOF
FORCE_SENSOR = "simbench/force/"  # prefix of the actuator-force sensors added to every scene (scene_spec)


class _Fault(Exception):
    """Raised inside the stepping loop at the first step at fault: its index among the steps, and why."""

    def __init__(self, step: int, cause: str):
        self.step = step
        self.cause = cause


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
    force: np.ndarray  # (N, dof): each joint's actuator force as MuJoCo applied it (after clamping)
    force_limit: np.ndarray  # (dof,): each actuator's force bound, inf where unlimited
    warnings: tuple[dict, ...] = ()
    sensors: dict = field(default_factory=dict)
    eq_active: dict = field(default_factory=dict)
    q_ref: np.ndarray | None = None  # the references as commanded, where the plan's feedback revised them
    qd_ref: np.ndarray | None = None


@dataclass(frozen=True)
class Plant:
    """A robot's compiled model with the indices the simulator needs."""

    model: mujoco.MjModel
    robot: Robot
    qpos_adr: np.ndarray
    dof_adr: np.ndarray
    actuators: np.ndarray
    sensors: dict[str, slice]
    force_sensors: np.ndarray

    @classmethod
    def load(cls, robot: Robot, timestep: float | None = None, kp: list[float] | None = None,
             kv: list[float] | None = None, force_limits: bool = True,
             gravity_compensation: bool = True) -> "Plant":
        """The robot's compiled scene (a fresh copy: a run changes its model), with the timestep and the position
        servos' gains (one per joint) where given, without force limits if asked, and without the bodies' gravity
        compensation (`gravcomp`: the controller's gravity feed-forward) if asked; actuators are named after the
        joints they drive."""
        model = copy.copy(compiled_scene(str(robot.scene)))
        if timestep is not None:
            model.opt.timestep = timestep
        act = np.array([model.actuator(name).id for name in robot.joints])
        if kp is not None:  # a position servo: force = kp ctrl - kp q - kv qd
            model.actuator_gainprm[act, 0] = kp
            model.actuator_biasprm[act, 1] = -np.asarray(kp)
        if kv is not None:
            model.actuator_biasprm[act, 2] = -np.asarray(kv)
        if not force_limits:
            model.actuator_forcelimited[:] = 0
            model.jnt_actfrclimited[:] = 0
        if not gravity_compensation:
            model.body_gravcomp[:] = 0
        joints = [model.joint(name) for name in robot.joints]
        sensors = {}
        for name in (robot.tool_sensor, *robot.sensors):
            sensor = model.sensor(name)
            sensors[name] = slice(int(sensor.adr[0]), int(sensor.adr[0] + sensor.dim[0]))
        return cls(model=model, robot=robot,
                   qpos_adr=np.array([j.qposadr[0] for j in joints]),
                   dof_adr=np.array([j.dofadr[0] for j in joints]),
                   actuators=act,
                   sensors=sensors,
                   force_sensors=np.array([model.sensor(FORCE_SENSOR + name).adr[0] for name in robot.joints]))

    def force_limit(self) -> np.ndarray:
        """Each joint's actuator force bound (dof,): the actuator's force range, and the joint's actuator force
        range where that is tighter; inf where neither limits it."""
        m = self.model
        bound = np.where(m.actuator_forcelimited[self.actuators].astype(bool),
                         np.abs(m.actuator_forcerange[self.actuators]).min(axis=1), np.inf)
        jnt = m.actuator_trnid[self.actuators, 0]
        joint_bound = np.where(m.jnt_actfrclimited[jnt].astype(bool), np.abs(m.jnt_actfrcrange[jnt]).min(axis=1),
                               np.inf)
        return np.minimum(bound, joint_bound)

    def initial_qpos(self, q: np.ndarray) -> np.ndarray:
        """Full qpos for actuated joints q: the model's reference pose, q, and any passive joints assembled."""
        qpos = self.model.qpos0.copy()
        qpos[self.qpos_adr] = q
        for name, value in self.robot.assemble(q).items():
            qpos[self.model.joint(name).qposadr[0]] = value
        return qpos


def scene_spec(scene: str) -> mujoco.MjSpec:
    """A scene as simbench runs it: the MJCF, plus an actuator-force sensor (FORCE_SENSOR + name) on every
    actuator, so that the recording holds the force MuJoCo really applied, force limits included."""
    spec = mujoco.MjSpec.from_file(scene)
    for actuator in spec.actuators:
        spec.add_sensor(name=FORCE_SENSOR + actuator.name, type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                        objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname=actuator.name)
    return spec


@cache
def compiled_scene(scene: str) -> mujoco.MjModel:
    """A scene compiled once per process (compiling costs about as much as simulating a short scenario)."""
    return scene_spec(scene).compile()


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


@contextmanager
def _quiet_mujoco():
    """MuJoCo prints warnings and appends them to MUJOCO_LOG.TXT in the working folder; simbench reads them from
    the data and reports them itself."""
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda message: None)
    try:
        yield
    finally:
        mujoco.set_mju_user_warning(previous)


def _dof(model: mujoco.MjModel, dof: int) -> str:
    return f"DOF {dof} (joint '{model.joint(int(model.dof_jntid[dof])).name}')"


def _warning_cause(model: mujoco.MjModel, code: int, info: int) -> str:
    """What a fatal MuJoCo warning means, naming the joint or actuator."""
    code = _W(code)
    if code in (_W.mjWARN_BADQACC, _W.mjWARN_BADQVEL):
        quantity = "acceleration" if code == _W.mjWARN_BADQACC else "velocity"
        where = f" at {_dof(model, info)}" if 0 <= info < model.nv else ""
        what = f"{quantity} NaN, infinite or huge{where}"
    elif code == _W.mjWARN_BADQPOS:
        what = f"position NaN, infinite or huge at qpos[{info}]"
    elif code == _W.mjWARN_BADCTRL:
        where = f" at actuator '{model.actuator(info).name}'" if 0 <= info < model.nu else ""
        what = f"control NaN, infinite or huge{where}"
    else:
        buffer = "constraint" if code == _W.mjWARN_CNSTRFULL else "contact"
        what = f"the {buffer} buffer is full (the model's <size memory> is too small)"
    return f"{what} ({code.name})"


def _unsound(model: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray) -> str | None:
    """Why a state (or the last of several) cannot be trusted, or None."""
    if not (np.isfinite(qpos).all() and np.isfinite(qvel).all()):
        return "the state became NaN or infinite"
    fast = np.abs(qvel) > _MAX_SPEED
    if fast.any():
        dof = int(np.flatnonzero(fast.reshape(-1, model.nv).any(axis=0))[0])
        return (f"the speed of {_dof(model, dof)} passed {_MAX_SPEED:g} rad/s or m/s: the integration is "
                "diverging")
    return None


def _fatal_cause(err: mujoco.FatalError) -> str:
    """MuJoCo's fatal error, on one line."""
    first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
    hint = " (the model's <size memory> is too small)" if "out of memory" in first else ""
    return f"MuJoCo stopped: {first}{hint}"


def _locate(model, data, state: np.ndarray, warmstart: np.ndarray, controls: np.ndarray) -> tuple[int, str]:
    """Replay a chunk that went wrong one step at a time, from its first state; the first step at fault and why.
    Leaves data where that step left it."""
    mujoco.mj_setState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    data.qacc_warmstart[:] = warmstart
    for w in data.warning:
        w.number = 0
    for j, u in enumerate(controls):
        data.ctrl[:] = u
        try:
            mujoco.mj_step(model, data)
        except mujoco.FatalError as err:
            return j, _fatal_cause(err)
        fatal = [c for c in _warnings(data) if c in _FATAL]
        if fatal:
            return j, _warning_cause(model, fatal[0], int(data.warning[fatal[0]].lastinfo))
        cause = _unsound(model, data.qpos, data.qvel)
        if cause:
            return j, cause
    return len(controls) - 1, "the chunk failed, but not when replayed step by step"


def _roll(model, data, controls, state_out, sensor_out, t0: float, slices: dict, progress=None) -> list[dict]:
    """Step through `controls`, chunk by chunk, from data's current state; returns the warnings met. Fills the
    outputs; data is left at the last state. Raises _Fault at the first step at fault."""
    found, k, n = [], 0, controls.shape[0]
    spec = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
    ctrl_spec = int(mujoco.mjtState.mjSTATE_CTRL)
    state = np.empty(mujoco.mj_stateSize(model, spec))
    while k < n:
        mujoco.mj_getState(model, data, state, spec)
        warmstart = data.qacc_warmstart.copy()
        stop = min(k + _CHUNK, n)
        try:
            rollout.rollout(model, data, state[None], controls[None, k:stop], control_spec=ctrl_spec,
                            initial_warmstart=warmstart[None], state=state_out[None, k:stop],
                            sensordata=sensor_out[None, k:stop])
            stopped = False
        except mujoco.FatalError:  # MuJoCo gave up (out of arena memory): found again when replayed
            stopped = True
        codes = _warnings(data)
        chunk = state_out[k:stop]
        if stopped or set(codes) & _FATAL or _unsound(model, chunk[:, slices["mjSTATE_QPOS"]],
                                                      chunk[:, slices["mjSTATE_QVEL"]]):
            step, cause = _locate(model, data, state, warmstart, controls[k:stop])
            raise _Fault(k + step, cause)
        for code in codes:
            found.append({"t": float(data.time - t0), "kind": _W(code).name, "count": int(data.warning[code].number)})
            data.warning[code].number = 0
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
             progress: bool = False, controller: Controller | None = None) -> Recording:
    """Settle at traj's first reference, then track it, applying the planned switches at their steps; one
    recorded row per control sample. The plant's model is copied, since switching edits it. PhysicsError if the
    physics fails on the way."""
    controller = controller if controller is not None else Servo(feedforward)
    with _quiet_mujoco():
        return _simulate(plant, traj, settle, controller, progress)


def at_start(plant: Plant, traj: JointTrajectory) -> tuple[mujoco.MjModel, mujoco.MjData, np.ndarray]:
    """A copy of the plant's model (switching edits it) and data posed at the plan's first reference (passive
    joints assembled, the plan's `initial` joints set, the switches at step 0 applied), and each switch's step."""
    model = copy.copy(plant.model)
    data = mujoco.MjData(model)
    data.qpos[:] = plant.initial_qpos(traj.q_ref[0])
    for name, value in traj.initial.items():
        adr = model.joint(name).qposadr[0]
        data.qpos[adr:adr + len(value)] = value
    steps = np.rint(np.array([w.t for w in traj.switches]) / model.opt.timestep).astype(int)
    for switch in (w for w, k in zip(traj.switches, steps) if k == 0):
        apply_switch(model, data, switch)
    return model, data, steps


def _simulate(plant: Plant, traj: JointTrajectory, settle: float, controller: Controller,
              progress: bool) -> Recording:
    if not np.isclose(plant.model.opt.timestep, traj.dt, rtol=1e-9, atol=0.0):
        raise ValueError(f"trajectory dt {traj.dt} differs from the model timestep {plant.model.opt.timestep}")
    controller.bind(plant, traj)
    ctrl = controller.open_loop()
    if ctrl is None:
        raise RunError(f"controller '{controller.name}' needs the measured state every step: simbench steps only "
                       "open-loop controllers (through mujoco.rollout) so far")
    bad = ~np.isfinite(ctrl).all(axis=1)
    if bad.any():
        raise RunError(f"the plan has no finite reference at t = {traj.t[np.argmax(bad)]:.4f} s")

    try:
        model, data, steps = at_start(plant, traj)
        data.ctrl[:] = ctrl[0]
        mujoco.mj_forward(model, data)
    except mujoco.FatalError as err:
        raise PhysicsError(-settle, _fatal_cause(err), traj, None) from None
    spec = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
    nstate = mujoco.mj_stateSize(model, spec)
    sl = _state_slices(model)
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
    dt = model.opt.timestep
    revised = None  # (q_ref, qd_ref) once the plan's feedback has changed them
    with tqdm(total=controls.shape[0], desc="simulate", unit="step", disable=not (progress and sys.stderr.isatty()),
              leave=False) as bar:
        try:
            for stop in bounds:
                eq_active[max(done - n_settle, 0):stop - n_settle] = data.eq_active
                warnings += _roll(model, data, controls[done:stop], states[done:stop], sensors[done:stop], t0, sl,
                                  bar)
                for switch in (w for w, k in zip(traj.switches, steps) if 0 < k and k + n_settle == stop):
                    apply_switch(model, data, switch)
                    if traj.feedback is not None:
                        change = traj.feedback(switch, model, data, stop - n_settle)
                        revised = _revise(controller, traj, revised, change, controls[n_settle:])
                done = stop
        except _Fault as fault:
            fault.step += done
            if fault.step < n_settle:
                raise PhysicsError((fault.step + 1 - n_settle) * dt, fault.cause, traj, None) from None
            rows = fault.step - n_settle + 1  # rows 0..m are sound; the step from row m failed
            start = states[n_settle - 1] if n_settle else first_state
            partial = _record(plant, traj, model, start, states[n_settle:], sensors[n_settle:n_settle + rows],
                              eq_active[:rows], ctrl, warnings, revised)
            raise PhysicsError(float(traj.t[rows - 1] + dt), fault.cause, commanded(traj, partial), partial) from None
        eq_active[-1] = data.eq_active
        mujoco.mj_forward(model, data)
    start = states[n_settle - 1] if n_settle else first_state
    readings = np.concatenate([sensors[n_settle:], data.sensordata[None]])
    return _record(plant, traj, model, start, states[n_settle:], readings, eq_active, ctrl, warnings, revised)


def commanded(traj: JointTrajectory, rec: Recording) -> JointTrajectory:
    """The plan with the references the run really commanded: its own, or those its feedback revised."""
    return traj if rec.q_ref is None else replace(traj, q_ref=rec.q_ref, qd_ref=rec.qd_ref)


def _revise(controller: Controller, traj: JointTrajectory, revised: tuple | None, change: tuple | None,
            upcoming: np.ndarray) -> tuple | None:
    """Apply a feedback change (k0, columns, q) to the references (q_ref, qd_ref: copies of the plan's at the
    first change), to the controller's commands, and to `upcoming`, the controls the remaining rollouts read
    (row k drives the step from sample k). Returns the references as they now are."""
    if change is None:
        return revised
    k0, columns, q = change
    q_ref, qd_ref = revised if revised is not None else (traj.q_ref.copy(), traj.qd_ref.copy())
    k1 = k0 + len(q)
    q_ref[k0:k1, columns] = q
    hi = min(k1 + 1, len(q_ref))  # the rate just after the change moves too; rows before k0 have been used
    qd_ref[k0:hi, columns] = np.gradient(q_ref[k0:hi, columns], traj.dt, axis=0)
    controller.revise(k0, q_ref, qd_ref)
    ctrl = controller.open_loop()
    upcoming[k0:min(hi, len(upcoming))] = ctrl[k0:min(hi, len(upcoming))]
    return q_ref, qd_ref


def _record(plant: Plant, traj: JointTrajectory, model: mujoco.MjModel, start: np.ndarray, states: np.ndarray,
            readings: np.ndarray, eq_active: np.ndarray, ctrl: np.ndarray, warnings: list,
            revised: tuple | None) -> Recording:
    """The Recording of the first len(readings) samples. Row 0 is `start`, the state at the end of settling (the
    start state itself when there is no settling); row r > 0 is states[r - 1]. MuJoCo computes sensors before it
    integrates, so readings[r] is the sensor row of step r, taken at row r's state."""
    rows = len(readings)
    sl = _state_slices(model)
    track = np.concatenate([start[None], states[:rows - 1]])
    recorded = {name: readings[:, where] for name, where in plant.sensors.items()}
    qpos = track[:, sl["mjSTATE_QPOS"]]
    qvel = track[:, sl["mjSTATE_QVEL"]]
    return Recording(t=traj.t[:rows].copy(), qpos=qpos, q=qpos[:, plant.qpos_adr], qd=qvel[:, plant.dof_adr],
                     ctrl=ctrl[:rows], tool=recorded.pop(plant.robot.tool_sensor), timestep=float(model.opt.timestep),
                     warnings=tuple(warnings), sensors=recorded,
                     eq_active={model.equality(i).name: eq_active[:, i] for i in range(model.neq)},
                     force=readings[:, plant.force_sensors], force_limit=plant.force_limit(),
                     **({} if revised is None else {"q_ref": revised[0], "qd_ref": revised[1]}))
