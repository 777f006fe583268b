"""Physics: a controller drives the robot along a JointTrajectory in MuJoCo, and every step is recorded.

The robot settles at the first reference, then tracks; open-loop commands step in C through `mujoco.rollout`,
closed-loop ones every step in Python (simbench.physics.stepping). Planned switches split the run into segments, after
which a plan's feedback may revise the references to come. A strided run may be analysed as it is simulated, a
window at a time (simbench.core.buffers). The first step at fault stops the run with a PhysicsError (ControlError for
a controller's bad command) carrying the recording up to the last sound state (simbench.core.faults).
"""

from __future__ import annotations

import sys
from dataclasses import replace
from typing import TYPE_CHECKING

import mujoco
import numpy as np
from tqdm import tqdm

from simbench.api import Commands, Controller
from simbench.api.recording import Recording
from simbench.api.trajectory import JointTrajectory, joined, revise
from simbench.core.errors import ControlError, PhysicsError, RunError
from simbench.core.faults import Fault, fatal_cause, quiet_mujoco
from simbench.core.plant import Plant
from simbench.physics.controllers import Servo
from simbench.physics.stepping import CHUNK, ClosedLoop, CommandFault, OpenLoop, Rows, state_slices
from simbench.physics.switches import apply_switch, at_start

if TYPE_CHECKING:
    from simbench.analysis import Analyser


def simulate(plant: Plant, traj: JointTrajectory, controller: Controller | None = None, settle: float = 0.2,
             progress: bool = False, record_every: int = 1, revise_in_place: bool = False,
             analyser: Analyser | None = None) -> Recording:
    """Settle at traj's first reference, then track it with `controller` (default: Servo), applying the planned
    switches (on a copy of the model, which switching edits); one row per control sample, whole at every
    `record_every`-th and the last (Recording.kept). PhysicsError or ControlError where the run fails.

    A plan's feedback revises copies of its references (Recording.q_ref), or with `revise_in_place` traj's own
    arrays: two (N, dof) arrays fewer. With an `analyser` the run is analysed a window at a time as it is
    simulated, each window's rows let go once its kept rows are copied out; its Recording holds the kept rows only,
    and the plan at them is the analyser's (Analyser.plan)."""
    if analyser is not None and not (record_every > 1 and analyser.streams):
        raise ValueError("a run is analysed as it is simulated with a recording stride (record_every > 1) and a "
                         "robot whose summary comes a window at a time (Robot.streams)")
    if analyser is not None and traj.feedback is not None and not revise_in_place:
        raise ValueError("a run analysed as it is simulated revises its plan in place (revise_in_place=True)")
    if not np.isclose(plant.model.opt.timestep, traj.dt, rtol=1e-9, atol=0.0):
        raise ValueError(f"trajectory dt {traj.dt} differs from the model timestep {plant.model.opt.timestep}")
    controller = controller if controller is not None else Servo()
    controller.bind(plant, traj)
    with quiet_mujoco():
        run = _Run(plant, traj, controller, settle, record_every, revise_in_place, analyser)
        try:
            return run.go(progress)
        finally:
            run.stream = None  # it refers back to the run: the run's arrays go as it ends, not at the next collection


def commanded(traj: JointTrajectory, rec: Recording) -> JointTrajectory:
    """The plan with the references the run really commanded: its own, or those its feedback revised, then without
    the feedback, which is spent (simulating them again should not revise them twice)."""
    return traj if rec.q_ref is None else replace(traj, q_ref=rec.q_ref, qd_ref=rec.qd_ref, feedback=None)


