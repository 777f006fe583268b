"""Every scenario as a dm_control environment, for any controller or policy, scored by simbench's own analysis.

    import simbench.env
    env = simbench.env.load("scenarios/puma600/weld_seam.yaml")   # or simbench.env.load_task("puma600", "weld_seam")
    step = env.reset()
    while not step.last():
        step = env.step(policy(step.observation))
    simbench.env.write_outputs(env, "renders/weld_seam_mine")     # report.json, timeseries.npz, plots, video

An episode is the scenario's run as `simbench.physics.sim.simulate` makes it: reset settles at the plan's start as
`simulate` settles (physics.time() and the observed time are 0 after it); an action is one value per joint
(position targets within the joint ranges, a joint with none the plan's span +- CONTINUOUS_SPAN; or torques and
forces within the force limits), held for the control step's physics steps (environment_kwargs' n_sub_steps or
control_timestep; 1 by default), each split as simbench's closed loop splits MuJoCo's step, applying planned
switches and the plan's feedback, and recorded; the observation is simbench.physics.observation's and the reward
dm_control's gaussian tolerance of the tool's error (0.5 at `analysis.path_tolerance`), both at the control
step's last physics step; the episode ends at the plan's last sample (timing.duration + timing.hold; the last
control step may be shorter), at time_limit (discount 1) or where the physics fails (discount 0, reward 0, the
physics back at the last sound sample, `Track.failure` saying when and why). `evaluation` analyses every physics
step that ran: `failed` or `truncated` where the episode ended early. task_kwargs={'random': seed} draws a random
task at each reset (simbench.env.random_task, which widens the bounds of a joint without a range for the
planner's own); task_kwargs={'rl': True} is the RL mode (simbench.env.rl_mode: 20 ms control steps, actions
in [-1, 1]; simbench.env.gym_ids names it in Gymnasium). snapshot/restore replay an episode exactly.
copy.deepcopy and pickle take an environment (and a snapshot) whole: the copy steps as the original.
visualize_reward colours the arm by the reward, as dm_control's suite does; frames render through EGL (or the
user's MUJOCO_GL) whichever of dm_control's users came first.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from simbench.outputs.render import choose_dm_control_backend

choose_dm_control_backend()  # before dm_control's first context: EGL, or the user's MUJOCO_GL, in any import order
from dm_control.mujoco import wrapper  # noqa: E402
from dm_control.rl import control  # noqa: E402
from dm_env import TimeStep  # noqa: E402

from simbench.core import budget  # noqa: E402
from simbench.core.errors import RunError  # noqa: E402
from simbench.core.plant import Actuation, Plant  # noqa: E402
from simbench.core.resources import scenarios_dir  # noqa: E402
from simbench.env.bounds import CONTINUOUS_SPAN  # noqa: E402
from simbench.env.episode import Physics, Track, track_of  # noqa: E402
from simbench.env.replay import Snapshot, restore, servo_policy, snapshot  # noqa: E402
from simbench.physics.fitting import fit  # noqa: E402
from simbench.physics.sim import Recording  # noqa: E402
from simbench.physics.switches import at_start  # noqa: E402
from simbench.scenario import Scenario, as_scenario  # noqa: E402

if TYPE_CHECKING:
    from simbench.commands.pipeline import Evaluation, Result

__all__ = ["ALL_TASKS", "CONTINUOUS_SPAN", "Environment", "Physics", "Snapshot", "Track", "evaluation", "load",
           "load_task", "recording", "restore", "servo_policy", "snapshot", "write_outputs"]

ALL_TASKS: tuple[tuple[str, str], ...] = tuple((path.parent.name, path.stem)
                                               for path in sorted(scenarios_dir().glob("*/*.yaml")))
"""The shipped scenarios as (robot, name) pairs, as dm_control's `suite.ALL_TASKS`: what `load_task` loads."""


HIGHLIGHT_RGBA = np.array([0.0, 0.5, 0.3, 1.0], np.float32)
"""The arm's colour at a reward of 1 under visualize_reward: dm_control's suite's `self_highlight`
(suite/common/materials.xml)."""


