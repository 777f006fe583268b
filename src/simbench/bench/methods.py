"""A bench's methods: each a named way to plan a common task (bench.tasks.Task), as a scenario's planner and the
task fields it takes (docs/guide/bench.md). A method that does not apply to a robot has no row there.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from simbench import extras
from simbench.bench.robots import BenchRobot
from simbench.bench.tasks import HOLD, Task


@dataclass(frozen=True)
class Method:
    """A method: its name, the planner it runs, and the scenario task it makes of a common task for a robot (None
    where it does not apply)."""

    name: str
    description: str
    fields: Callable[[Task, BenchRobot], dict | None]
    planner: Callable[[BenchRobot], str | None]
    needs: str | None = None  # the optional module it plans with (simbench.extras), if any

    def document(self, task: Task, robot: BenchRobot) -> dict | None:
        """The scenario document (SI) of `task` by this method, or None where it does not apply."""
        if self.name in robot.skip:
            return None
        planner, fields = self.planner(robot), self.fields(task, robot)
        if planner is None or fields is None:
            return None
        return {"name": f"{task.id}-{self.name}", "robot": robot.mapping, "planner": planner, "task": fields,
                "timing": {"law": "quintic", "duration": round(task.duration, 6), "hold": HOLD}}


def _path_task(task: Task, robot: BenchRobot) -> dict | None:
    """cartesian_path's task: the start, the path and the orientation held."""
    if not robot.hold:
        return None
    return {"start": list(task.start), "path": [task.segment], "orientation": "hold"}


def _with(method: str) -> Callable[[Task, BenchRobot], dict | None]:
    def fields(task: Task, robot: BenchRobot) -> dict | None:
        own = _path_task(task, robot)
        return None if own is None else {**own, "method": method}
    return fields


def _mink(task: Task, robot: BenchRobot) -> dict | None:
    """mink's QP on cartesian_path's path (written directly), or following the paper planner's plan."""
    if robot.hold:
        return _path_task(task, robot)
    return {"follow": robot.paper, "task": _paper(task, robot)}


def _paper(task: Task, robot: BenchRobot) -> dict | None:
    if robot.paper == "decoupled_path":
        from simbench.robots import puma600

        arm, elbow, wrist = puma600.configuration(np.array([task.start]))[0]
        return {"path": [task.segment], "orientation": {"convention": "quat", "value": list(task.orientation)},
                "configuration": {"arm": "righty" if arm < 0 else "lefty", "elbow": "up" if elbow > 0 else "down",
                                  "wrist": "noflip" if wrist > 0 else "flip"}}
    if robot.paper == "safe_straight_path":
        return {"start": list(task.start), "goal": list(task.goal)}
    return None


def _cartesian(robot: BenchRobot) -> str | None:
    return "cartesian_path" if robot.hold else None


METHODS: dict[str, Method] = {m.name: m for m in (
    Method("dls_adaptive", "cartesian_path as it is: damped least squares, damping grown near a rank loss",
           _path_task, _cartesian),
    Method("pinv", "cartesian_path, the pseudo-inverse", _with("pinv"), _cartesian),
    Method("dls", "cartesian_path, fixed damping", _with("dls"), _cartesian),
    Method("time_scaling", "cartesian_path, the path kept and retimed under the limits", _with("time_scaling"),
           _cartesian),
    Method("mink", "mink_baseline: mink's QP under the speed limits", _mink,
           lambda robot: "mink_baseline" if robot.hold or robot.paper else None, needs="mink"),
    Method("paper", "the paper's own planner for the robot", _paper, lambda robot: robot.paper),
)}


def installed() -> list[str]:
    """The methods whose optional package (if any) is installed, in the table's order: a suite's default."""
    return [name for name, m in METHODS.items() if m.needs is None or extras.installed(m.needs)]


def refusal(name: str) -> str | None:
    """Why method `name` cannot run here (its optional package is not installed), or None."""
    needs = METHODS[name].needs
    return None if needs is None else extras.missing(needs, f"method {name}")
