"""A control step's physics steps, in MuJoCo's C loop (`in_c`) or one at a time in Python (`in_python`): the rollout
steps them with their commands (known at the control step's start) and records every state and sensor reading in
C, where the Python loop pays for mj_step2, its checks, mj_step1 and the recording one step at a time.

mj_step is mj_step1 then mj_step2 (MuJoCo's documentation), so the rollout takes the same steps; a stretch in
which the Python loop would have looked closer at a step (a warning counted, a speed past MAX_SPEED or NaN) is
stepped again in Python from its start, which finds and reports the step at fault (or records the warnings) as it
always does.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np
from mujoco import rollout

from simbench.api import Array
from simbench.core.faults import MAX_SPEED, clear_warnings, fatal_cause, step_fault
from simbench.physics.stepping import FULL, state_slices

if TYPE_CHECKING:
    from simbench.env.episode import Physics

_CTRL = int(mujoco.mjtState.mjSTATE_CTRL)
_POOL: list[rollout.Rollout] = []  # one Rollout on the calling thread (nthread=0), made when first needed


def _rollout() -> rollout.Rollout:
    """The process's Rollout: made once (its per-call set-up is what makes mujoco.rollout.rollout slow for a few
    steps)."""
    if not _POOL:
        _POOL.append(rollout.Rollout(nthread=0))
    return _POOL[0]


def in_c(physics: Physics, commands: Array) -> bool:
    """Step and record the physics through `commands` (steps, nu) in MuJoCo's C loop (MuJoCo kept quiet by the
    caller: Physics.step).

    Args:
        physics: The environment's physics, its data as mj_step1 leaves it and no warning counted.
        commands: One command a physics step, none of them past the plan's end or its next switch.

    Returns:
        Whether the steps ran and were recorded; False: the physics is back where it was, to be stepped in Python.
    """
    model, data, track = physics.model.ptr, physics.data.ptr, physics.track
    if np.count_nonzero(physics.counts):  # (a tenth of ndarray.any's time: an environment's every control step)
        return False
    steps = len(commands)
    start, warmstart, states, slices = _buffers(physics, steps)
    sensors = track.sensor_rows(steps)  # written in place: rows of the recording
    mujoco.mj_getState(model, data, start[0], FULL)
    np.copyto(warmstart[0], data.qacc_warmstart)
    try:
        _rollout().rollout([model], [data], start, np.ascontiguousarray(commands, dtype=float)[None],
                           control_spec=_CTRL, skip_checks=True, nstep=steps, initial_warmstart=warmstart,
                           state=states, sensordata=sensors[None])
        mujoco.mj_step1(model, data)  # the next step's position and velocity, as the Python loop leaves them
        # the Python loop's own test of a step (NaN fails the comparison), over every step at once, on a view
        speed = np.maximum.reduce(np.abs(states[0, :, slices[1]]), axis=None)
        sound = not np.count_nonzero(physics.counts) and speed <= MAX_SPEED
    except mujoco.FatalError:  # MuJoCo gave up: found again, and reported, when stepped in Python
        sound = False
    if not sound:  # (the rows it wrote are written again by the Python loop)
        mujoco.mj_setState(model, data, start[0], FULL)
        data.qacc_warmstart[:] = warmstart[0]
        clear_warnings(data)
        mujoco.mj_step1(model, data)
        return False
    physics.readings = sensors[-1]  # a row the recording keeps as it is
    track.record_steps(physics, states[0], commands, slices)
    return True


def in_python(physics: Physics, commands: Array) -> None:
    """One physics step a command, each checked and recorded (until one fails: the track's `fail` then says when
    and why); MuJoCo kept quiet by the caller (Physics.step)."""
    model, data, track = physics.model.ptr, physics.data.ptr, physics.track
    for command in commands:
        data.ctrl[:] = command
        try:
            mujoco.mj_step2(model, data)
            cause = None
        except mujoco.FatalError as err:
            cause = fatal_cause(err)
        # NaN fails the comparison: one reduction finds a NaN, an infinite or a diverging speed
        if cause is None and (np.count_nonzero(physics.counts) or not np.abs(data.qvel).max(initial=0.0) <= MAX_SPEED):
            cause = step_fault(model, data)
        if cause:  # (at the end of the step that failed: MuJoCo may have reset the data's time)
            track.fail(physics, f"the physics failed at t = {track.plan.t[track.k] + track.dt:.4f} s: {cause}")
            return
        physics.readings = data.sensordata.copy()
        mujoco.mj_step1(model, data)
        track.record(physics, command)


def _buffers(physics: Physics, steps: int) -> tuple[Array, Array, Array, tuple[slice, slice]]:
    """What a rollout of `steps` reads and writes (the start state, its warm start, the states), made once a
    stretch length and kept on the physics (what it records is copied out of them), and where qpos and qvel sit in
    a state (stepping.state_slices)."""
    made = physics.__dict__.setdefault("_c_buffers", {})
    if steps not in made:
        model = physics.model.ptr
        size = mujoco.mj_stateSize(model, FULL)
        made[steps] = (np.empty((1, size)), np.empty((1, model.nv)), np.empty((1, steps, size)),
                       state_slices(model))
    return made[steps]
