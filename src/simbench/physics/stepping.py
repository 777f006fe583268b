"""The stepping loops: from the current state through a stretch of control steps, recording every state.

- `OpenLoop`: commands known beforehand, stepped in C through `mujoco.rollout` a chunk at a time; a chunk that
  went wrong (simbench.core.faults) is replayed step by step to find the first step at fault.
- `ClosedLoop`: the controller asked every step, between `mj_step1` (what it reads) and `mj_step2`, as MuJoCo's
  manual advises for control.

Step i of a run is control sample k = max(i - n_settle, 0) at time t = (i - n_settle) dt.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from mujoco import rollout

from simbench.api import Commands, Controller, State
from simbench.core import interrupts
from simbench.core.buffers import WindowBuffer
from simbench.core.errors import RunError, described
from simbench.core.faults import (FATAL, MAX_SPEED, Fault, clear_warnings, fatal_cause, step_fault, unsound,
                                  warnings_raised)
from simbench.core.plant import Plant

CHUNK = 5000  # steps stepped at a time (and an open loop's commands found at a time for them)
FULL = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)


@dataclass(frozen=True)
class Rows:
    """A run's steps as recorded: each step's sensors (computed before integrating, so at the state the step started
    from; n + 1 rows, the last the final state's) and command, and for each recorded row (row r: the state after
    step n_settle + r - 1) its joint positions, the constraints in force from it on, and its full state where the
    row is `kept`. The steppers write up to CHUNK states into `scratch` and then `keep` them, so that a strided run
    never holds every step's state."""

    sensors: np.ndarray | WindowBuffer  # (n + 1, nsensordata)
    controls: np.ndarray | WindowBuffer  # (n, nu), or (0, nu) where the commands are not kept here
    q: np.ndarray | WindowBuffer  # (rows, dof): every recorded row's joint positions
    eq_active: np.ndarray | WindowBuffer  # (rows, neq): the constraints in force from each row on
    states: np.ndarray  # (len(kept), nstate): the full state of the kept rows
    kept: np.ndarray  # the recorded rows whose full state is kept, ascending
    q_columns: np.ndarray  # where the joint positions sit in a full state vector
    qd_columns: np.ndarray  # and their speeds
    qd_peak: np.ndarray  # (dof,): each joint's largest |qd| over the rows recorded so far
    scratch: np.ndarray  # (CHUNK, nstate): the states of the steps not yet kept
    n_settle: int
    t0: float  # the simulated time of the plan's first sample

    @classmethod
    def empty(cls, model: mujoco.MjModel, n_settle: int, n_track: int, every: int = 1,
              q_columns: np.ndarray | None = None, start: np.ndarray | None = None, controls: bool = True,
              window: int | None = None, qd_columns: np.ndarray | None = None) -> "Rows":
        """The rows of a run of n_settle + n_track steps keeping every `every`-th row whole (kept_rows); `start`:
        row 0's state when there is no settling; `controls`: whether to keep the commands (not an open loop's, a
        second copy); `window`: hold a window of this many samples and a chunk of steps only (WindowBuffer)."""
        n, nstate = n_settle + n_track, mujoco.mj_stateSize(model, FULL)
        q_columns = np.zeros(0, int) if q_columns is None else q_columns
        qd_columns = np.zeros(0, int) if qd_columns is None else qd_columns
        kept = kept_rows(n_track + 1, every)
        scratch = min(CHUNK, max(n, 1))

        def empty(length: int, width: int, dtype=float) -> np.ndarray | WindowBuffer:
            if window is None:
                return np.empty((length, width), dtype)
            # the settling steps and the samples not yet analysed (fewer than a window), then a chunk of steps
            return WindowBuffer(length, n_settle + window + scratch + 1, (width,), dtype)

        rows = cls(sensors=empty(n + 1, model.nsensordata), controls=empty(n if controls else 0, model.nu),
                   q=empty(n_track + 1, len(q_columns)), eq_active=empty(n_track + 1, model.neq, bool),
                   states=np.empty((len(kept), nstate)), kept=kept,
                   q_columns=q_columns, qd_columns=qd_columns, qd_peak=np.zeros(len(qd_columns)),
                   scratch=np.empty((scratch, nstate)), n_settle=n_settle,
                   t0=n_settle * model.opt.timestep)
        if start is not None:
            rows.q[0], rows.states[0], rows.qd_peak[:] = start[q_columns], start, np.abs(start[qd_columns])
        return rows

    def keep(self, first: int, stop: int, eq_active: np.ndarray) -> None:
        """Record steps first..stop-1, whose states are scratch[:stop - first], taken with the constraints
        `eq_active` in force (a switch at the last row, applied between the steppers' calls, rewrites its)."""
        skip = max(self.n_settle - 1 - first, 0)  # settling steps: no row
        lo, hi = first + skip - self.n_settle + 1, stop - self.n_settle + 1  # their rows, lo..hi-1
        self.eq_active[max(first - self.n_settle, 0):hi] = eq_active
        if lo >= hi:
            return
        chunk = self.scratch[skip:stop - first]
        self.q[lo:hi] = chunk[:, self.q_columns]
        np.maximum(self.qd_peak, np.abs(chunk[:, self.qd_columns]).max(axis=0, initial=0.0), out=self.qd_peak)
        if len(self.kept) == len(self.q):  # every row kept whole
            self.states[lo:hi] = chunk
            return
        slot = np.minimum(np.searchsorted(self.kept, np.arange(lo, hi)), len(self.kept) - 1)
        hit = self.kept[slot] == np.arange(lo, hi)
        self.states[slot[hit]] = chunk[hit]

    def drop(self, samples: int) -> None:
        """Let the rows of the first `samples` samples go (rows made with a `window`), but for the last command,
        which a closed loop's last sample repeats (sim._Run._commands)."""
        for rows, upto in ((self.sensors, self.n_settle + samples), (self.controls, self.n_settle + samples - 1),
                           (self.q, samples), (self.eq_active, samples)):
            rows.drop(upto)


