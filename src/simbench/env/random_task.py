"""Random tasks for an environment's resets (task_kwargs={'random': seed}): a joint move of the scenario's robot,
on its timing, from a random start to a random goal, both drawn uniformly within the action bounds (the joint
ranges; a joint with none: the plan's span widened by episode.CONTINUOUS_SPAN) shrunk by MARGIN at either end."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from simbench import registry
from simbench.errors import RunError, ScenarioError
from simbench.scenario import Scenario, _scenario_class
from simbench.switches import at_start

if TYPE_CHECKING:
    import mujoco

    from simbench.env.episode import Track
    from simbench.trajectory import JointTrajectory

MARGIN = 0.05  # of each joint's span, kept clear of its bounds
TRIES = 20  # draws before giving up on a robot whose random moves cannot be planned


def check(scenario: Scenario) -> None:
    """ValueError if the scenario's robot cannot take random joint moves."""
    refusal = registry.planners()["joint_move"].refuses(scenario.robot_def)
    if refusal:
        raise ValueError(f"no random tasks for the {scenario.robot_def.name}: {refusal}")


def draw(track: Track) -> tuple[JointTrajectory, mujoco.MjData]:
    """A random task's plan from track.random, and the data posed at its start (switches.at_start)."""
    scenario, plant, random = track.scenario, track.plant, track.random
    assert random is not None, "a Track made with random"
    lo, hi = track.bounds
    margin = MARGIN * (hi - lo)
    planner = registry.planners()["joint_move"]
    cls = _scenario_class("joint_move")
    for _ in range(TRIES):
        start, goal = (random.uniform(lo + margin, hi - margin) for _ in range(2))
        fields = {name: getattr(scenario, name) for name in Scenario.model_fields}
        fields.update(planner="joint_move", expect=None, task=planner.task.model_construct(
            start=tuple(start.tolist()), goal=tuple(goal.tolist())))
        drawn = cls.model_construct(**fields)
        drawn._robot = scenario._robot
        try:
            plan = planner.plan(drawn, scenario.robot_def, track.dt)
        except (RunError, ScenarioError, ValueError):
            continue
        if np.isfinite(plan.tool_ref).all():
            track.scenario = drawn
            return plan, at_start(plant, plan)[1]
    raise RunError(f"no random joint move of the {scenario.robot_def.name} could be planned in {TRIES} draws")
