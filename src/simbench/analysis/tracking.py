"""The shipped metric `tracking`: each joint's error, the tool's distance from the planned path, its lag along it
and its error against the reference point (RMS, max, final), the path's length, and an orientation error where
the task is one; SI units. Its figures go to report.json's `tracking`, not under metrics.<name>.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from simbench.api import Array, Figures, JointTrajectory, Metric, Recording, Robot
from simbench.core.windowed import Sums, norms

if TYPE_CHECKING:
    from simbench.scenario import Scenario


class Tracking(Metric):
    """The tracking figures, a window at a time (windowed.Sums), and the planned path's length."""

    name = "tracking"
    description = "joint and tool errors against the plan: RMS, largest, final; the planned path's length"

    def __init__(self, joints: tuple[str, ...], orientation_error: str | None):
        self.joints, self.orientation_error = joints, orientation_error
        self.sums, self.arc = Sums(), 0.0
        self.last: Array | None = None  # the planned tool point of the window before's last sample

    @classmethod
    def for_run(cls, robot: Robot, traj: JointTrajectory, scenario: Scenario | None) -> Tracking:
        return cls(robot.joints, robot.orientation_error)

    def add(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> None:
        self.sums.add(**{name: series[name] for name in ("joint_error", "path_deviation", "path_lag", "tool_error")})
        error = series.get(self.orientation_error) if self.orientation_error else None
        if error is not None:
            self.sums.add(orientation=error)
        points = traj.tool_ref if self.last is None else np.concatenate([self.last, traj.tool_ref])
        self.arc += float(np.sum(norms(np.diff(points, axis=0))))
        self.last = traj.tool_ref[-1:].copy()

    def finish(self) -> Figures:
        sums, joints = self.sums, self.joints
        figures: Figures = {
            "joint_rms": dict(zip(joints, sums.rms("joint_error").tolist())),
            "joint_max": {name: float(v) for name, v in zip(joints, sums.largest["joint_error"])},
            "tool_rms": float(sums.rms("path_deviation")),
            "tool_max": sums.highest["path_deviation"],
            "tool_lag_rms": float(sums.rms("path_lag")),
            "tool_lag_max": float(sums.largest["path_lag"]),
            "tool_error_rms": float(sums.rms("tool_error")),
            "tool_error_max": sums.highest["tool_error"],
            "tool_error_final": float(sums.last["tool_error"]),
            "path_length": self.arc,
        }
        if "orientation" in sums.squares:
            figures.update(orientation_rms=float(sums.rms("orientation")), orientation_max=sums.highest["orientation"],
                           orientation_final=float(sums.last["orientation"]))
        return figures
