"""An episode's exact snapshot and replay, copies and pickles of its physics, and the servo as a policy
(simbench.env re-exports them)."""

from __future__ import annotations

import copy
import copyreg
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from dm_control.rl import control

from simbench.env.episode import Physics, track_of
from simbench.physics.controllers import Servo

# Everything that decides the next steps: the integration state (warm start included), what switches edited
_STATE = mujoco.mjtState.mjSTATE_INTEGRATION
_ROWS = ("_qpos", "_qvel", "_readings", "_ctrl", "_eq")  # the recording, rows 0..k
_TASK = ("k", "failure", "_command", "plan", "n", "scenario", "_start", "_eq_active", "_switches", "_stops", "_settler",
         "_hold", "_queue", "drawn")  # the RL mode's delayed actions and what its randomisation drew


@dataclass(frozen=True)
class Snapshot:
    """An episode at a control step, for `restore`: the physics (with the model's randomised values, in the RL
    mode), the task's episode state, its random state (random tasks, the RL mode's noise) and the environment's
    step count."""

    state: np.ndarray
    model: tuple
    randomised: dict[str, np.ndarray]
    physics: dict[str, Any]
    task: dict[str, Any]
    rows: dict[str, np.ndarray]
    references: Any
    warnings: list
    random: Any
    environment: dict[str, Any]


def snapshot(env: control.Environment) -> Snapshot:
    """The episode as it is now: replaying the same actions after `restore` gives the same steps, bit for bit.

    Args:
        env: An environment of `load`.

    Returns:
        The snapshot.
    """
    task, physics = track_of(env), env.physics
    model, data = physics.model.ptr, physics.data.ptr
    state = np.empty(mujoco.mj_stateSize(model, _STATE))
    mujoco.mj_getState(model, data, state, _STATE)
    rows = {name: getattr(task, name)[:task.k + 1].copy() for name in _ROWS}
    randomiser = getattr(task, "_randomiser", None)  # the RL mode's domain randomisation
    randomised = {} if randomiser is None else {name: getattr(model, name).copy() for name in randomiser.nominal}
    return Snapshot(state=state, model=(model.eq_data.copy(), model.eq_active0.copy(), int(model.opt.disableactuator)),
                    randomised=randomised,
                    physics={"t0": physics.t0, "readings": physics.readings.copy()},
                    task={name: copy.copy(getattr(task, name)) for name in _TASK if hasattr(task, name)},
                    rows=rows, references=copy.deepcopy(task.references), warnings=list(task.warnings),
                    random=None if task._random is None else task._random.get_state(),
                    environment={"_step_count": env._step_count, "_reset_next_step": env._reset_next_step})


def restore(env: control.Environment, snap: Snapshot) -> None:
    """Put the episode back as it was at a snapshot.

    Args:
        env: The environment the snapshot was taken of (or one over the same scenario and task).
        snap: The snapshot.
    """
    task, physics = track_of(env), env.physics
    model, data = physics.model.ptr, physics.data.ptr
    for name, value in snap.randomised.items():  # the draw of the snapshot's episode, as Randomiser.draw applies it
        getattr(model, name)[:] = value
    if snap.randomised:
        mujoco.mj_setConst(model, data)
    model.eq_data[:], model.eq_active0[:] = snap.model[:2]
    model.opt.disableactuator = snap.model[2]
    for name, value in snap.task.items():
        setattr(task, name, copy.copy(value))
    task._rows(model)  # rows for the plan restored, then the recorded ones
    task.k, task.failure, task._command = snap.task["k"], snap.task["failure"], snap.task["_command"].copy()
    for name, rows in snap.rows.items():
        getattr(task, name)[:len(rows)] = rows
    task.references, task.warnings = copy.deepcopy(snap.references), list(snap.warnings)
    if snap.random is not None and task._random is not None:
        task._random.set_state(snap.random)
    mujoco.mj_resetData(model, data)
    mujoco.mj_setState(model, data, snap.state, _STATE)
    mujoco.mj_step1(model, data)  # the position- and velocity-dependent quantities the next mj_step2 uses
    physics.t0, physics.readings = snap.physics["t0"], snap.physics["readings"].copy()
    for name, value in snap.environment.items():
        setattr(env, name, value)


_REMADE = frozenset({"counts"})  # views of the data, made anew with it


def _reduce_physics(physics: Physics) -> tuple:
    """How copy.deepcopy and pickle take an episode's Physics: dm_control's keeps only the data (its
    __getstate__), which would lose the episode (the copy then steps unrecorded, past the plan's end, its time off
    by the settle); the attributes Physics declares beyond dm_control's go with it (the time origin, the last
    step's sensors, the task that records each step)."""
    own = {name: value for name, value in vars(physics).items()
           if name in Physics.__annotations__ and name not in _REMADE}
    return _rebuilt_physics, (physics.data, own)


def _rebuilt_physics(data: Any, own: dict[str, Any]) -> Physics:
    """A Physics over the data (dm_control's after_reset: mj_forward and mj_step1, which leave the state as the
    step left it), with the episode's attributes."""
    physics = Physics(data)
    vars(physics).update(own)
    return physics


copyreg.pickle(Physics, _reduce_physics)


def servo_policy(env: control.Environment) -> Callable[[Any], np.ndarray]:
    """simbench's servo as a policy: at one physics step a control step, it reproduces `simbench.evaluate`'s run.

    Args:
        env: An environment of `load`, under position actuation.

    Returns:
        The policy, from a timestep (or an observation) to the position targets the servo commands for the
        references the observation shows (as the plan's feedback revised them; with a flat observation, the
        task's references at its sample).

    Raises:
        ValueError: The environment is under torque actuation.
    """
    task = track_of(env)
    if task.actuation != "position":
        raise ValueError("the servo's actions are position targets: load the environment with position actuation")
    servo = Servo.from_scenario(task.scenario)
    servo.bind(task.plant, task.plan)
    act = task.plant.actuators

    def policy(timestep: Any) -> np.ndarray:
        obs = getattr(timestep, "observation", timestep)
        if isinstance(obs, dict) and "q_ref" in obs:
            q_ref, qd_ref = obs["q_ref"], obs["qd_ref"]
        else:
            q_ref, qd_ref = task.q_ref[task.k], task.qd_ref[task.k]
        return servo.targets(np.asarray(q_ref)[None], np.asarray(qd_ref)[None])[0, act]

    return policy
