"""The figures a bench row needs beyond `simbench run`'s report: a Metric measured by the same analysis, but only
for the runs of a bench (`active`), so that every other run's report stays as it was.

    speed_share_max     max over joints and samples of |qd_ref| / qd_max: the plan's joint rates against the
                        speed limits (above 1 the plan asks more than a drive gives)
    closest_approach    the least, over the recorded samples, of the robot's `sigma_min_unit` (an arm derived from
                        its model: the least singular value of [Jp / L; Jr], the rank_loss set's gap, about the
                        angle from the singular set in rad); None for a robot without that measure
    slowdown            the planned duration over the asked one: the plan's own `slowdown`, or its `duration` over
                        timing.duration, where its info states one (a planner that retimes the path); else 1

The metric is registered once in the process that runs the bench (simbench.register_metric) and is made only while
`active()` holds: worker processes forked then inherit both. A Ray worker, a fresh process, has neither, and its
rows lack these figures.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

from simbench.api import Metric

_ACTIVE = [False]


class BenchFigures(Metric):
    """speed_share_max, closest_approach and slowdown of one run (the module's docstring)."""

    name = "bench"
    description = "the bench's figures: the plan's joint-speed share, the closest approach to rank loss, slowdown"

    def __init__(self, qd_max: np.ndarray, slowdown: float):
        self.qd_max, self.slowdown = np.asarray(qd_max, float), slowdown
        self.share, self.gap = 0.0, np.inf

    @classmethod
    def for_run(cls, robot, traj, scenario):
        if not _ACTIVE[0] or scenario is None:
            return None
        info = traj.info or {}
        slowdown = info.get("slowdown")
        if slowdown is None:
            slowdown = info["duration"] / scenario.timing.duration if "duration" in info else 1.0
        return cls(robot.qd_max, float(slowdown))

    def add(self, traj, rec, series) -> None:
        if len(traj.qd_ref):
            self.share = max(self.share, float(np.max(np.abs(traj.qd_ref) / self.qd_max)))
        gap = series.get("sigma_min_unit")
        if gap is not None and len(gap):
            self.gap = min(self.gap, float(np.min(gap)))

    def finish(self) -> dict:
        return {"speed_share_max": self.share, "closest_approach": None if np.isinf(self.gap) else self.gap,
                "slowdown": self.slowdown}


@contextmanager
def active() -> Iterator[None]:
    """Measure every run started (or forked) within: the metric registered once, made while this holds."""
    from simbench import registry

    if registry.metrics().get(BenchFigures.name) is not BenchFigures:
        registry.register_metric(BenchFigures, "simbench.bench")
    _ACTIVE[0] = True
    try:
        yield
    finally:
        _ACTIVE[0] = False
