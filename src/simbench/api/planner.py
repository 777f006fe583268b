"""What a planner is to simbench (`simbench.api.Planner`): a task schema and a plan of joint references."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any, ClassVar, Generic, Literal, NamedTuple, TypeVar

import numpy as np
from pydantic import BaseModel

from simbench.api.robot import Robot
from simbench.api.trajectory import JointTrajectory

if TYPE_CHECKING:
    from simbench.scenario import Scenario


class Decoration(NamedTuple):
    """A shape the video draws in every frame: a cone from the world origin.

    Attributes:
        kind: `"cone"`.
        axis: Its unit axis (3,).
        half_angle: Its half angle (rad).
        length: Its length along the axis (m).
        rgba: Its colour, each channel 0 to 1.
    """

    kind: Literal["cone"]
    axis: tuple[float, float, float]
    half_angle: float
    length: float
    rgba: tuple[float, float, float, float]



TaskT = TypeVar("TaskT", bound=BaseModel)


class Planner(ABC, Generic[TaskT]):
    """A path-generation method: a task schema and `plan`.

    Attributes:
        name: The name scenarios give (`planner:`).
        description: One line for `simbench list`.
        task: The schema of the scenario's `task:`, built from `simbench.scenario.schema`'s types so that units convert
            at load time.
        robots: The robots it is written for; None: any robot that has what `needs` names.
        needs: What it needs of a robot: `"fk"`, forward kinematics of the joints alone.
        seconds_per_sample: Its planning time a control sample beyond a few microseconds, for the run's budget.
    """

    name: ClassVar[str]
    description: ClassVar[str]
    task: ClassVar[type[BaseModel]]
    robots: ClassVar[tuple[str, ...] | None] = None
    needs: ClassVar[tuple[Literal["fk"], ...]] = ()
    seconds_per_sample: ClassVar[float] = 0.0

    @abstractmethod
    def plan(self, scenario: Scenario, robot: Robot, dt: float) -> JointTrajectory:
        """Plan the scenario's task.

        A plan's `feedback` may change its q_ref and qd_ref in place during the run: return arrays of its own,
        not cached ones.

        Args:
            scenario: The scenario, its `task` an instance of `task`, in SI.
            robot: The robot.
            dt: The control period (s).

        Returns:
            Joint references on the control grid of period dt.

        Raises:
            RunError: The task cannot be planned (a point out of reach, say).
        """

    def check(self, scenario: Scenario, robot: Robot) -> tuple[str, str] | None:
        """Find a task that is well-formed but means nothing (a zero-length path), at validation.

        Args:
            scenario: The scenario.
            robot: The robot.

        Returns:
            (field, what is wrong), or None.
        """
        return None

    def decorations(self, scenario: Scenario) -> list[Decoration]:
        """Shapes the video draws in every frame (obstacles, say).

        Args:
            scenario: The scenario.

        Returns:
            The shapes.
        """
        return []

    def random_task(self, robot: Robot, random: np.random.RandomState) -> dict[str, Any] | None:
        """A random task, for an environment's resets with `task_kwargs={'random': seed}`.

        A task the planner then refuses is drawn again.

        Args:
            robot: The robot.
            random: The only source of randomness to draw from.

        Returns:
            The scenario sections it sets, as a scenario file writes them in SI units: `task`, and `timing` where
            the task sets its own pace (else the scenario's is kept). None (the default): not offered, and the
            environment draws a joint move instead.
        """
        return None

    def refuses(self, robot: Robot) -> str | None:
        """Why this planner cannot plan for a robot.

        Args:
            robot: The robot.

        Returns:
            Why, in words, or None if it can.
        """
        if self.robots is not None and robot.name not in self.robots:
            return f"'{self.name}' works with {', '.join(self.robots)}, not '{robot.name}'"
        if "fk" in self.needs and not robot.has_fk:
            return f"'{self.name}' needs the robot's forward kinematics of its joints, which '{robot.name}' has not"
        return None
