"""What a policy sees at a control step, and what `simbench.env`'s environments observe: the measured joints and
tool, and the plan's references now and a few samples ahead. Every entry is a float array, SI units."""

from __future__ import annotations

from collections import OrderedDict

import mujoco
import numpy as np

from simbench.api import Array, State
from simbench.core.plant import Plant

AHEAD = (1, 5, 20)
"""The samples ahead of now at which the observation shows the references."""
_AHEAD = np.array(AHEAD)


def observation(plant: Plant, state: State, q_ref: Array, qd_ref: Array, tool_ref: Array) -> OrderedDict:
    """What a policy sees at a control step.

    Args:
        plant: The compiled robot.
        state: The measured state, as `mj_step1` leaves it.
        q_ref: The joint references (N, dof).
        qd_ref: Their rates (N, dof).
        tool_ref: The tool's reference points (N, 3).

    Returns:
        `time` (1,), `q`, `qd` (dof,) and `tool` (3,) measured; `q_ref`, `qd_ref` and `tool_ref` at this sample;
        and `q_ref_ahead` (len(AHEAD) * dof,), the references AHEAD samples on (the last sample past the end).
    """
    assert state.data is not None, "an observation needs the live data"
    return observe(plant, state.k, state.t, np.array(state.q, dtype=float), np.array(state.qd, dtype=float), state.data,
                   q_ref, qd_ref, tool_ref)


def observe(plant: Plant, k: int, t: float, q: Array, qd: Array, data: mujoco.MjData, q_ref: Array, qd_ref: Array,
            tool_ref: Array) -> OrderedDict:
    """`observation`'s, from the state's parts (an environment's step makes no State: a few microseconds a step);
    `q` and `qd` are taken as they are (the caller's own copies)."""
    return OrderedDict(
        time=np.array([t]),
        q=q,
        qd=qd,
        tool=data.sensordata[plant.sensors[plant.robot.tool_sensor]].copy(),
        q_ref=q_ref[k].copy(),
        qd_ref=qd_ref[k].copy(),
        tool_ref=tool_ref[k].copy(),
        q_ref_ahead=q_ref.take(k + _AHEAD, axis=0, mode="clip").ravel(),  # the last sample past the end
    )