class Environment(control.Environment):
    """dm_control's Environment of a scenario, as `load` makes it.

    With `visualize_reward`, the arm's geoms are coloured by the reward (clipped to [0, 1]) at each reset and
    step, as dm_control's suite colours its tasks (`base.Task.after_step`, `_set_reward_colors`): each geom's own
    colour blended toward HIGHLIGHT_RGBA by reward ** 4.

    Args:
        physics: The episode's physics.
        task: The episode's task.
        visualize_reward: Whether to colour the arm by the reward.
        **kwargs: What `control.Environment` takes (`time_limit`, `control_timestep`, `n_sub_steps`,
            `flat_observation`).
    """

    def __init__(self, physics: Physics, task: Track, visualize_reward: bool = False, **kwargs: Any):
        super().__init__(physics, task, **kwargs)
        self.visualize_reward = visualize_reward
        model = physics.model.ptr
        self._arm_geoms = arm_geoms(model, task.plant)
        self._arm_rgba = drawn_rgba(model, self._arm_geoms)

    @property
    def visualize_reward(self) -> bool:
        """Whether the arm is coloured by the reward (dm_control's `base.Task.visualize_reward`)."""
        return self._visualize_reward

    @visualize_reward.setter
    def visualize_reward(self, value: bool) -> None:
        if not isinstance(value, bool):  # a ValueError, as dm_control's
            raise ValueError(f"visualize_reward must be a bool, got {type(value).__name__}")  # noqa: TRY004
        self._visualize_reward = value

    def observation_spec(self) -> Any:
        """dm_control's, its observation made without noise (Track.noiseless): asking for it draws nothing."""
        with self._task.noiseless():
            return super().observation_spec()

    def reset(self) -> TimeStep:
        """dm_control's reset, then the arm coloured by the reward at the start (as the suite's tasks do)."""
        timestep = super().reset()
        if self._visualize_reward:
            self._colour(self._task.get_reward(self._physics))
        return timestep

    def step(self, action: Any) -> TimeStep:
        """dm_control's step, then the arm coloured by its reward (after a reset: by the reward at the start)."""
        timestep = super().step(action)
        if self._visualize_reward and timestep.reward is not None:
            self._colour(timestep.reward)
        return timestep

    def _colour(self, reward: float) -> None:
        blend = float(np.clip(reward, 0.0, 1.0)) ** 4  # dm_control's: better told apart near high rewards
        self._physics.model.ptr.geom_rgba[self._arm_geoms] = blend * HIGHLIGHT_RGBA + (1.0 - blend) * self._arm_rgba


def arm_geoms(model: mujoco.MjModel, plant: Plant) -> np.ndarray:
    """The geoms of the bodies the robot's actuated joints move (those bodies and all below them)."""
    moved = np.zeros(model.nbody, bool)
    moved[model.jnt_bodyid[model.actuator_trnid[plant.actuators, 0]]] = True
    for body in range(1, model.nbody):  # MuJoCo numbers a body after its parent
        moved[body] |= moved[model.body_parentid[body]]
    return np.flatnonzero(moved[model.geom_bodyid])


_DEFAULT_RGBA = np.array([0.5, 0.5, 0.5, 1.0], np.float32)  # a geom's rgba where its file sets none


def drawn_rgba(model: mujoco.MjModel, geoms: np.ndarray) -> np.ndarray:
    """The colours MuJoCo draws the geoms in: a geom's material's unless the geom sets its own rgba."""
    rgba = model.geom_rgba[geoms].copy()
    matid = model.geom_matid[geoms]
    of_material = (matid >= 0) & (rgba == _DEFAULT_RGBA).all(axis=1)
    rgba[of_material] = model.mat_rgba[matid[of_material]]
    return rgba


