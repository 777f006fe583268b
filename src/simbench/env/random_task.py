"""Random tasks for an environment's resets (task_kwargs={'random': seed}): the scenario planner's own where it
draws them (api.Planner.random_task), else a joint move between two points drawn uniformly within the position
targets' bounds (the position actuation's action bounds, under torque actuation too) shrunk by MARGIN. A draw the
planner refuses, or whose references leave the position targets' bounds, is drawn again, up to TRIES times.

The planner's own random tasks may wind a joint without a range further than the shipped plan does (the RSMG's
rotor motions of up to 5 turns wind an arm's base joint about as many turns): `widen` makes room for them."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from simbench.api import registry
from simbench.core.errors import RunError, ScenarioError
from simbench.physics.switches import pose_start
from simbench.scenario.document import Scenario, _scenario_class
from simbench.scenario.schema import Units

if TYPE_CHECKING:
    from simbench.api import Array
    from simbench.api.trajectory import JointTrajectory
    from simbench.env.episode import Track

MARGIN = 0.05  # of each joint's span, kept clear of its bounds
TRIES = 100  # draws before giving up on a robot whose random tasks cannot be planned (a PUMA line is plannable in
# about 1 draw of 6: 20 draws failed about 1 reset in 40)
RANDOM_TURNS = 6  # how much further (turns, either side) the planner's own random tasks may take a hinge without a
# range than the shipped plan: the RSMG's random rotor motions turn at most 5 times (rsmg_contacts.random_motion)


def offered(scenario: Scenario) -> bool:
    """Whether the scenario's planner draws random tasks for its robot (one draw from a scratch RandomState)."""
    return scenario.planner_def.random_task(scenario.robot_def, np.random.RandomState(0)) is not None


def check(scenario: Scenario) -> None:
    """ValueError if the scenario's robot can take neither its planner's random tasks nor random joint moves."""
    if offered(scenario):
        return
    refusal = registry.planners()["joint_move"].refuses(scenario.robot_def)
    if refusal:
        raise ValueError(f"no random tasks for the {scenario.robot_def.name}: its planner "
                         f"'{scenario.planner}' draws none, and {refusal}")


def widen(track: Track, model: mujoco.MjModel) -> None:
    """Widen the track's bounds (actions and position targets) for the planner's own random tasks: a hinge
    without a range by RANDOM_TURNS either side, beyond the shipped plan's span and CONTINUOUS_SPAN."""
    if not offered(track.scenario):
        return  # random joint moves are drawn within the bounds
    plant, plan = track.plant, track.plan
    joints = model.actuator_trnid[plant.actuators, 0]
    winding = (model.jnt_type[joints] == mujoco.mjtJoint.mjJNT_HINGE) & ~model.jnt_limited[joints].astype(bool)
    reach = RANDOM_TURNS * 2 * np.pi * winding
    # the bounds of a plan whose references reach that much further (only its q_ref's extremes are read)
    extremes = np.stack([plan.q_ref.min(axis=0) - reach, plan.q_ref.max(axis=0) + reach])
    track.set_bounds(model, dataclasses.replace(plan, q_ref=extremes))


def _own(scenario: Scenario, sections: dict[str, Any]) -> Scenario:
    """The scenario with the task (and timing) its planner drew, in SI units; ValueError if it is not valid."""
    robot = scenario.robot_def
    fields = {name: getattr(scenario, name) for name in Scenario.model_fields}
    fields.update(expect=None, task=sections["task"], timing=sections.get("timing", scenario.timing))
    drawn = _scenario_class(scenario.planner, scenario.control.controller).model_validate(
        fields, context={"robot": robot, "units": Units()})
    drawn._robot = scenario._robot
    problem = drawn.planner_def.check(drawn, robot)
    if problem:
        raise ValueError(f"{problem[0]}: {problem[1]}")
    return drawn


def _joint_move(scenario: Scenario, bounds: tuple[Array, Array], random: np.random.RandomState) -> Scenario:
    """The scenario turned into a random joint move within the position targets' `bounds` (under torque actuation
    too)."""
    lo, hi = bounds
    margin = MARGIN * (hi - lo)
    start, goal = (random.uniform(lo + margin, hi - margin) for _ in range(2))
    fields = {name: getattr(scenario, name) for name in Scenario.model_fields}
    fields.update(planner="joint_move", expect=None, task=registry.planners()["joint_move"].task.model_construct(
        start=tuple(start.tolist()), goal=tuple(goal.tolist())))
    drawn = _scenario_class("joint_move", scenario.control.controller).model_construct(**fields)
    drawn._robot = scenario._robot
    return drawn


def plan_random(scenario: Scenario, bounds: tuple[Array, Array], dt: float,
                random: np.random.RandomState) -> tuple[Scenario, JointTrajectory]:
    """A random task of the scenario's robot drawn from `random` and planned at `dt`: its scenario and plan, the
    references within the position targets' `bounds`.

    Raises:
        RunError: No draw of TRIES could be planned.
    """
    robot = scenario.robot_def
    lo, hi = bounds
    for _ in range(TRIES):
        sections = scenario.planner_def.random_task(robot, random)
        try:
            drawn = _joint_move(scenario, bounds, random) if sections is None else _own(scenario, sections)
            plan = drawn.planner_def.plan(drawn, robot, dt)
        except (RunError, ScenarioError, ValueError):
            continue
        if np.isfinite(plan.tool_ref).all() and (plan.q_ref >= lo).all() and (plan.q_ref <= hi).all():
            return drawn, plan
    raise RunError(f"no random task of the {robot.name} could be planned in {TRIES} draws")


def draw(track: Track, model: mujoco.MjModel, data: mujoco.MjData) -> tuple[JointTrajectory, mujoco.MjData]:
    """A random task's plan from track.random (or the track's pool), and `data` posed at its start, the switches
    of its step 0 applied to `model` (the environment's: switches.pose_start); track.scenario becomes the task's."""
    assert track.random is not None, "a Track made with random"
    if track.pool is not None:
        drawn, plan = track.pool.take(track.random)
    else:
        drawn, plan = plan_random(track.base_scenario, track.target_bounds, track.dt, track.random)
    track.scenario = drawn
    pose_start(track.plant, plan, model, data)
    return plan, data
