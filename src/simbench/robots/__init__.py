"""The mechanisms simbench ships, each an analytic kinematics module over an MJCF model, with its
simbench.api.Robot subclass (as an outside package would write it) at its end: the serial arms' subclass
serial.SerialArm, whose kinematics are functions of the joint values alone; the closed chains' Robot itself.

Measures and singular sets are computed from a whole Recording, since a closed chain's state is more than its
actuated joints; a serial arm's come from the joint values alone (`rec.q`). A closed chain also names the
sensors it needs recorded, assembles its passive joints from the actuated ones, and may add its own entries to
the report (`summary`), colour its parts by their state in the video (`paint`) and draw its own plots
(`plots`): the RSMG's are in rsmg_outputs. A robot whose task is an orientation (a camera orienter, a rotor)
names the analysis series of its orientation error (`orientation_error`), and any robot names the events that
mean it did not do what was asked (`breaking`: a parallel mechanism changing assembly mode), so that such a run
does not end `ok` (simbench.verdict)."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from simbench.api import PRISMATIC, REVOLUTE, Robot, SingularSet, Tolerance
from simbench.resources import models_dir

__all__ = ["PRISMATIC", "REVOLUTE", "Robot", "SingularSet", "Tolerance", "joint_set", "scene"]


def scene(name: str) -> Path:
    """The MJCF scene of the shipped robot `name` (its folder under models/: robot, floor, lights, cameras)."""
    return models_dir() / name / "scene.xml"


def joint_set(name: str, family: str, condition: str, q: np.ndarray, values: dict[int, float],
              kinds: tuple[str, ...], joints: tuple[str, ...], tol: Tolerance,
              shared: dict[tuple[int, float], tuple[np.ndarray, np.ndarray]] | None = None) -> SingularSet:
    """A singular set given by joints held at constant values (paper 000's sets p_i, eqs. 15-17): its gaps
    |q_j - v| and its distance, the largest gap in multiples of its joint kind's tolerance. `shared`: a dict that
    sets of the same q and tol pass on to one another, so that a gap to a value more than one set holds a joint at
    is computed once (paper 000's 15 sets hold the joints at 7 values); each of its entries is a set's array,
    read-only."""
    shared = {} if shared is None else shared
    for j, v in values.items():
        if (j, v) not in shared:
            gap = np.abs(q[:, j] - v)
            shared[j, v] = gap, gap / tol.of(kinds[j])
    scaled = [shared[j, v][1] for j, v in values.items()]
    distance = scaled[0].copy() if len(scaled) == 1 else functools.reduce(np.maximum, scaled[1:], scaled[0])
    return SingularSet(name, family, condition, distance, {joints[j]: shared[j, v][0] for j, v in values.items()})
