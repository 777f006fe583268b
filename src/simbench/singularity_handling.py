"""The shipped metric `singularity_handling`: how a run's plan meets the singular sets and the speed limits, the
figures that set the methods of a path near a singularity apart (`compare`, `simbench bench`). In report.json:

    speed_share_max     max over joints and samples of |qd_ref| / qd_max: the plan's joint rates against the
                        robot's speed limits (above 1 the plan asks more than a drive gives); None for a robot
                        without one positive speed limit per joint
    closest_approach    the least of the robot's `sigma_min_unit` measure over the run (an arm derived from its
                        model: the rank_loss gap, about the angle from the set in rad). None for the papers' robots,
                        whose gaps are in units of their own (`compare`'s singular_min_<set> columns)
    slowdown            the plan's own `slowdown` (planned duration over asked: a planner that retimes the path,
                        cartesian_path's time_scaling), else 1

A figure it cannot find is None: the metric never fails a run.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from simbench.api import Array, Figures, JointTrajectory, Metric, Recording, Robot

if TYPE_CHECKING:
    from simbench.scenario import Scenario

GAP = "sigma_min_unit"  # the measure closest_approach reads (robots.model_arm)


class SingularityHandling(Metric):
    """speed_share_max, closest_approach and slowdown of one run (the module's docstring)."""

    name = "singularity_handling"
    description = "the plan's joint-speed share of the limits, the closest approach to rank loss, the slowdown"

    def __init__(self, qd_max: Array | None, slowdown: float | None):
        self.qd_max, self.slowdown = qd_max, slowdown
        self.share, self.gap = (0.0 if qd_max is not None else None), math.inf

    @classmethod
    def for_run(cls, robot: Robot, traj: JointTrajectory, scenario: Scenario | None) -> SingularityHandling:
        return cls(_limits(robot), _slowdown(traj.info))

    def add(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> None:
        qd, limits = getattr(traj, "qd_ref", None), self.qd_max
        if self.share is not None and limits is not None and qd is not None and len(qd):
            qd = np.asarray(qd, float)
            if qd.ndim == 2 and qd.shape[1] == limits.size:
                self.share = max(self.share, float(np.max(np.abs(qd) / limits)))
            else:
                self.share = None
        gap = series.get(GAP)
        if gap is not None and len(gap):
            self.gap = min(self.gap, float(np.min(gap)))

    def finish(self) -> Figures:
        share = self.share if self.share is not None and math.isfinite(self.share) else None
        return {"speed_share_max": share, "closest_approach": self.gap if math.isfinite(self.gap) else None,
                "slowdown": self.slowdown}


def _limits(robot: Robot) -> Array | None:
    """The robot's speed limits (dof,), or None where it has no positive finite one per joint."""
    try:
        qd_max = np.asarray(getattr(robot, "qd_max", None), float).reshape(-1)
    except (TypeError, ValueError):
        return None
    ok = qd_max.size and qd_max.size == getattr(robot, "dof", qd_max.size)
    return qd_max if ok and np.all(np.isfinite(qd_max)) and np.all(qd_max > 0) else None


def _slowdown(info: dict | None) -> float | None:
    """The plan's `slowdown`, 1 where it states none, None where it states one that is not a number."""
    value = (info or {}).get("slowdown", 1.0)
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None
