"""Planners: each turns a scenario's task into a JointTrajectory for one robot or for any.

A planner is a task schema (the `task:` section of a scenario), a `plan` function and, optionally, a `check`
that rejects a valid-looking task that means nothing (a zero-length path) before anything runs, and
`decorations`: what of the task the video should show (obstacle regions, say).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel

from simbench.trajectory import JointTrajectory


@dataclass(frozen=True)
class Planner:
    """A path-generation method."""

    name: str
    description: str
    task: type[BaseModel]
    plan: Callable[..., JointTrajectory]
    robots: tuple[str, ...] | None = None
    check: Callable[..., tuple[str, str] | None] | None = None
    decorations: Callable[..., list[dict]] | None = None

    def supports(self, robot: str) -> bool:
        """Whether this planner works with the robot called `robot`."""
        return self.robots is None or robot in self.robots


def rate(evaluate: Callable[[np.ndarray], np.ndarray], s: np.ndarray, revolute: np.ndarray,
         step: float = 1e-6) -> np.ndarray:
    """dq/ds (N, n) of a joint-space method q(s) by central differences (one-sided at s = 0 and 1).

    `evaluate` maps an array of s to configurations, sample by sample, so a caller can pin each sample's
    branch; differences of revolute joints are taken modulo one turn.
    """
    hi = np.clip(s + step, 0.0, 1.0)
    lo = np.clip(s - step, 0.0, 1.0)
    dq = evaluate(hi) - evaluate(lo)
    dq[:, revolute] = np.angle(np.exp(1j * dq[:, revolute]))
    return dq / (hi - lo)[:, None]


def registry() -> dict[str, Planner]:
    """All planners by name."""
    from simbench.planners import avoidance_4567, decoupled_path, joint_move, round_robin, safe_straight_path

    return {p.name: p for p in (safe_straight_path.PLANNER, decoupled_path.PLANNER, avoidance_4567.PLANNER,
                                round_robin.PLANNER, joint_move.PLANNER)}
