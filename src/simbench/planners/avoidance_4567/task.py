"""Paper 003's `task:`, and the clearances and margins every stage of the planner judges a path by."""

from __future__ import annotations

from functools import lru_cache
from typing import Annotated, Literal

import numpy as np
from pydantic import Field

from simbench.maths.rotations import rotation_angle
from simbench.robots import agile_eye
from simbench.scenario.schema import NonNegativeAngle, Orientation, PositiveAngle, SimbenchModel, Weight, seconds


class Obstacle(SimbenchModel):
    """A region of orientations the platform must stay out of: all within `radius` of `center`."""

    name: str = ""
    center: Orientation
    radius: PositiveAngle


class Avoidance(SimbenchModel):
    """How the path is bent: window length T*, how many windows at most, which FK estimates clearances."""

    enabled: bool = True
    window: seconds(0.01, 3600.0) = 1.0
    max_windows: int = Field(4, ge=1, le=20)
    estimator: Literal["network", "exact"] = "network"
    deviation_weight: Weight = 0.1
    time_budget: seconds(0.0, 600.0, low_open=True) = Field(
        10.0, description="seconds of planning: windows for about half, the global search for the rest")


class Task(SimbenchModel):
    """`task:` of paper 003's planner."""

    start: Orientation
    goal: Orientation
    working_mode: int = Field(0, ge=0, le=7)
    obstacles: list[Obstacle] = []
    singularity_clearance: PositiveAngle = float(np.deg2rad(10.0))
    kci_min: Annotated[float, Field(ge=0, lt=1)] = 0.0
    obstacle_clearance: NonNegativeAngle = 0.0
    avoidance: Avoidance = Avoidance()
    accept_margin_violation: bool = Field(
        False, description="hand over the best path found, with warnings, when none keeps the margins (a "
                           "singular crossing included) instead of refusing to run")


def obstacle_names(task: Task) -> list[str]:
    """Each obstacle's name in the clearances and margins: its own, or obstacle<k> counting from 1."""
    return [obstacle.name or f"obstacle{k + 1}" for k, obstacle in enumerate(task.obstacles)]


def centers(task: Task) -> list[np.ndarray]:
    """Each obstacle's centre as a rotation matrix (3, 3), read-only (Orientation.matrix, computed once)."""
    return [_matrix(o.center.convention, tuple(o.center.value)) for o in task.obstacles]


@lru_cache(maxsize=256)
def _matrix(convention: str, value: tuple[float, ...]) -> np.ndarray:
    """Orientation.matrix of an orientation given by its fields, cached (scipy is slow for one)."""
    out = Orientation.model_construct(convention=convention, value=list(value)).matrix()  # already validated
    out.flags.writeable = False
    return out


def clearances(task: Task, theta: np.ndarray, rot: np.ndarray,
               kci: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Clearance (rad, negative inside) of each obstacle and of the singular curves along orientations (N, 3, 3);
    and the KCI (agile_eye.kci, or `kci` if given) where the task sets a floor on it."""
    out = {}
    if task.kci_min > 0:
        out["kci"] = agile_eye.kci(theta, rot) if kci is None else kci
    for name, obstacle, center in zip(obstacle_names(task), task.obstacles, centers(task)):
        out[name] = rotation_angle(np.broadcast_to(center, rot.shape), rot) - obstacle.radius
    out["type2"] = agile_eye.axis_gaps(rot).min(axis=1)
    return out


def margins(task: Task) -> dict[str, float]:
    """The clearance each constraint must keep."""
    out = dict.fromkeys(obstacle_names(task), task.obstacle_clearance)
    out["type2"] = task.singularity_clearance
    if task.kci_min > 0:
        out["kci"] = task.kci_min
    return out