def load(scenario: Scenario | str | os.PathLike, task_kwargs: dict | None = None,
         environment_kwargs: dict | None = None, visualize_reward: bool = False, *, actuation: Actuation = "position",
         flat_observation: bool = False) -> Environment:
    """A scenario as a dm_control Environment, as dm_control's `suite.load` loads a task.

    Args:
        scenario: A Scenario, or the path of a scenario file.
        task_kwargs: What makes the task: `random` (a seed or a RandomState: a new random task at each reset),
            `pool` (with `random`: each reset takes one of this many random tasks planned ahead in a background
            process, `simbench.env.task_pool`), `actuation`, `task` (a subclass of Track, for a reward or
            observation of your own) and that class's own arguments, and `rl`: the RL mode
            (`simbench.env.rl_mode`: 20 ms control steps, actions in [-1, 1]) as True (its defaults), a dict of
            `rl_mode.RL`'s fields or an `RL`; None or False: none.
        environment_kwargs: What goes to `control.Environment`: `control_timestep` or `n_sub_steps`,
            `time_limit`, `flat_observation`.
        visualize_reward: Whether rendered frames show the reward in the arm's colour (dm_control's meaning:
            `Environment`).
        actuation: `"position"` (targets of the position servos) or `"torque"` (forces and torques).
        flat_observation: Whether the observation is one flat array.

    Returns:
        The environment.

    Raises:
        ScenarioError: The scenario is bad input, or beyond what the machine can give.
        RunError: The scenario cannot be planned, or its scene cannot be stepped as an environment steps.
        ValueError: A control step of no physics step (n_sub_steps < 1), or an RL setting out of its range.
    """
    scenario = as_scenario(scenario, "simbench.env.load")
    task_kwargs = dict(task_kwargs or {})
    rl = task_kwargs.pop("rl", None)
    if rl is not None and rl is not False:  # the RL mode
        from simbench.env.rl_mode import with_rl
        task_kwargs, environment_kwargs = with_rl(rl, task_kwargs, environment_kwargs)
    environment_kwargs = {"flat_observation": flat_observation, **(environment_kwargs or {})}
    actuation = task_kwargs.pop("actuation", actuation)
    task_class = task_kwargs.pop("task", Track)
    if actuation not in ("position", "torque"):
        raise ValueError(f"actuation must be 'position' or 'torque', got {actuation!r}")
    if not (isinstance(task_class, type) and issubclass(task_class, Track)):
        raise TypeError(f"task_kwargs['task'] must be a subclass of simbench.env.Track, got {task_class!r}")
    budget.check(scenario)
    sim, robot = scenario.sim, scenario.robot_def
    plant = Plant.load(robot, sim.timestep, sim.kp, sim.kv, sim.force_limits, sim.gravity_compensation, actuation)
    if plant.model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
        raise RunError(f"the {robot.name} scene's RK4 integrator cannot be stepped as an environment steps (mj_step1, "
                       "then mj_step2); use implicitfast or Euler")
    random_tasks = task_kwargs.get("random") is not None
    if random_tasks:
        from simbench.env.random_task import check, widen
        check(scenario)
    plan = scenario.planner_def.plan(scenario, robot, float(plant.model.opt.timestep))
    plant, plan, design = fit(scenario, plant, plan)  # a derived arm's servos designed for the first plan
    _, data, _ = at_start(plant, plan)  # the environment's own model copy: switching edits it
    physics = Physics(wrapper.MjData(data))
    task = task_class(scenario, plant, plan, physics, **task_kwargs)
    task.servo_design = tuple(design)
    if random_tasks:
        widen(task, physics.model.ptr)
    env = Environment(physics, task, visualize_reward, **environment_kwargs)
    if not env.control_timestep() > 0:  # dm_control takes 0: its episodes would never end
        raise ValueError("a control step must be at least one physics step: environment_kwargs' n_sub_steps is "
                         f"{environment_kwargs.get('n_sub_steps')}")
    return env


def load_task(robot: str, name: str, task_kwargs: dict | None = None, environment_kwargs: dict | None = None,
              visualize_reward: bool = False, *, actuation: Actuation = "position",
              flat_observation: bool = False) -> Environment:
    """The environment of a shipped scenario, `scenarios/<robot>/<name>.yaml`.

    Args:
        robot: The robot's folder, as in `ALL_TASKS`.
        name: The scenario's name, as in `ALL_TASKS`.
        task_kwargs: As `load`'s: `random`, `actuation`, `task` and its arguments, `rl` (the RL mode: True, a
            dict of `rl_mode.RL`'s fields or an `RL`).
        environment_kwargs: As `load`'s.
        visualize_reward: As `load`'s.
        actuation: As `load`'s.
        flat_observation: As `load`'s.

    Returns:
        The environment.

    Raises:
        ValueError: No such shipped scenario.
    """
    if (robot, name) not in ALL_TASKS:
        raise ValueError(f"no shipped scenario {robot}/{name}; ALL_TASKS lists them: "
                         f"{', '.join(f'{r}/{n}' for r, n in ALL_TASKS)}")
    return load(scenarios_dir() / robot / f"{name}.yaml", task_kwargs, environment_kwargs, visualize_reward,
                actuation=actuation, flat_observation=flat_observation)


