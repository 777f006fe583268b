"""The episode of a scenario as dm_control's Physics and Task: simbench's stepping, switching and recording
inside `control.Environment` (simbench.env builds them; its docstring says what an episode is)."""

from __future__ import annotations

import bisect
import copy
from collections import OrderedDict
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import mujoco
import numpy as np
from dm_control.mujoco import wrapper
from dm_control.rl import control
from dm_env import specs

from simbench.api import Array, JointTrajectory
from simbench.core.faults import Fault, clear_warnings, quiet_mujoco
from simbench.core.indices import as_slice, copied
from simbench.core.plant import Plant
from simbench.env.bounds import action_bounds, joint_bounds
from simbench.env.pixels import FittedRendering
from simbench.env.substeps import in_c, in_python
from simbench.env.task_pool import TaskPool
from simbench.physics.computed_torque import ComputedTorque, ComputedTorqueSettings
from simbench.physics.controllers import Servo
from simbench.physics.observation import observe
from simbench.physics.sim import Recording, Revisions, recording
from simbench.physics.stepping import ClosedLoop, OpenLoop, Rows, state_slices, warning_rows
from simbench.physics.switches import apply_switch, switch_steps
from simbench.scenario import Scenario

_REWARD_AT_TOLERANCE = 0.5  # the reward when the tool is analysis.path_tolerance off its reference
_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


class Physics(FittedRendering):
    """dm_control's Physics of a simbench scene, stepped and checked as simbench's closed loop, its frames at their
    own size's cost (`simbench.env.pixels`).

    Attributes:
        readings: The sensors of the last step, at its start state.
        counts: MuJoCo's warning counters.
        t0: The plan's start in MuJoCo's time (s).
        track: The task that records each physics step.
        c_loop: Whether a control step's physics steps run in MuJoCo's C loop where they can (False: one at a
            time in Python, as a control step of one physics step always does).
    """

    readings: Array
    counts: Array
    t0: float = 0.0
    track: Track
    c_loop: bool = True

    def _reload_from_data(self, data: wrapper.MjData) -> None:
        super()._reload_from_data(data)
        self.counts = data.ptr.warning.number  # a view of MuJoCo's warning counters
        self.readings = data.ptr.sensordata.copy()

    def after_reset(self) -> None:
        """dm_control's mj_forward with the actuators off (after a reset or a copy), then mj_step1: the next step
        starts from the position- and velocity-dependent quantities of the actual state, as simbench's closed loop
        leaves them (the actuators' velocities included, which the servos' damping uses)."""
        super().after_reset()
        mujoco.mj_step1(self.model.ptr, self.data.ptr)

    def copy(self, share_model: bool = False) -> Physics:
        """A copy at the episode's time, for looking ahead: it steps as dm_control's Physics does, unrecorded and
        without the plan's switches.

        Args:
            share_model: Whether the copy shares the model.

        Returns:
            The copy.
        """
        new = super().copy(share_model)
        new.t0 = self.t0
        return new

    def step(self, nstep: int = 1) -> None:
        """Step the physics as simbench's closed loop does (mj_step2, then mj_step1), the task recording each step.

        The steps up to the next planned switch run in MuJoCo's C loop (`simbench.env.substeps`) where `c_loop`
        is set and they are more than one: the same physics, recorded alike. No step goes past the plan's last
        sample; a step that fails ends the episode at the last sound state (`Track.failure` says why). A copy (no
        task) steps as dm_control's Physics.

        Args:
            nstep: The most physics steps to take.
        """
        if not hasattr(self, "track"):
            super().step(nstep)
            return
        track = self.track
        with quiet_mujoco():
            while nstep > 0 and track.k < track.n - 1 and track.failure is None:
                commands = track.controls(self, track.stretch(nstep))
                if not (self.c_loop and len(commands) > 1 and in_c(self, commands)):
                    in_python(self, commands)
                nstep -= len(commands)

    def time(self) -> float:
        """The episode's time, as the observation's.

        Returns:
            The time (s): 0 at the plan's start, the settle before it excluded.
        """
        return float(self.data.time - self.t0)


