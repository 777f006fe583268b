"""What a policy sees at a control step, and what `simbench.env`'s environments observe: the measured joints and
tool, and the plan's references now and a few samples ahead. Every entry is a float array, SI units."""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from simbench.api import Array, State
from simbench.plant import Plant

AHEAD = (1, 5, 20)  # samples ahead of now at which the references are shown


def observation(plant: Plant, state: State, q_ref: Array, qd_ref: Array, tool_ref: Array) -> OrderedDict:
    """The observation at `state` (as `mj_step1` leaves it) for references q_ref, qd_ref (N, dof) and tool_ref
    (N, 3): time (1,), q, qd (dof,) and tool (3,) measured; the references at this sample; and q_ref_ahead
    (len(AHEAD) * dof,) AHEAD samples on (the last one past the end)."""
    assert state.data is not None, "an observation needs the live data"
    k, last = state.k, len(q_ref) - 1
    ahead = [min(k + h, last) for h in AHEAD]
    return OrderedDict(
        time=np.array([state.t]),
        q=np.array(state.q, dtype=float),
        qd=np.array(state.qd, dtype=float),
        tool=state.data.sensordata[plant.sensors[plant.robot.tool_sensor]].copy(),
        q_ref=q_ref[k].copy(),
        qd_ref=qd_ref[k].copy(),
        tool_ref=tool_ref[k].copy(),
        q_ref_ahead=q_ref[ahead].ravel(),
    )
