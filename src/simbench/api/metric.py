"""What a metric is to simbench (`simbench.api.Metric`): a figure of merit found a window of samples at a time."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, ClassVar

from simbench.api.recording import Recording
from simbench.api.robot import Array, Robot
from simbench.api.trajectory import JointTrajectory

if TYPE_CHECKING:
    from simbench.scenario import Scenario


Figures = dict[str, float | None | list[float] | dict[str, float]]
"""A metric's figures by name (`Metric.finish`), SI: a number (None: not found), a short list, or numbers by name."""


class Metric(ABC):
    """A figure of merit of a run, found a window of samples at a time: `for_run`, `add` each window, `finish`.

    Registered as a class (`simbench.register_metric`); its figures go to report.json under `metrics.<name>` and
    to a sweep's results.csv as columns `<name>.<figure>`.

    Attributes:
        name: The metric's name.
        description: One line on what it measures.
    """

    name: ClassVar[str]
    description: ClassVar[str]

    @classmethod
    def for_run(cls, robot: Robot, traj: JointTrajectory, scenario: Scenario | None) -> Metric | None:
        """The metric of one run.

        Args:
            robot: The robot that runs.
            traj: The plan it runs.
            scenario: The scenario, or None (a run made without one).

        Returns:
            A fresh metric, or None where it does not apply to this run.
        """
        return cls()

    @abstractmethod
    def add(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> None:
        """Take the next window: keep what the figures need, not the window's arrays.

        Args:
            traj: The plan at the window's rows.
            rec: The recording there (with a recording stride, qpos, qd and ctrl at kept rows only).
            series: The analysis's per-sample series there.
        """

    @abstractmethod
    def finish(self) -> Figures:
        """The whole run's figures.

        Returns:
            Names to numbers, short lists of numbers, or numbers by name (a joint's).
        """
