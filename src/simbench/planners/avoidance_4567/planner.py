"""The Avoidance4567 Planner: the path chosen (plain, bent by windows, or the global search's), timed on the
control grid, with what the exact FK says of it."""

from __future__ import annotations

import time

import numpy as np

from simbench.api import Decoration, Planner
from simbench.api.trajectory import JointTrajectory, control_grid
from simbench.core.errors import RunError
from simbench.maths.rotations import matrix_to_quat
from simbench.maths.timing import TimeLaw
from simbench.planners import learnt_fk
from simbench.planners.avoidance_4567.checks import Checked, accepted, check_path, refusal
from simbench.planners.avoidance_4567.path import Plan
from simbench.planners.avoidance_4567.search import global_search
from simbench.planners.avoidance_4567.task import Task, clearances, margins
from simbench.planners.avoidance_4567.windows import optimise
from simbench.robots import agile_eye


def _choose(task: Task, law: TimeLaw, t: np.ndarray,
            source: str = "scenario") -> tuple[Checked, Checked, list[dict], dict | None]:
    """The path to hand over (plain, else bent by windows, else the global search's, each judged by the exact FK),
    the plain path, the windows and the search's info (None if it did not run). Windows get half the time
    budget, the search the rest. RunError if none keeps the margins, unless the task accepts that."""
    clock = time.perf_counter()
    budget = task.avoidance.time_budget
    bent, steps = optimise(task, law, deadline=clock + budget / 2)
    plain_plan = Plan(bent.theta_init, bent.theta_final, law)
    plain = check_path(task, "plain 4-5-6-7 joint path", t, plain_plan.theta(t), plain_plan.theta(t, order=1))
    chosen = plain if not steps else check_path(task, "4-5-6-7 joint path bent by windows", t, bent.theta(t),
                                            bent.theta(t, order=1))
    search = None
    if not chosen.ok and task.avoidance.enabled:
        found, search = global_search(task, law, t, max(clock + budget, time.perf_counter() + budget / 2), source)
        if found is not None and found.ok:
            chosen = found
    if not chosen.ok and not task.accept_margin_violation:
        raise RunError(refusal(task, chosen, search))
    return chosen, plain, steps, search


def _info(task: Task, chosen: Checked, plain: Checked, steps: list[dict], search: dict | None,
          planning_time: float) -> dict:
    """The plan's info: the path chosen, its windows and search, the exact FK's judgement of it and of the plain
    path, and with the network its estimated clearances."""
    theta = chosen.theta
    info = {
        "method": "paper 003: 4-5-6-7 joint path with smooth avoidance windows found by SLSQP; where they fail, "
                  "a global search in SO(3) (RRT-Connect) timed by the same law",
        "path": chosen.name + ("" if chosen.ok else " (margins not kept: accepted by task.accept_margin_violation)"),
        "planning_time": planning_time,
        "working_mode": task.working_mode,
        "theta_init": theta[0].tolist(),
        "theta_final": theta[-1].tolist(),
        "estimator": task.avoidance.estimator if task.avoidance.enabled else None,
        "windows": steps,
        "search": search,
        "margins": margins(task),
        "goal_error": chosen.goal_error,
        "singular_crossings": chosen.crossings.tolist(),
        **chosen.exact,
        "plain_path": {**plain.exact, "singular_crossings": plain.crossings.tolist(),
                       "goal_error": plain.goal_error},
    }
    if task.avoidance.enabled and task.avoidance.estimator == "network":
        estimated = clearances(task, theta, learnt_fk.load()(theta, task.working_mode))
        info["clearance_estimated"] = {name: float(c.min()) for name, c in estimated.items()}
    return info


class Avoidance4567(Planner):
    name = "avoidance_4567"
    description = "paper 003: 4-5-6-7 orientation path bent around obstacles and singularities (SLSQP)"
    task = Task
    robots = ("agile_eye",)

    def plan(self, scenario, robot, dt: float) -> JointTrajectory:
        """Plan, bend and time the path, searching SO(3) where bending fails (RunError: _choose)."""
        task = scenario.task
        law = scenario.timing.law_fn()
        clock = time.perf_counter()
        t = control_grid(law.duration, scenario.timing.hold, dt)
        chosen, plain, steps, search = _choose(task, law, t, scenario.source or scenario.name or "scenario")
        theta, rot = chosen.theta, chosen.rot
        warnings, violations = accepted(task, chosen, float(t[-1]))
        info = _info(task, chosen, plain, steps, search, time.perf_counter() - clock)
        quat = matrix_to_quat(rot)
        aim = rot @ agile_eye.LINE_OF_SIGHT * agile_eye.AIM
        waypoints = tuple({"s": s, "X": aim[k].tolist(), "q": theta[k].tolist(), "quat": quat[k].tolist()}
                          for s, k in ((0.0, 0), (1.0, -1)))
        return JointTrajectory(t=t, s=law(t, order=0)[0], q_ref=theta, qd_ref=chosen.theta_dot, tool_ref=aim,
                               waypoints=waypoints, info=info, warnings=tuple(warnings),
                               violations=tuple(violations), series={"platform_quat_ref": quat},
                               initial={joint: [value] for joint, value in  # the robot's own may pick another mode
                                        agile_eye.assemble(theta[0], task.start.matrix()).items()})

    def check(self, scenario, robot) -> tuple[str, str] | None:
        """T* must fit in T, and the start and goal must not lie on a singular curve (no IK there)."""
        task = scenario.task
        if task.avoidance.window > scenario.timing.duration:
            return ("task.avoidance.window", f"T* = {task.avoidance.window:g} s is longer than the motion "
                                             f"(timing.duration = {scenario.timing.duration:g} s)")
        for field in ("start", "goal"):
            gap = agile_eye.axis_gaps(getattr(task, field).matrix()).min()
            if gap < 1e-6:
                return f"task.{field}", "lies on a singular curve (some v_i = +-u_i): its base angles are undefined"
        return None

    def random_task(self, robot, random: np.random.RandomState) -> dict | None:
        """A random start and goal whose plain path runs into 1 or 2 obstacles (random_tasks.agile_eye_task)."""
        from simbench.planners import random_tasks  # imported when drawn, not when registered

        count = 1 + int(random.randint(2))
        return {"task": random_tasks.first(lambda: random_tasks.agile_eye_task(random, count), "Agile Eye task")}

    def decorations(self, scenario) -> list[Decoration]:
        """The obstacles as the cones of lines of sight they contain, for the video."""
        out = []
        for obstacle in scenario.task.obstacles:
            x, y, z = (float(v) for v in obstacle.center.matrix() @ agile_eye.LINE_OF_SIGHT)
            out.append(Decoration("cone", (x, y, z), obstacle.radius, agile_eye.AIM, (0.6, 0.25, 0.95, 0.35)))
        return out


PLANNER = Avoidance4567()
