"""The mechanisms simbench ships: each an analytic kinematics module over an MJCF model, its simbench.api.Robot
subclass at its end (serial arms through serial.SerialArm; closed chains, whose measures need a whole Recording,
subclass Robot themselves), arms derived from a user's MJCF or URDF, and the servos designed for a plan.

Imports core, maths and api."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from simbench.api import PRISMATIC, REVOLUTE, Robot, SingularSet, Tolerance
from simbench.core.resources import models_dir

__all__ = ["PRISMATIC", "REVOLUTE", "Robot", "SingularSet", "Tolerance", "joint_set", "scene"]


def scene(name: str) -> Path:
    """The MJCF scene of the shipped robot `name` (its folder under models/: robot, floor, lights, cameras)."""
    return models_dir() / name / "scene.xml"


def joint_set(name: str, family: str, condition: str, q: np.ndarray, values: dict[int, float],
              kinds: tuple[str, ...], joints: tuple[str, ...], tol: Tolerance,
              shared: dict[tuple[int, float], tuple[np.ndarray, np.ndarray]] | None = None) -> SingularSet:
    """A singular set of joints held at constant values (paper 000's sets p_i, eqs. 15-17): gaps |q_j - v| and the
    distance, the largest gap over its joint kind's tolerance. `shared`: gaps that sets of the same q and tol reuse
    (its arrays read-only)."""
    shared = {} if shared is None else shared
    for j, v in values.items():
        if (j, v) not in shared:
            gap = np.abs(q[:, j] - v)
            shared[j, v] = gap, gap / tol.of(kinds[j])
    distance = np.maximum.reduce([shared[j, v][1] for j, v in values.items()])
    return SingularSet(name, family, condition, distance, {joints[j]: shared[j, v][0] for j, v in values.items()})
