"""Every scenario as a dm_control environment, for any controller or policy, scored by simbench's own analysis.

    import simbench.env
    env = simbench.env.load("scenarios/puma600/weld_seam.yaml")   # or simbench.env.load_task("puma600", "weld_seam")
    step = env.reset()
    while not step.last():
        step = env.step(policy(step.observation))
    simbench.env.write_outputs(env, "renders/weld_seam_mine")     # report.json, timeseries.npz, plots, video

An episode is the scenario's run as `simbench.sim.simulate` makes it, one control step a physics step:

- reset: the plan (made once, by `load`) at its start pose (`switches.at_start`), settled for `sim.settle` as
  `simulate` settles: under position actuation the servo's first command is held (simbench.controllers.Servo,
  stepped through `mujoco.rollout` as `simulate` steps it); under torque actuation the computed-torque controller
  (the scenario's gains if it names computed_torque, else its defaults) holds the plan's first sample, closed
  loop, as `simulate` settles a computed_torque run.
- action: one value per robot joint, given to that joint's actuator: position targets, or torques and forces;
  bounded by the actuator's control range where it has one (the joint range, or under torque actuation the force
  range), else +-mjMAXVAL as dm_control's `action_spec` writes "unbounded".
- step: MuJoCo's step split as simbench's closed loop splits it (`mj_step2` finishes the step `mj_step1`
  prepared, then `mj_step1` at the new state, which the observation reads): dm_control's own step, with the
  sensors of each step kept for the recording. The planned switches (RSMG welds) are applied at their sample,
  before the step from it, and the plan's feedback revises the references the observations show from then on.
- observation: simbench.observation.observation, what a `policy` controller gets: joint positions and speeds,
  the tool point, the references now and AHEAD samples ahead, the tool's reference.
- reward: in [0, 1], from the tool's distance to its reference at this sample (dm_control.utils.rewards.
  tolerance, gaussian): 1 at no error, 0.5 at the scenario's `analysis.path_tolerance`.
- end: at the plan's last sample (len(t) - 1 steps after reset), with discount 1: a time limit.
- faults: dm_control's PhysicsError, with the time and simbench's reason (simbench.faults: a fatal MuJoCo
  warning, a NaN state, a speed past 1000 rad/s); other MuJoCo warnings are kept for the report.

Every step is recorded; `recording(env)` is the episode as a simbench.sim.Recording (the same rows as
`simulate`'s closed loop records), `evaluation(env)` analyses it as a run is analysed, and `write_outputs(env,
out)` writes what `simbench.run` writes. `ALL_TASKS` lists every shipped scenario as (robot, name).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
from dm_control.mujoco import wrapper
from dm_control.rl import control

from simbench import budget
from simbench.env.episode import Physics, Track
from simbench.errors import RunError
from simbench.plant import Actuation, Plant
from simbench.resources import scenarios_dir
from simbench.scenario import Scenario, as_scenario
from simbench.sim import Recording
from simbench.switches import at_start

if TYPE_CHECKING:
    from simbench.pipeline import Evaluation, Result

__all__ = ["ALL_TASKS", "Physics", "Track", "evaluation", "load", "load_task", "recording", "write_outputs"]

ALL_TASKS: tuple[tuple[str, str], ...] = tuple((path.parent.name, path.stem)
                                               for path in sorted(scenarios_dir().glob("*/*.yaml")))


def load(scenario: Scenario | str | os.PathLike, actuation: Actuation = "position",
         flat_observation: bool = False) -> control.Environment:
    """The scenario (or the scenario file at a path) as a dm_control Environment whose actions are position
    targets or (actuation="torque") torques and forces; ScenarioError if its run is beyond the machine
    (simbench.budget), RunError if its plan cannot be made."""
    scenario = as_scenario(scenario, "simbench.env.load")
    if actuation not in ("position", "torque"):
        raise ValueError(f"actuation must be 'position' or 'torque', got {actuation!r}")
    budget.check(scenario)
    sim, robot = scenario.sim, scenario.robot_def
    plant = Plant.load(robot, sim.timestep, sim.kp, sim.kv, sim.force_limits, sim.gravity_compensation, actuation)
    if plant.model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
        raise RunError(f"the {robot.name} scene's RK4 integrator cannot be stepped as an environment steps (mj_step1, "
                       "then mj_step2); use implicitfast or Euler")
    plan = scenario.planner_def.plan(scenario, robot, float(plant.model.opt.timestep))
    _, data, _ = at_start(plant, plan)  # the environment's own model copy: switching edits it
    physics = Physics(wrapper.MjData(data))
    return control.Environment(physics, Track(scenario, plant, plan, physics), flat_observation=flat_observation)


def load_task(robot: str, name: str, actuation: Actuation = "position",
              flat_observation: bool = False) -> control.Environment:
    """The environment of the shipped scenario scenarios/<robot>/<name>.yaml (one of ALL_TASKS)."""
    if (robot, name) not in ALL_TASKS:
        raise ValueError(f"no shipped scenario {robot}/{name}; ALL_TASKS lists them: "
                         f"{', '.join(f'{r}/{n}' for r, n in ALL_TASKS)}")
    return load(scenarios_dir() / robot / f"{name}.yaml", actuation, flat_observation)


def _track(env: control.Environment) -> Track:
    task = getattr(env, "task", None)
    if not isinstance(task, Track):
        raise TypeError(f"expected an environment of simbench.env.load, got {type(env).__name__}")
    return task


def recording(env: control.Environment) -> Recording:
    """The episode so far (from the last reset) as a simbench.sim.Recording."""
    return _track(env).recording(env.physics)


def evaluation(env: control.Environment, control_info: dict | None = None) -> Evaluation:
    """A finished episode analysed as `simbench.evaluate` analyses a run: its Evaluation, whose `control` is
    {"controller": "simbench.env", "actuation": ...} and `control_info` (what ran it: your policy's name, say).
    RuntimeError if the episode has not reached its end."""
    from simbench.analysis import analyse
    from simbench.pipeline import Evaluation
    from simbench.robots import Tolerance
    from simbench.sim import commanded
    from simbench.verdict import run_verdict

    task = _track(env)
    if task.k < task.n - 1:
        raise RuntimeError(f"the episode is at step {task.k} of {task.n - 1}: step it to its end (the last "
                           "TimeStep) before analysing it")
    rec = recording(env)
    scenario, robot = task.scenario, task.plant.robot
    traj = commanded(task.plan, rec)
    a = scenario.analysis
    result = analyse(robot, traj, rec, near=Tolerance(a.near_angle, a.near_length),
                     margin=Tolerance(a.limit_angle, a.limit_length), scenario=scenario)
    verdict = run_verdict(robot, traj, result, a, scenario.expect)
    info = {"controller": "simbench.env", "actuation": task.actuation, **(control_info or {})}
    return Evaluation(traj, rec, result, verdict, info)


def write_outputs(env: control.Environment, out: str | Path | None = None, video: bool = True,
                  force: bool = False, control_info: dict | None = None) -> Result:
    """Write a finished episode's report.json, timeseries.npz, plots/ and (unless video=False) video.mp4 into
    `out` (default renders/<name>/) as `simbench.run` writes a run's, with the same refusals (a folder that
    holds anything unless `force`, one writer at a time, the machine's budget)."""
    from simbench import destination
    from simbench.pipeline import write_outputs as write

    task = _track(env)
    scenario = task.scenario
    out = destination.followed(Path(out) if out is not None else Path("renders") / (scenario.name or "episode"))
    budget.check(scenario, video=video, outputs=True, out=out)
    ev = evaluation(env, control_info)
    inputs: Sequence[Path] = [Path(scenario.source)] if scenario.source and Path(scenario.source).is_file() else []
    with destination.locked(out):
        destination.check(out, inputs, force)
        return write(scenario, ev, out, video)
