"""Step 5 of the method: where bending fails, a global search in SO(3) (so3_search) for an orientation path that
keeps every margin, timed by the 4-5-6-7 law."""

from __future__ import annotations

import time

import numpy as np

from simbench.core import extras
from simbench.maths.timing import TimeLaw
from simbench.planners.avoidance_4567.checks import Checked, check_path
from simbench.planners.avoidance_4567.task import Task, clearances, margins
from simbench.robots import agile_eye

_SEARCH_STEP = np.deg2rad(0.5)  # rotation angle between the states the global search checks along a motion


def slack(task: Task, rot: np.ndarray, pad: float = 0.0) -> np.ndarray:
    """The worst clearance less its margin (N,) at orientations (N, 3, 3), angular margins raised by `pad`."""
    theta = agile_eye.ik(rot, task.working_mode)
    need = margins(task)
    return np.min([c - need[name] - (0.0 if name == "kci" else pad)
                   for name, c in clearances(task, theta, rot).items()], axis=0)


def global_search(task: Task, law: TimeLaw, t: np.ndarray, deadline: float,
                  source: str = "scenario") -> tuple[Checked | None, dict]:
    """The global search's path, timed as sigma = length S(t / T) (S the 4-5-6-7 law, eq. 8) and checked, or None;
    and what the search did. Without OMPL, MissingExtra naming the scenario `source`."""
    extras.require("ompl", "the global search in SO(3), where bending the path fails,", source, "task.avoidance")
    from simbench.planners import so3_search  # OMPL, imported when a search is planned

    start, goal = task.start.matrix(), task.goal.matrix()
    clock = time.perf_counter()

    def padded(rot):  # margins padded so that whole motions keep them (so3_search's docstring)
        return slack(task, rot, _SEARCH_STEP / 2)

    waypoints, status = so3_search.search(padded, start, goal, max(deadline - clock, 1e-3), _SEARCH_STEP)
    info = {"status": status, "time": time.perf_counter() - clock}
    if waypoints is None:
        return None, info
    path = so3_search.smooth(waypoints, padded, _SEARCH_STEP)
    rot = path(path.length * law(t, order=0)[0])
    theta = np.unwrap(agile_eye.ik(rot, task.working_mode), axis=0)  # continuous, from IK(start) in (-pi, pi]
    info.update({"waypoints": len(waypoints), "length": path.length, "blends": path.blends.tolist(),
                 "time": time.perf_counter() - clock})
    return check_path(task, "global search in SO(3)", t, theta, np.gradient(theta, t, axis=0)), info
