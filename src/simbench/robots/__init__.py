"""The mechanisms simbench models, each an analytic kinematics module over an MJCF model.

A `Robot` says everything the pipeline needs without reaching into a robot module: where its MJCF scene is,
its joints in the planner's order, their limits and speed limits, the tool site, and the functions for the tool
point, the per-sample singularity measures and the singular sets of its paper. Measures and singular sets are
computed from a whole Recording, since a closed chain's state is more than its actuated joints; `of_joints`
adapts functions of the joint values alone. A closed chain also names the sensors it needs recorded, assembles
its passive joints from the actuated ones, and may add its own entries to the report (`summary`), colour its
parts by their state in the video (`paint`) and draw its own plots (`plots`). A robot whose task is an
orientation (a camera orienter, a rotor) names the analysis series of its orientation error
(`orientation_error`), and any robot names the events that mean it did not do what was asked (`breaking`: a
parallel mechanism changing assembly mode), so that such a run does not end `ok` (simbench.verdict).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

from simbench.resources import models_dir

REVOLUTE = "revolute"
PRISMATIC = "prismatic"


@dataclass(frozen=True)
class Tolerance:
    """How near a singular set counts as near: radians for revolute joints, metres for prismatic ones."""

    angle: float
    length: float

    def of(self, kind: str) -> float:
        """The tolerance for a joint of this kind."""
        return self.angle if kind == REVOLUTE else self.length


@dataclass(frozen=True)
class SingularSet:
    """One singular set evaluated along a trajectory.

    `distance` is normalised: the largest over the set's conditions of |gap| / tolerance, so that a sample with
    distance <= 1 lies near the set. `gaps` holds each condition's gap in SI units (rad or m).
    """

    name: str
    family: str
    condition: str
    distance: np.ndarray
    gaps: dict[str, np.ndarray]


@dataclass(frozen=True)
class Robot:
    """A mechanism: its model, its joints and its analytic kinematics."""

    name: str
    description: str
    paper: str
    joints: tuple[str, ...]
    kinds: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    qd_max: np.ndarray
    tool_site: str
    tool_sensor: str
    fk: Callable[[np.ndarray], np.ndarray]
    measures: Callable[..., dict[str, np.ndarray]]
    singular_sets: Callable[..., list[SingularSet]]
    sensors: tuple[str, ...] = ()
    assemble: Callable[[np.ndarray], dict[str, float]] | None = None
    summary: Callable[..., tuple[dict, list[dict], dict[str, np.ndarray]]] | None = None
    paint: Callable[..., None] | None = None
    plots: Callable[..., list[str]] | None = None
    orientation_error: str | None = None
    breaking: tuple[str, ...] = ()

    @property
    def dof(self) -> int:
        """Number of actuated joints."""
        return len(self.joints)

    @property
    def scene(self) -> Path:
        """The MJCF scene (robot, floor, lights, cameras)."""
        return models_dir() / self.name / "scene.xml"

    def cameras(self) -> tuple[str, ...]:
        """Names of the cameras the scene defines."""
        return _camera_names(self.scene)


@cache
def _camera_names(scene: Path) -> tuple[str, ...]:
    import mujoco

    model = mujoco.MjModel.from_xml_path(str(scene))
    return tuple(model.camera(i).name for i in range(model.ncam))


def of_joints(fn: Callable) -> Callable:
    """A function of the recorded joint values q (N, n) as a function of the whole Recording."""

    def of_recording(rec, *args):
        return fn(rec.q, *args)

    of_recording.__doc__ = fn.__doc__
    return of_recording


def joint_set(name: str, family: str, condition: str, q: np.ndarray, values: dict[int, float],
              kinds: tuple[str, ...], joints: tuple[str, ...], tol: Tolerance) -> SingularSet:
    """A singular set given by joints held at constant values (paper 000's sets p_i, eqs. 15-17)."""
    gaps = {joints[j]: np.abs(q[:, j] - v) for j, v in values.items()}
    distance = np.max([gaps[joints[j]] / tol.of(kinds[j]) for j in values], axis=0)
    return SingularSet(name, family, condition, distance, gaps)


def registry() -> dict[str, Robot]:
    """All robots by name."""
    from simbench.robots import agile_eye, puma600, rsmg, spherical_arm

    return {r.name: r for r in (spherical_arm.ROBOT, puma600.ROBOT, agile_eye.ROBOT, rsmg.ROBOT)}


def get(name: str) -> Robot:
    """The robot called `name`; KeyError if there is none."""
    return registry()[name]
