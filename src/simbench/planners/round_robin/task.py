"""The round-robin scheme's `task:`: the rotor's commanded motion, the swing times, the floor on |det A| and
the band of gamma the schedule keeps to."""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from simbench.maths.rotations import axis_rotation
from simbench.robots import rsmg
from simbench.scenario.schema import Direction, NonNegativeAngle, SimbenchModel, seconds

# The default floor on the holding arms' |det A| (eq. 46 puts rank loss at 0.01); general contacts raise it with the
# rotor's speed (GeneralContacts.floor).
_DET_A_MIN = {"fixed": 0.15, "general": 0.3}


Turns = Annotated[float, Field(ge=-100, le=100)]  # a motion of more turns is a typo: it would run for hours


class Motion(SimbenchModel):
    """The rotor's commanded motion. `turns`: `turns` turns about `axis`. `tumble`: `spin_turns` about the
    rotor's `spin_axis` while that axis turns `precession_turns` about `precession_axis`."""

    kind: Literal["turns", "tumble"]
    axis: Direction = [0.0, 0.0, 1.0]
    turns: Turns = 1.0
    spin_axis: Direction = [0.0, 0.0, 1.0]
    spin_turns: Turns = 1.0
    precession_axis: Direction = [1.0, 0.0, 0.0]
    precession_turns: Turns = 1.0

    def orientation(self, s: np.ndarray) -> np.ndarray:
        """R (N, 3, 3) at path parameters s in [0, 1]: a tumble is the precession's rotation after the spin's."""
        s = np.asarray(s, float)

        def turning(axis: list[float], turns: float) -> np.ndarray:  # about a unit axis (schema.Direction)
            return axis_rotation(np.broadcast_to(np.array(axis), (len(s), 3)), 2 * np.pi * turns * s)

        if self.kind == "turns":
            return turning(self.axis, self.turns)
        return turning(self.precession_axis, self.precession_turns) @ turning(self.spin_axis, self.spin_turns)


class Task(SimbenchModel):
    """`task:` of the round-robin scheme."""

    motion: Motion
    swing_time: seconds(0.01, 60.0) = 0.5
    approach_time: seconds(0.0, 60.0) = 0.1
    det_a_min: Annotated[float, Field(gt=0, le=1)] | None = None  # default: _DET_A_MIN of the contacts
    regrip_feedback: bool = True
    gamma_margin: NonNegativeAngle = float(np.deg2rad(12.0))
    contacts: Literal["general", "fixed"] = "general"

    @model_validator(mode="after")
    def _default_det_a_min(self) -> "Task":
        if self.det_a_min is None:
            object.__setattr__(self, "det_a_min", _DET_A_MIN[self.contacts])  # the model is frozen
        return self


def band(task: Task) -> tuple[float, float]:
    """(lo, hi): eq. 45's band of gamma, (10, 170) deg, narrowed by task.gamma_margin at both ends."""
    return rsmg.GAMMA_BAND[0] + task.gamma_margin, rsmg.GAMMA_BAND[1] - task.gamma_margin