class Revisions:
    """A plan's references as its feedback revises them (trajectory.revise): the plan's own until the first change,
    then copies, or with `in_place` the plan's own arrays."""

    def __init__(self, traj: JointTrajectory, in_place: bool = False):
        self.traj, self.in_place = traj, in_place
        self.q_ref, self.qd_ref, self.revised = traj.q_ref, traj.qd_ref, False

    def apply(self, change: tuple | None) -> tuple[int, int] | None:
        """Apply a feedback change (k0, columns, q): the rows it changed (k0, hi), or None where there is none."""
        if change is None:
            return None
        if not self.revised:
            if not self.in_place:
                self.q_ref, self.qd_ref = self.q_ref.copy(), self.qd_ref.copy()
            self.revised = True
        return revise(self.q_ref, self.qd_ref, change, self.traj.dt)

    def recorded(self) -> dict[str, np.ndarray]:
        """Recording's q_ref and qd_ref: the references as revised; none where the feedback never changed them."""
        return {"q_ref": self.q_ref, "qd_ref": self.qd_ref} if self.revised else {}


def recording(plant: Plant, model: mujoco.MjModel, t: np.ndarray, readings: np.ndarray, q: np.ndarray,
              qpos: np.ndarray, qvel: np.ndarray, eq_active: np.ndarray, ctrl: np.ndarray, warnings: list[dict],
              **more) -> Recording:
    """A Recording of the run of `model` (the plant's, or the copy switches edit); `more`: Recording's other
    fields."""
    recorded = {name: readings[:, where] for name, where in plant.sensors.items()}
    return Recording(t=t, qpos=qpos, q=q, qd=qvel[:, plant.dof_adr], ctrl=ctrl,
                     tool=recorded.pop(plant.robot.tool_sensor), timestep=float(model.opt.timestep),
                     warnings=tuple(warnings), sensors=recorded,
                     eq_active={model.equality(i).name: eq_active[:, i] for i in range(model.neq)},
                     force=readings[:, _columns(plant.force_sensors)], force_limit=plant.force_limit(), **more)


