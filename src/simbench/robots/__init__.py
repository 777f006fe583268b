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

from pathlib import Path

import numpy as np

from simbench.api import PRISMATIC, REVOLUTE, Robot, SingularSet, Tolerance
from simbench.resources import models_dir

__all__ = ["PRISMATIC", "REVOLUTE", "Robot", "SingularSet", "Tolerance", "joint_set", "scene"]


def scene(name: str) -> Path:
    """The MJCF scene of the shipped robot `name` (its folder under models/: robot, floor, lights, cameras)."""
    return models_dir() / name / "scene.xml"


def joint_set(name: str, family: str, condition: str, q: np.ndarray, values: dict[int, float],
              kinds: tuple[str, ...], joints: tuple[str, ...], tol: Tolerance) -> SingularSet:
    """A singular set given by joints held at constant values (paper 000's sets p_i, eqs. 15-17)."""
    gaps = {joints[j]: np.abs(q[:, j] - v) for j, v in values.items()}
    distance = np.max([gaps[joints[j]] / tol.of(kinds[j]) for j in values], axis=0)
    return SingularSet(name, family, condition, distance, gaps)
