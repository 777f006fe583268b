"""Planners: each turns a scenario's task into a JointTrajectory for one robot or for any.

A planner is a task schema (the `task:` section of a scenario), a `plan` function and, optionally, a `check`
that rejects a valid-looking task that means nothing (a zero-length path) before anything runs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

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

    def supports(self, robot: str) -> bool:
        """Whether this planner works with the robot called `robot`."""
        return self.robots is None or robot in self.robots


def registry() -> dict[str, Planner]:
    """All planners by name."""
    from simbench.planners import joint_move, safe_straight_path

    return {p.name: p for p in (safe_straight_path.PLANNER, joint_move.PLANNER)}