def kept_rows(n: int, every: int) -> np.ndarray:
    """The rows a recording of n rows keeps whole with stride `every`: 0, every, 2 every, ... and the last."""
    rows = np.arange(0, n, every)
    return rows if rows.size == 0 or rows[-1] == n - 1 else np.append(rows, n - 1)


def state_slices(model: mujoco.MjModel) -> tuple[slice, slice]:
    """Where qpos and qvel sit in a full physics state vector: after the time, in mjtState's order."""
    qpos = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_TIME)
    return slice(qpos, qpos + model.nq), slice(qpos + model.nq, qpos + model.nq + model.nv)


def warning_rows(data: mujoco.MjData, t0: float) -> list[dict]:
    """The non-fatal warnings counted since they were last cleared, as the report lists them; then cleared."""
    found = [{"t": float(data.time - t0), "kind": mujoco.mjtWarning(code).name,
              "count": int(data.warning[code].number)} for code in warnings_raised(data)]
    clear_warnings(data)
    return found


class OpenLoop:
    """Commands known beforehand stepped through `mujoco.rollout`, chunk by chunk: rows.controls, or `planned`, an
    open-loop controller's per sample (an array or api.Commands), read without a copy in the rows."""

    def __init__(self, model: mujoco.MjModel, planned: np.ndarray | Commands | None = None):
        self.slices = state_slices(model)
        self.state = np.empty(mujoco.mj_stateSize(model, FULL))
        self.planned = planned

    def commands(self, rows: Rows, first: int, stop: int) -> np.ndarray:
        """The commands of steps first..stop-1 (a settling step's: the first sample's)."""
        if self.planned is None:
            return rows.controls[first:stop]
        samples = np.maximum(np.arange(first, stop) - rows.n_settle, 0)
        return self.planned.rows(samples) if isinstance(self.planned, Commands) else self.planned[samples]

    def run(self, model: mujoco.MjModel, data: mujoco.MjData, rows: Rows, first: int, stop: int,
            progress=None, after=None) -> list[dict]:
        """Steps first..stop-1 from data's current state; the warnings met (stamped at the end of their chunk).
        Fault at the first step at fault. `after(end)` is called once the steps before `end` are kept."""
        found, k = [], first
        ctrl_spec = int(mujoco.mjtState.mjSTATE_CTRL)
        while k < stop:
            mujoco.mj_getState(model, data, self.state, FULL)
            warmstart = data.qacc_warmstart.copy()
            end = min(k + CHUNK, stop)
            controls = self.commands(rows, k, end)
            try:
                rollout.rollout(model, data, self.state[None], controls[None], control_spec=ctrl_spec,
                                initial_warmstart=warmstart[None], state=rows.scratch[None, :end - k],
                                sensordata=rows.sensors[k:end][None])
                stopped = False
            except mujoco.FatalError:  # MuJoCo gave up (out of arena memory): found again when replayed
                stopped = True
            if stopped or self._went_wrong(model, data, rows.scratch[:end - k]):
                step, cause = _locate(model, data, self.state, warmstart, controls)
                rows.keep(k, k + step, data.eq_active)  # the steps before the one at fault
                raise Fault(k + step, cause)
            rows.keep(k, end, data.eq_active)
            found += warning_rows(data, rows.t0)
            if progress is not None:
                progress.update(end - k)
            if after is not None:
                after(end)
            k = end
        return found

    def _went_wrong(self, model: mujoco.MjModel, data: mujoco.MjData, chunk: np.ndarray) -> bool:
        qpos, qvel = self.slices
        return bool(set(warnings_raised(data)) & FATAL) or unsound(model, chunk[:, qpos], chunk[:, qvel]) is not None


