"""A bench's methods: each a named way to plan a common task (bench.tasks.Task), as a scenario's planner and the
task fields it takes (docs/guide/bench.md). A method that does not apply to a robot has no row there.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

import numpy as np

from simbench.commands.bench.robots import BenchRobot
from simbench.commands.bench.tasks import HOLD, Task
from simbench.core import extras


@dataclass(frozen=True)
class Method:
    """A method: its name, the planner it runs, and the scenario task it makes of a common task for a robot (None
    where it does not apply)."""

    name: str
    description: str
    fields: Callable[[Task, BenchRobot], dict | None]
    planner: Callable[[BenchRobot], str | None]
    needs: str | None = None  # the optional module it plans with (simbench.core.extras), if any
    default: bool = True  # a suite that names no methods runs it (else only where named)

    def document(self, task: Task, robot: BenchRobot) -> dict | None:
        """The scenario document of `task` by this method, or None where it does not apply: complete (every section
        the run reads, defaults written out, SI), so that the file the bench writes of it (scenarios/<id>.yaml)
        says all the run used."""
        planner, fields = self.planner(robot), self.fields(task, robot)
        if planner is None or fields is None:
            return None
        units, timing, settings = _defaults()
        return {"name": f"{task.id}-{self.name}",
                "description": f"{task.robot}'s bench task {task.index} ({task.kind} {task.shape}) by {self.name}",
                "robot": robot.mapping, "planner": planner, "units": units, "task": fields,
                "timing": {"law": timing.pop("law"), "duration": round(task.duration, 6), "hold": HOLD, **timing},
                **settings}


def _defaults() -> tuple[dict, dict, dict]:
    """The schema's defaults a bench run takes, as a scenario writes them (fresh copies): its units, its time law
    (the duration and hold are the task's) and its sim, analysis and control sections."""
    return json.loads(_defaults_text())


@cache
def _defaults_text() -> str:
    """_defaults' sections as JSON, made once."""
    from simbench.api import ControlSettings
    from simbench.scenario import Sim, Thresholds, Timing
    from simbench.scenario.schema import Units

    law = Timing(law="quintic", duration=1.0).model_dump(mode="json", exclude={"duration", "hold"})
    return json.dumps([Units().model_dump(mode="json"), law,
                       {"sim": Sim().model_dump(mode="json"), "analysis": Thresholds().model_dump(mode="json"),
                        "control": ControlSettings().model_dump(mode="json")}])


def _path_task(task: Task, robot: BenchRobot) -> dict:
    """cartesian_path's task: the start, the path and the orientation held, or free where the robot's tasks ask
    the tool's point alone (bench.tasks)."""
    return {"start": list(task.start), "path": [task.segment], "orientation": "hold" if robot.hold else "free"}


def _with(method: str) -> Callable[[Task, BenchRobot], dict]:
    def fields(task: Task, robot: BenchRobot) -> dict:
        return {**_path_task(task, robot), "method": method}
    return fields


def _redundant(method: str) -> Callable[[Task, BenchRobot], dict | None]:
    """A method for a redundant arm alone (gradient): more joints than the task's rows (6 where the orientation is
    held, 3 where the tool's point alone is asked); None elsewhere."""
    def fields(task: Task, robot: BenchRobot) -> dict | None:
        from simbench.planners.resolved_rates import POSITION_ROWS

        rows = 6 if robot.hold else POSITION_ROWS
        return _with(method)(task, robot) if robot.model_arm().dof > rows else None
    return fields


def _mink(task: Task, robot: BenchRobot) -> dict | None:
    """mink's QP following the paper planner's plan where the robot's tasks ask the point alone and it has a paper
    planner; else on cartesian_path's path, written directly, the orientation's cost 0 where the point alone is
    asked."""
    if robot.hold:
        return _path_task(task, robot)
    if robot.paper:
        return {"follow": robot.paper, "task": _paper(task, robot)}
    return {**_path_task(task, robot), "orientation_cost": 0.0}


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


def _every_robot(planner: str) -> Callable[[BenchRobot], str]:
    """A method's planner that applies to every robot."""
    return lambda robot: planner


METHODS: dict[str, Method] = {m.name: m for m in (
    Method("dls_adaptive", "cartesian_path as it is: damped least squares, damping grown near a rank loss",
           _path_task, _every_robot("cartesian_path")),
    Method("pinv", "cartesian_path, the pseudo-inverse", _with("pinv"), _every_robot("cartesian_path")),
    Method("dls", "cartesian_path, fixed damping", _with("dls"), _every_robot("cartesian_path")),
    Method("time_scaling", "cartesian_path, the path kept and retimed under the limits", _with("time_scaling"),
           _every_robot("cartesian_path")),
    Method("mink", "mink_baseline: mink's QP under the speed limits", _mink, _every_robot("mink_baseline"),
           needs="mink"),
    Method("paper", "the paper's own planner for the robot", _paper, lambda robot: robot.paper),
    Method("sns", "cartesian_path, joints saturated in the null space and the task scaled under the limits",
           _with("sns"), _every_robot("cartesian_path"), default=False),
    Method("gradient", "cartesian_path, the pseudo-inverse climbing manipulability in the null space (redundant "
           "arms)", _redundant("gradient"), _every_robot("cartesian_path"), default=False),
    Method("priority", "cartesian_path, the tool's point first, its orientation in the null space, damped",
           _with("priority"), _every_robot("cartesian_path"), default=False),
    Method("ruckig", "cartesian_path, the path kept and retimed under the limits with jerk limits (Ruckig)",
           _with("ruckig"), _every_robot("cartesian_path"), default=False),
)}


def installed() -> list[str]:
    """A suite's default: the methods run by default whose optional package (if any) is installed, in the table's
    order (sns, gradient and priority run where a suite or --methods names them)."""
    return [name for name, m in METHODS.items() if m.default and (m.needs is None or extras.installed(m.needs))]


def refusal(name: str) -> str | None:
    """Why method `name` cannot run here (its optional package is not installed), or None."""
    needs = METHODS[name].needs
    return None if needs is None else extras.missing(needs, f"method {name}")