def recording(env: control.Environment) -> Recording:
    """The episode so far, from the last reset.

    Args:
        env: An environment of `load`.

    Returns:
        The recording, as `simbench.evaluate` records a run.
    """
    return track_of(env).recording(env.physics)


def evaluation(env: control.Environment, control_info: dict | None = None) -> Evaluation:
    """The episode analysed as `simbench.evaluate` analyses a run.

    An episode that ended early is analysed as far as it ran: its status is `failed` where its physics failed,
    else `truncated`.

    Args:
        env: An environment of `load`.
        control_info: What ran the episode, for the report (a policy's name and settings, say).

    Returns:
        The evaluation.

    Raises:
        RuntimeError: The episode has taken no sound step since its reset.
    """
    from simbench.analysis import analyse
    from simbench.analysis.verdict import FAILED, TRUNCATED, cut_short, run_verdict
    from simbench.commands.pipeline import Evaluation
    from simbench.physics.sim import commanded
    from simbench.robots import Tolerance

    task = track_of(env)
    if task.k == 0 and task.failure is not None:
        raise RuntimeError(f"nothing to evaluate: the episode's first step failed ({task.failure})")
    if task.k == 0:
        raise RuntimeError("the episode has taken no step since its reset: nothing to evaluate")
    rec = recording(env)
    scenario, robot = task.scenario, task.plant.robot
    traj = commanded(task.plan, rec)
    if task.k < task.n - 1:
        traj = traj.rows(np.arange(task.k + 1))
    a = scenario.analysis
    result = analyse(robot, traj, rec, near=Tolerance(a.near_angle, a.near_length),
                     margin=Tolerance(a.limit_angle, a.limit_length), scenario=scenario)
    verdict = run_verdict(robot, traj, result, a, scenario.expect)
    if task.failure is not None:
        verdict = cut_short(verdict, FAILED, float(rec.t[-1]), task.failure)
    elif task.k < task.n - 1:
        verdict = cut_short(verdict, TRUNCATED, float(rec.t[-1]), f"the episode stopped at t = {rec.t[-1]:.4f} s, "
                            f"before the plan's end at {task.plan.t[-1]:.4f} s (step {task.k} of {task.n - 1})")
    design = {"servo_design": list(task.servo_design)} if task.servo_design else {}
    info = {"controller": "simbench.env", "actuation": task.actuation, **design, **(control_info or {})}
    return Evaluation(traj, rec, result, verdict, info)


def write_outputs(env: control.Environment, out: str | Path | None = None, video: bool = True,
                  force: bool = False, control_info: dict | None = None) -> Result:
    """Write an episode's outputs as `simbench.run` writes a run's.

    Args:
        env: An environment of `load`.
        out: The output folder, which must be empty unless `force`; None: `renders/<name>/`.
        video: Whether to render the video.
        force: Whether to replace what the folder holds.
        control_info: As `evaluation`'s.

    Returns:
        The result: where the outputs are, and what they say.
    """
    from simbench.commands.pipeline import write_outputs as write
    from simbench.core import destination

    task = track_of(env)
    scenario = task.scenario
    out = destination.followed(Path(out) if out is not None else Path("renders") / (scenario.name or "episode"))
    budget.check(scenario, video=video, outputs=True, out=out)
    ev = evaluation(env, control_info)
    inputs: Sequence[Path] = [Path(scenario.source)] if scenario.source and Path(scenario.source).is_file() else []
    with destination.locked(out):
        destination.check(out, inputs, force)
        return write(scenario, ev, out, video)