def _locate(model, data, state: np.ndarray, warmstart: np.ndarray, controls: np.ndarray) -> tuple[int, str]:
    """Replay a chunk that went wrong one step at a time; the first step at fault and why (data left there)."""
    mujoco.mj_setState(model, data, state, FULL)
    data.qacc_warmstart[:] = warmstart
    clear_warnings(data)
    for j, u in enumerate(controls):
        data.ctrl[:] = u
        try:
            mujoco.mj_step(model, data)
        except mujoco.FatalError as err:
            return j, fatal_cause(err)
        cause = step_fault(model, data)
        if cause:
            return j, cause
    return len(controls) - 1, "the chunk failed, but not when replayed step by step"


class ClosedLoop:
    """A controller asked for every step's command from the measured state; MuJoCo steps in Python."""

    def __init__(self, plant: Plant, controller: Controller):
        if plant.model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
            raise RunError(f"controller '{controller.name}' is closed-loop, which steps with mj_step1 and "
                           f"mj_step2; the {plant.robot.name} scene's RK4 integrator cannot be split so (use "
                           "implicitfast or Euler)")
        self.plant = plant
        self.controller = controller
        self.nu = plant.model.nu

    def run(self, model: mujoco.MjModel, data: mujoco.MjData, rows: Rows, first: int, stop: int,
            progress=None, after=None) -> list[dict]:
        """As OpenLoop.run, each step commanded by the controller; CommandFault at the first bad command."""
        found, size, base = [], len(rows.scratch), first
        try:
            for base in range(first, stop, size):  # a scratch's worth of steps at a time
                end = min(base + size, stop)
                found += self._steps(model, data, rows, base, end, progress)
                rows.keep(base, end, data.eq_active)
                if after is not None:
                    after(end)
        except Fault as fault:
            rows.keep(base, fault.step, data.eq_active)  # the steps before the one at fault
            raise
        return found

    def _steps(self, model: mujoco.MjModel, data: mujoco.MjData, rows: Rows, first: int, stop: int,
               progress) -> list[dict]:
        """Steps first..stop-1 (at most a scratch's worth) into rows; the warnings met."""
        found = []
        qpos_adr, dof_adr, dt, n_settle = self.plant.qpos_adr, self.plant.dof_adr, model.opt.timestep, rows.n_settle
        qpos, qvel, warned = data.qpos, data.qvel, data.warning.number  # views, read after every step
        for i in range(first, stop):
            try:
                mujoco.mj_step1(model, data)  # positions and velocities: what the controller may read
                state = State(k=max(i - n_settle, 0), t=(i - n_settle) * dt, q=qpos[qpos_adr], qd=qvel[dof_adr],
                              qpos=qpos.copy(), qvel=qvel.copy(), data=data)
                rows.controls[i] = data.ctrl[:] = self._command(state, i)
                mujoco.mj_step2(model, data)  # forces, acceleration, integration
            except mujoco.FatalError as err:
                raise Fault(i, fatal_cause(err)) from None
            mujoco.mj_getState(model, data, rows.scratch[i - first], FULL)
            rows.sensors[i] = data.sensordata
            if warned.any() or not np.abs(qvel).max() <= MAX_SPEED:  # NaN fails the comparison too
                cause = step_fault(model, data)
                if cause:
                    raise Fault(i, cause)
                found += warning_rows(data, rows.t0)
            if progress is not None and i % 1000 == 999:
                progress.update(1000)
        return found

    def _command(self, state: State, step: int) -> np.ndarray:
        """The controller's command for `state`, checked: CommandFault naming what is wrong with it."""
        name = self.controller.name
        try:
            u = np.asarray(self.controller.commands(state), dtype=float)
        except BaseException as err:  # a user's controller: whatever it raises (sys.exit too) is reported
            if interrupts.is_press(err):
                raise
            raise CommandFault(step, f"controller '{name}' raised {described(err)}") from None
        if u.shape != (self.nu,):
            raise CommandFault(step, f"controller '{name}' returned commands of shape {u.shape}; ({self.nu},) "
                                     "expected, one per actuator")
        if not np.isfinite(u.sum()) and not np.isfinite(u).all():  # the sum first: one check when all is well
            bad = int(np.flatnonzero(~np.isfinite(u))[0])
            raise CommandFault(step, f"controller '{name}' commanded {u[bad]} to actuator "
                                     f"'{self.plant.model.actuator(bad).name}'")
        return u


class CommandFault(Fault):
    """A controller's command that cannot be applied, at the step it was asked for."""