class _Run:
    """One simulation: the model and data, the recorded rows, the stepper, and the references as revised."""

    def __init__(self, plant: Plant, traj: JointTrajectory, controller: Controller, settle: float, every: int,
                 in_place: bool = False, analyser: Analyser | None = None):
        self.plant, self.traj, self.controller, self.every = plant, traj, controller, every
        self.ctrl = controller.open_loop()  # (N, nu) (an array or Commands), or None for a closed loop
        if self.ctrl is not None:
            _check_finite(self.ctrl, traj)
        self.model, self.data, self.steps = self._start(-settle)
        self.first_state = np.empty(mujoco.mj_stateSize(self.model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
        mujoco.mj_getState(self.model, self.data, self.first_state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        n_settle = int(round(settle / self.model.opt.timestep))
        qpos, qvel = state_slices(self.model)
        self.rows = Rows.empty(self.model, n_settle, traj.t.size - 1, every, qpos.start + plant.qpos_adr,
                               self.first_state, controls=self.ctrl is None,
                               window=None if analyser is None else analyser.window,
                               qd_columns=qvel.start + plant.dof_adr)
        self.stepper = OpenLoop(self.model, self.ctrl) if self.ctrl is not None else ClosedLoop(plant, controller)
        self.warnings: list[dict] = []
        self.references = Revisions(traj, in_place)
        self.stream = None if analyser is None else _Stream(self, analyser)

    def _start(self, t: float) -> tuple[mujoco.MjModel, mujoco.MjData, np.ndarray]:
        """The model and data at the plan's first reference, forwarded (PhysicsError if MuJoCo cannot)."""
        try:
            model, data, steps = at_start(self.plant, self.traj)
            if self.ctrl is not None:
                data.ctrl[:] = self.ctrl[0]
            mujoco.mj_forward(model, data)
        except mujoco.FatalError as err:
            raise PhysicsError(t, fatal_cause(err), self.traj, None) from None
        return model, data, steps

    def go(self, progress: bool) -> Recording:
        """Step every segment between switches; the Recording, or PhysicsError with the one up to the fault."""
        n_settle, n = self.rows.n_settle, len(self.rows.sensors) - 1
        bounds = sorted({int(k) + n_settle for k in self.steps if 0 < k < n - n_settle}) + [n]
        # Windows are analysed as the stepper's chunks come in, on the chunks a run recorded whole takes: MuJoCo's
        # warnings are stamped at the end of their chunk.
        after = None if self.stream is None else (lambda step: self.stream.feed(step - n_settle))
        done = 0
        with tqdm(total=n, desc="simulate", unit="step", disable=not (progress and sys.stderr.isatty()),
                  leave=False) as bar:
            try:
                for stop in bounds:
                    self.warnings += self.stepper.run(self.model, self.data, self.rows, done, stop, bar, after)
                    self._switch(stop - n_settle)
                    done = stop
            except Fault as fault:
                raise self._failure(fault) from None
            self.rows.eq_active[-1] = self.data.eq_active
            mujoco.mj_forward(self.model, self.data)
        self.rows.sensors[-1] = self.data.sensordata
        if self.stream is not None:
            self.stream.feed(n - n_settle + 1, last=True)
            return self.stream.recording(n - n_settle + 1)
        return self._record(self.rows.sensors[n_settle:])

    def _switch(self, k: int) -> None:
        """Apply the switches planned at sample k, and the plan's feedback on each."""
        for switch in (w for w, step in zip(self.traj.switches, self.steps) if 0 < step and step == k):
            apply_switch(self.model, self.data, switch)
            if self.traj.feedback is not None:
                self._revise(self.traj.feedback(switch, self.model, self.data, k))

    def _revise(self, change: tuple | None) -> None:
        """Apply a feedback change (k0, columns, q) to the references and to the controller's commands to come."""
        rows = self.references.apply(change)
        if rows is None:
            return
        self.controller.revise_rows(*rows, self.references.q_ref, self.references.qd_ref)
        if isinstance(self.stepper, OpenLoop):
            self.ctrl = self.stepper.planned = self.controller.open_loop()

    def _failure(self, fault: Fault) -> PhysicsError:
        """The error for a fault, with the recording of every sound row before it: an unsound step fails at the
        time after it, a bad command at the time it was asked."""
        command = isinstance(fault, CommandFault)
        error = ControlError if command else PhysicsError
        rows = fault.step + (0 if command else 1) - self.rows.n_settle  # the rows recorded soundly
        if rows <= 0:
            return error(rows * self.model.opt.timestep, fault.cause, self.traj, None)
        when = float(self.traj.t[rows - 1] + self.model.opt.timestep)
        if self.stream is not None:  # the kept rows before the fault, and the plan at them
            return error(when, fault.cause, self.stream.plan(rows), self.stream.recording(rows))
        partial = self._record(self.rows.sensors[self.rows.n_settle:self.rows.n_settle + rows])
        return error(when, fault.cause, commanded(self.traj, partial), partial)

    def _record(self, readings: np.ndarray) -> Recording:
        """The Recording of the first len(readings) samples: row 0 the state at the end of settling, row r the
        state after step r - 1, whose sensors MuJoCo computed before integrating (readings[r])."""
        rows = len(readings)
        kept = self.rows.kept[self.rows.kept < rows]
        ctrl = self._commands(slice(0, rows) if self.every == 1 else kept)
        return self._recording(self.traj.t[:rows].copy(), readings, self.rows.q[:rows], self.rows.eq_active[:rows],
                               ctrl, slice(0, len(kept)), kept=None if self.every == 1 else kept,
                               qd_peak=self.rows.qd_peak.copy(), **self.references.recorded())

    def _window(self, lo: int, hi: int) -> Recording:
        """Samples lo..hi-1 as Recording.rows gives them (views of the rows held): a streamed run's window."""
        rows = self.rows
        stored = slice(*np.searchsorted(rows.kept, [lo, hi]))
        kept = rows.kept[stored]
        return self._recording(self.traj.t[lo:hi], rows.sensors[rows.n_settle + lo:rows.n_settle + hi],
                               rows.q[lo:hi], rows.eq_active[lo:hi], self._commands(kept), stored, kept=kept - lo)

    def _recording(self, t: np.ndarray, readings: np.ndarray, q: np.ndarray, eq_active: np.ndarray,
                   ctrl: np.ndarray, stored: slice, **more) -> Recording:
        """recording() with the full states of the kept rows `stored` (a slice of Rows.states)."""
        states = self.rows.states[stored]
        qpos, qvel = state_slices(self.model)
        return recording(self.plant, self.model, t, readings, q, states[:, qpos], states[:, qvel], eq_active, ctrl,
                         self.warnings, **more)

    def _commands(self, k: slice | np.ndarray) -> np.ndarray:
        """The commands of samples k (a slice from 0, or sample numbers); a closed loop's last sample, which no step
        follows, repeats the one before."""
        if self.ctrl is not None:
            return self.ctrl[k]
        controls, settle = self.rows.controls, self.rows.n_settle
        k = np.arange(len(controls) - settle + 1)[k] if isinstance(k, slice) else k
        return controls[settle + np.minimum(k, len(controls) - settle - 1)]


class _Stream:
    """A run's samples handed to an Analyser a window at a time as they are simulated: each window's kept rows
    copied out, then its rows let go (Rows.drop)."""

    def __init__(self, run: _Run, analyser: Analyser):
        self.run, self.analyser, self.window = run, analyser, analyser.window
        rows = run.rows
        kept = len(rows.kept)
        self.lo, self.copied = 0, 0  # the first sample not analysed; the kept rows copied out
        self.sensors, self.q = np.empty((kept, rows.sensors.shape[1])), np.empty((kept, rows.q.shape[1]))
        self.eq_active = np.empty((kept, rows.eq_active.shape[1]), bool)
        self.controls = np.empty((kept, run.model.nu))  # the commands at the kept rows

    def feed(self, done: int, last: bool = False) -> None:
        """Analyse the whole windows among the first `done` samples (with `last`, the rest too), then let them go."""
        while self.lo + self.window <= done or (last and self.lo < done):
            hi = min(self.lo + self.window, done)
            self.analyser.add(self.run._window(self.lo, hi))
            self._copy(hi)
            self.run.rows.drop(hi)
            self.lo = hi

    def plan(self, done: int) -> JointTrajectory:
        """The plan at the kept rows of the first `done` samples."""
        kept = self.run.rows.kept
        rest = self.run.traj.rows(kept[(kept >= self.lo) & (kept < done)])
        return joined([*self.analyser.plan_kept, rest])

    def _copy(self, done: int) -> None:
        """Copy out the kept rows among the first `done` samples not copied yet."""
        rows, settle = self.run.rows, self.run.rows.n_settle
        stop = int(np.searchsorted(rows.kept, done))
        k = rows.kept[self.copied:stop]
        self.sensors[self.copied:stop] = rows.sensors[settle + k]
        self.q[self.copied:stop] = rows.q[k]
        self.eq_active[self.copied:stop] = rows.eq_active[k]
        self.controls[self.copied:stop] = self.run._commands(k)
        self.copied = stop

    def recording(self, done: int) -> Recording:
        """The kept rows of the first `done` samples (all simulated), as Recording.thinned gives them."""
        self._copy(done)
        run, m = self.run, self.copied
        return run._recording(run.traj.t[run.rows.kept[:m]], self.sensors[:m], self.q[:m], self.eq_active[:m],
                              self.controls[:m], slice(0, m), qd_peak=run.rows.qd_peak.copy())


def _columns(index: np.ndarray) -> slice | np.ndarray:
    """Columns `index` as a slice where they are consecutive (a view of the sensor rows, not an (N, dof) copy)."""
    if len(index) and np.array_equal(index, np.arange(index[0], index[0] + len(index))):
        return slice(int(index[0]), int(index[0]) + len(index))
    return index


def _check_finite(ctrl: np.ndarray | Commands, traj: JointTrajectory) -> None:
    """RunError at the first sample without a finite command, reading the commands a chunk at a time."""
    for lo in range(0, len(ctrl), CHUNK):
        bad = ~np.isfinite(ctrl[lo:lo + CHUNK]).all(axis=1)
        if bad.any():
            raise RunError(f"the plan has no finite reference at t = {traj.t[lo + np.argmax(bad)]:.4f} s")
