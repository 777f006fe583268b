"""The shipped metric `singularity_handling`: the figures that set a path's methods near a singularity apart
(`compare`, `simbench bench`): speed_share_max (max |qd_ref| / qd_max; None without a positive speed limit per
joint), closest_approach (the least `sigma_min_unit` gap; None for a robot without it) and slowdown (the plan's
own, else 1). A figure it cannot find is None: the metric never fails a run.
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
    """speed_share_max, closest_approach and slowdown of one run."""

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
