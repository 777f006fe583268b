"""A plan's plant, fitted before it is simulated (`Robot.plant_fit`): a start whose geoms touch refused as bad input,
what the plan breaks that the plant shows (a contact along it, a force past a limit) added to its violations, and
the position servos' gains designed for it, unless the scenario states its own (`sim.kp`, `sim.kv`)."""

from __future__ import annotations

from dataclasses import replace

from simbench.api.trajectory import JointTrajectory
from simbench.core.errors import ScenarioError
from simbench.core.plant import Plant


def fit(scenario, plant: Plant, traj: JointTrajectory) -> tuple[Plant, JointTrajectory, tuple[dict, ...]]:
    """The plant and the plan to simulate, and report.json's servo design (empty where none was designed);
    ScenarioError naming the start where its geoms touch."""
    robot, sim = plant.robot, scenario.sim
    found = robot.plant_fit(plant, traj, scenario.analysis)
    if found is None:
        return plant, traj, ()
    if found.start_contacts:
        field = "task.start" if hasattr(scenario.task, "start") else "task"
        more = f" (and {len(found.start_contacts) - 1} more)" if len(found.start_contacts) > 1 else ""
        raise ScenarioError(scenario.source, field, f"puts {found.start_contacts[0]}{more}: start where the arm's "
                                                    "geoms are clear of each other and of the floor")
    traj = replace(traj, violations=(*traj.violations, *found.violations))
    if plant.actuation != "position" or sim.kp is not None or sim.kv is not None or not found.kp:
        return plant, traj, ()
    gains = plant.gains()
    kp = [found.kp.get(joint, value) for joint, value in zip(robot.joints, gains["kp"])]
    kv = [found.kv.get(joint, value) for joint, value in zip(robot.joints, gains["kv"])]
    plant = Plant.load(robot, float(plant.model.opt.timestep), kp, kv, sim.force_limits, sim.gravity_compensation,
                       plant.actuation)
    return plant, traj, found.design