class Track(control.Task):
    """The scenario's episode: settle at the plan's start, then follow it to its last sample.

    Subclass it for a reward or an observation of your own (`task_kwargs={"task": MyTrack}`).

    Args:
        scenario: The scenario.
        plant: Its compiled robot.
        plan: Its plan.
        physics: The environment's physics.
        random: A seed or a RandomState (dm_control's `base.Task` convention): each reset then draws a new task
            for the robot from it. None: the scenario's own task every time.
        pool: With `random`: each reset takes one of this many random tasks planned ahead in a background process
            (`simbench.env.task_pool`) rather than planning its own. None: a plan at every reset.

    Attributes:
        failure: Why the physics ended the episode; None while it is sound.
        base_scenario: The scenario the environment was made of (`scenario` is the episode's: a random task's).
        pool: The pool of random tasks, made at the first reset (None before, and without `pool`).
        servo_design: The servos simbench designed for a derived arm's first plan, as report.json's
            `control.servo_design` has them (empty where none was designed; `load` sets it).

    Raises:
        TypeError: `random` is neither a seed nor a RandomState.
        ValueError: A `pool` without `random`, or not a count >= 1.
    """

    servo_design: tuple[dict, ...] = ()

    def __init__(self, scenario: Scenario, plant: Plant, plan: JointTrajectory, physics: Physics,
                 random: int | np.random.RandomState | None = None, pool: int | None = None):
        super().__init__()
        if isinstance(random, bool) or not isinstance(random, (type(None), int, np.integer, np.random.RandomState)):
            raise TypeError("random must be a seed (an int) or a numpy.random.RandomState, got "
                            f"{type(random).__name__}")
        if pool is not None and (random is None or isinstance(pool, bool) or not isinstance(pool, (int, np.integer))
                                 or pool < 1):
            raise ValueError(f"pool: a number of random tasks >= 1, with random set, expected; got {pool!r}")
        self.scenario = self.base_scenario = scenario
        self.plant, self.actuation, self.pool_size = plant, plant.actuation, pool
        self.pool: TaskPool | None = None
        self.random = random if random is None or isinstance(random, np.random.RandomState) \
            else np.random.RandomState(random)
        physics.track = self
        model, data = physics.model.ptr, physics.data.ptr
        self.dt = float(model.opt.timestep)
        self.n_settle = round(scenario.sim.settle / self.dt)
        self._model0 = (model.eq_data.copy(), model.eq_active0.copy(), int(model.opt.disableactuator))
        self._tool = plant.sensors[plant.robot.tool_sensor]
        self._joints_at = (as_slice(plant.qpos_adr), as_slice(plant.dof_adr))  # the joints' q, qd in the data
        self._tolerance = scenario.analysis.path_tolerance
        self.set_bounds(model, plan)
        self.failure: str | None = None
        self._use(plan, data)
        self._rows(model)

    def set_bounds(self, model: mujoco.MjModel, plan: JointTrajectory) -> None:
        """The bounds for a plan's references: the actions' (`bounds`, `action_bounds`) and what random joint moves
        are drawn within (`target_bounds`: position targets, under torque actuation too)."""
        self.bounds = action_bounds(model, self.plant, plan)
        self.target_bounds = self.bounds if self.actuation == "position" else joint_bounds(model, self.plant, plan)

    def _use(self, plan: JointTrajectory, data: mujoco.MjData) -> None:
        """Episodes of this plan from the start state in `data` (posed by switches.at_start)."""
        model = self.plant.model
        self.plan, self.n = plan, plan.t.size  # samples; an episode is n - 1 steps
        # The start: the state and grips at_start left, and what switching changes in the model (restored at reset).
        self._start = np.empty(mujoco.mj_stateSize(model, _FULL))
        mujoco.mj_getState(model, data, self._start, _FULL)
        self._eq_active = data.eq_active.copy()
        steps = switch_steps(model, plan)
        self._switches: dict[int, list] = {}
        for switch, k in zip(plan.switches, steps):
            if 0 < k < self.n - 1:  # as simulate: the step-0 ones are in the start, none after the last step
                self._switches.setdefault(int(k), []).append(switch)
        self._stops = sorted(self._switches) + [self.n - 1]  # where a stretch of physics steps ends, at the latest
        self._settler = self._settling_controller()

    def _settling_controller(self) -> Servo | ComputedTorque:
        """What holds the start while the robot settles: the servo (position) or computed torque (torque)."""
        settings = self.scenario.control
        if self.actuation == "torque":
            settler: Servo | ComputedTorque = ComputedTorque(settings if isinstance(settings, ComputedTorqueSettings)
                                                             else None)
        else:
            settler = Servo(self.scenario.sim.velocity_feedforward)
        settler.bind(self.plant, self.plan)
        if isinstance(settler, Servo):
            self._hold = settler.open_loop()[0].copy()  # simulate's first command, held while settling
        return settler

    def _rows(self, model: mujoco.MjModel) -> None:
        """An empty recording, and the references and sample of an episode's start."""
        n = self.n
        self.k = 0
        self.failure = None
        self.references = Revisions(self.plan)  # as the plan's feedback revises them, in copies
        self.warnings: list[dict] = []
        self._qpos, self._qvel = np.empty((n, model.nq)), np.empty((n, model.nv))
        self._readings, self._ctrl = np.empty((n, model.nsensordata)), np.zeros((n, model.nu))
        self._eq = np.empty((n, model.neq), bool)
        self._command = np.zeros(model.nu)

    @property
    def _random(self) -> np.random.RandomState | None:
        """`random` under dm_control's name, which shimmy's reset(seed=...) sets."""
        return self.random

    @_random.setter
    def _random(self, value: np.random.RandomState) -> None:
        if self.random is not None:  # a seed reseeds random tasks; without them, the scenario's task stays
            self.random = value
            if self.pool is not None:  # its tasks were seeded by the old state
                self.pool.close()
                self.pool = None

    @property
    def q_ref(self) -> Array:
        """The joint references (N, dof) as the plan's feedback has revised them so far."""
        return self.references.q_ref

    @property
    def qd_ref(self) -> Array:
        """Their rates (N, dof), revised with them."""
        return self.references.qd_ref

    # --- control.Task -----------------------------------------------------------------------------------------

    def initialize_episode(self, physics: Physics) -> None:
        """Start an episode: a new random task if `random` is set, then the start pose and grips, settled.

        Args:
            physics: The physics.

        Raises:
            PhysicsError: The settle at the start pose failed.
        """
        model, data = physics.model.ptr, physics.data.ptr
        model.eq_data[:], model.eq_active0[:] = self._model0[:2]
        model.opt.disableactuator = self._model0[2]
        if self.random is not None:
            from simbench.env.random_task import draw
            if self.pool_size and self.pool is None:
                self.pool = TaskPool(self.base_scenario, self.target_bounds, self.dt, self.pool_size,
                                     int(self.random.randint(2**31)))
            self._use(*draw(self, model, data))
        mujoco.mj_resetData(model, data)
        mujoco.mj_setState(model, data, self._start, _FULL)
        data.eq_active[:] = self._eq_active
        self._rows(model)
        physics.t0 = self.n_settle * self.dt
        rows = Rows.empty(model, self.n_settle, 0)
        with quiet_mujoco():
            try:
                if isinstance(self._settler, Servo):
                    rows.controls[:] = data.ctrl[:] = self._hold
                    found = OpenLoop(model).run(model, data, rows, 0, self.n_settle)
                else:
                    found = ClosedLoop(self.plant, self._settler).run(model, data, rows, 0, self.n_settle)
                mujoco.mj_step1(model, data)
            except Fault as fault:
                raise control.PhysicsError(f"the physics failed while settling at the plan's start (step "
                                           f"{fault.step} of {self.n_settle}): {fault.cause}") from None
        self.warnings += found
        self._qpos[0], self._qvel[0], self._eq[0] = data.qpos, data.qvel, data.eq_active

    def before_step(self, action: Any, physics: Physics) -> None:
        """Give the action to the joints' actuators, held for the control step.

        Args:
            action: One finite value per joint.
            physics: The physics.

        Raises:
            ValueError: The action is not one finite value per joint.
        """
        action = self.checked(action)
        self._command = ctrl = np.zeros(physics.model.ptr.nu)  # zero but for the joints' actuators
        ctrl[self.plant.actuators] = action
        physics.data.ptr.ctrl[:] = ctrl

    def checked(self, action: Any) -> Array:
        """The action as floats; ValueError saying what is wrong where it is not one finite value per joint."""
        action, robot = np.asarray(action, dtype=float), self.plant.robot
        if action.shape != (robot.dof,):
            raise ValueError(f"an action has one value per joint ({', '.join(robot.joints)}): shape ({robot.dof},) "
                             f"expected, got {action.shape}")
        if np.count_nonzero(np.isfinite(action)) < action.size:  # ndarray.all's answer at a third of its time
            bad = int(np.flatnonzero(~np.isfinite(action))[0])
            raise ValueError(f"the action for joint '{robot.joints[bad]}' is {action[bad]}")
        return action

    def stretch(self, nstep: int) -> int:
        """How many of `nstep` physics steps run before the plan's end or its next switch, whichever comes first."""
        return min(nstep, self._next_stop(self.k) - self.k)

    def _next_stop(self, k: int) -> int:
        """The first planned switch's sample after sample k, or the plan's last sample (a switch is before it:
        `_use`)."""
        stops = self._stops
        return stops[min(bisect.bisect_right(stops, k), len(stops) - 1)]

    def controls(self, physics: Physics, steps: int) -> Array:
        """The commands (steps, nu) of the next physics steps: the action before_step gave, held.

        Override it for commands that change within a control step (known at its start).

        Args:
            physics: The physics.
            steps: How many physics steps.

        Returns:
            One row of `data.ctrl` a step.
        """
        return np.repeat(physics.data.ptr.ctrl[None], steps, axis=0)

    def record(self, physics: Physics, command: Array) -> None:
        """Record a physics step; at a planned switch's sample, apply it and the plan's feedback on it.

        Args:
            physics: The physics.
            command: The step's command (nu,).
        """
        data = physics.data.ptr
        self._readings[self.k], self._ctrl[self.k] = physics.readings, command
        self.k = k = self.k + 1
        self._qpos[k], self._qvel[k] = data.qpos, data.qvel
        if np.count_nonzero(physics.counts):
            self.warnings += warning_rows(data, physics.t0)
        self._reached(physics)

    def record_steps(self, physics: Physics, states: Array, commands: Array,
                     slices: tuple[slice, slice] | None = None) -> None:
        """Record physics steps that ran without a warning, as `record` records each; their sensors are in the
        recording already (`sensor_rows`, which the rollout writes into).

        Args:
            physics: The physics.
            states: Each step's full physics state after it (steps, nstate).
            commands: Each step's command (steps, nu).
            slices: Where qpos and qvel sit in a state (stepping.state_slices), if the caller has them.
        """
        qpos, qvel = slices or state_slices(physics.model.ptr)
        first, stop = self.k, self.k + len(commands)
        self._ctrl[first:stop] = commands
        self._qpos[first + 1:stop + 1], self._qvel[first + 1:stop + 1] = states[:, qpos], states[:, qvel]
        if self._eq.shape[1]:  # (a model without equality constraints has none to record)
            self._eq[first + 1:stop] = physics.data.ptr.eq_active
        self.k = stop
        self._reached(physics)

    def sensor_rows(self, steps: int) -> Array:
        """The recording's rows (steps, nsensordata) for the next `steps` physics steps' sensors, written in place."""
        return self._readings[self.k:self.k + steps]

    def _reached(self, physics: Physics) -> None:
        """At the sample just reached: a planned switch applied with the plan's feedback on it, and the constraints
        in force from here on recorded."""
        model, data, k = physics.model.ptr, physics.data.ptr, self.k
        if k in self._switches:
            for switch in self._switches[k]:
                apply_switch(model, data, switch)
                if self.plan.feedback is not None:
                    self.references.apply(self.plan.feedback(switch, model, data, k))
            mujoco.mj_step1(model, data)  # the constraints as they now are, for the next step
        if self._eq.shape[1]:
            self._eq[k] = data.eq_active

    def fail(self, physics: Physics, why: str) -> None:
        """End the episode: the physics back at the last sound sample, `failure` saying why.

        Args:
            physics: The physics.
            why: Why, in words.
        """
        model, data = physics.model.ptr, physics.data.ptr
        self.failure = why
        data.qpos[:], data.qvel[:] = self._qpos[self.k], self._qvel[self.k]
        data.time = physics.t0 + self.plan.t[self.k] - self.plan.t[0]
        data.qacc_warmstart[:] = 0
        mujoco.mj_forward(model, data)
        clear_warnings(data)

    def action_spec(self, physics: Physics) -> specs.BoundedArray:
        """The actions: one value per joint, within `bounds`.

        Args:
            physics: The physics.

        Returns:
            The bounded spec: position targets within the joints' ranges, or torques within the force limits.
        """
        return specs.BoundedArray(shape=(self.plant.robot.dof,), dtype=float, minimum=self.bounds[0],
                                  maximum=self.bounds[1], name="action")

    def get_observation(self, physics: Physics) -> OrderedDict:
        """What the policy sees: `simbench.physics.observation.observation` at this sample, the references as revised.

        Args:
            physics: The physics.

        Returns:
            The observation.
        """
        data, (q_at, qd_at) = physics.data.ptr, self._joints_at
        return observe(self.plant, self.k, float(self.plan.t[self.k]), copied(data.qpos, q_at),
                       copied(data.qvel, qd_at), data, self.q_ref, self.qd_ref, self.plan.tool_ref)

    @contextmanager
    def noiseless(self) -> Iterator[None]:
        """A block in which get_observation draws nothing from the task's random state: where dm_control's
        Environment makes its observation spec (simbench.env.Environment.observation_spec), so that asking for the
        spec (as shimmy's wrapper does when it is made, or unpickled) leaves the episodes a seed gives as they are.
        Track's observation draws nothing; a subclass whose observation is noisy overrides it (RLTrack)."""
        yield

    def get_reward(self, physics: Physics) -> float:
        """The step's reward: dm_control's gaussian `rewards.tolerance` of the tool's tracking error.

        Written out as `0.5 ** ((error / path_tolerance) ** 2)` for speed: 1 on the reference, 0.5 at
        `analysis.path_tolerance`.

        Args:
            physics: The physics.

        Returns:
            The reward; 0 once the physics has failed.
        """
        if self.failure is not None:
            return 0.0
        offset = physics.data.ptr.sensordata[self._tool] - self.plan.tool_ref[self.k]
        # (ndarray.dot: @'s product at less cost, every step)
        return _REWARD_AT_TOLERANCE ** (float(offset.dot(offset)) / self._tolerance ** 2)

    def get_termination(self, physics: Physics) -> float | None:
        """Whether the episode ends here.

        Args:
            physics: The physics.

        Returns:
            The discount: 1 at the plan's last sample (the episode's end), 0 where the physics failed, else None.
        """
        if self.failure is not None:
            return 0.0
        return 1.0 if self.k >= self.n - 1 else None

    # --- the episode as a run ---------------------------------------------------------------------------------

    def recording(self, physics: Physics) -> Recording:
        """The episode so far, as simbench records a closed-loop run.

        The last row's sensors are from mj_forward at the last state, its command the one before.

        Args:
            physics: The physics.

        Returns:
            The recording.
        """
        model, plant, rows = physics.model.ptr, self.plant, self.k + 1
        end = copy.copy(physics.data.ptr)
        mujoco.mj_forward(model, end)
        readings = np.concatenate([self._readings[:rows - 1], end.sensordata[None]])
        qpos = self._qpos[:rows].copy()
        given = self._ctrl[:rows - 1]
        ctrl = np.concatenate([given, given[-1:] if len(given) else end.ctrl[None]])
        revised = {name: ref.copy() for name, ref in self.references.recorded().items()}  # the episode goes on
        return recording(plant, model, self.plan.t[:rows].copy(), readings, qpos[:, plant.qpos_adr], qpos,
                         self._qvel[:rows], self._eq[:rows].copy(), ctrl, self.warnings, **revised)


def track_of(env: control.Environment) -> Track:
    """The Track task of an environment of `simbench.env.load`; TypeError for any other environment."""
    task = getattr(env, "task", None)
    if not isinstance(task, Track):
        raise TypeError(f"expected an environment of simbench.env.load, got {type(env).__name__}")
    return task
