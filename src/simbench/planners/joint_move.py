"""Joint-space move for any robot: every joint from start to goal on the same time law, arriving together."""

from __future__ import annotations

import numpy as np

from simbench.api import Planner
from simbench.api.trajectory import JointTrajectory, control_grid
from simbench.scenario.schema import JointVector, SimbenchModel


class Task(SimbenchModel):
    """`task:` of a joint move."""

    start: JointVector
    goal: JointVector


class JointMove(Planner):
    """Joint-space move: every joint on the time law from start to goal (any robot)."""

    name = "joint_move"
    description = "joint-space move: every joint on the time law from start to goal (any robot)"
    task = Task
    needs = ("fk",)

    def plan(self, scenario, robot, dt: float) -> JointTrajectory:
        """q(t) = q_start + (q_goal - q_start) s(t)."""
        law = scenario.timing.law_fn()
        t = control_grid(law.duration, scenario.timing.hold, dt)
        s, ds = law(t, order=1)
        q0, dq = np.array(scenario.task.start), np.array(scenario.task.goal) - np.array(scenario.task.start)
        q_ref = q0 + s[:, None] * dq
        waypoints = tuple({"s": float(v), "X": robot.fk(q0 + v * dq)[0].tolist(), "q": (q0 + v * dq).tolist()}
                          for v in (0.0, 1.0))
        return JointTrajectory(t=t, s=s, q_ref=q_ref, qd_ref=ds[:, None] * dq, tool_ref=robot.fk(q_ref),
                               waypoints=waypoints, info={"method": "joint-space interpolation"})

    def check(self, scenario, robot) -> tuple[str, str] | None:
        """A move to where the robot already is has nothing to do."""
        if np.allclose(scenario.task.start, scenario.task.goal, rtol=0.0, atol=1e-12):
            return "task.goal", "equals start: a zero-length move"
        return None


PLANNER = JointMove()
