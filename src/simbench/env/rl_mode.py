"""The RL mode of a task: what a reinforcement-learning agent trains on, beside the default episode (which stays
as it is: physics-step control, actions in the joints' own units, a reward 0.5 at `analysis.path_tolerance`).

    task_kwargs, environment_kwargs = with_rl({"residual": True})
    env = simbench.env.load_task("puma600", "line", task_kwargs, environment_kwargs)

- **Control step**: `control_timestep`, 20 ms by default (10-40 ms allowed), the action held over its physics
  steps (which run in MuJoCo's C loop, `simbench.env.substeps`). A 2.9 s line is 145 steps.
- **Actions** in [-1, 1], one a joint (clipped there). Absolute: the joint's target (position actuation) or force
  (torque actuation) mapped linearly onto its action bounds (`Track.bounds`), -1 to the lower. Residual (`residual`,
  position actuation): the servo's target for the plan's reference (as its feedback revised it) shifted by
  `scale * action` within the actuator's control range, `scale` per joint (`residual_scale`; by default
  RESIDUAL_SCALE by joint type: 0.05 rad, 0.01 m), the target updated every physics step as the servo updates it,
  so that the action 0 is simbench's servo exactly; with `residual_of="reference"`, the reference itself shifted
  (target = reference + scale * action: the action 0 lags the path as a bare position servo does).
- **Reward** of the tool's distance d from its reference, `width` 20 mm by default: `gaussian` (the default),
  `0.5 ** ((d / width) ** 2)`, dm_control's gaussian `rewards.tolerance` with 0.5 at d = width; `shaped`,
  `exp(-d / width)` (0.37 at d = width), dense: it still rises towards the path from afar. Either is 0 once the
  physics has failed.
- **Observation**: the default episode's, and `tool_error` (tool - tool_ref, m); float32 throughout with the action
  spec where `float32` is set.
- **Domain randomisation and noise** (`randomise`, `noise`; off by default): `simbench.env.randomise`.

Through Gymnasium: `simbench.env.gym_ids`.
"""

from __future__ import annotations

import copy
import dataclasses
from collections import OrderedDict, deque
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Literal

import mujoco
import numpy as np
from dm_env import specs

from simbench.api import Array, JointTrajectory
from simbench.core.plant import Plant
from simbench.env.episode import Physics, Track
from simbench.env.randomise import DRAWN, Noise, Randomisation, Randomiser, as_settings
from simbench.physics.controllers import Servo
from simbench.scenario import Scenario

RESIDUAL_SCALE = {mujoco.mjtJoint.mjJNT_HINGE: 0.05, mujoco.mjtJoint.mjJNT_SLIDE: 0.01}
"""A residual action's default scale by joint type: rad (hinge) or m (slide) at an action of 1."""
CONTROL_TIMESTEPS = (0.01, 0.04)
"""The control steps the RL mode allows (s), both ends included."""


@dataclass(frozen=True)
class RL:
    """The RL mode's settings (the module's docstring says what each does).

    Attributes:
        control_timestep: The control step (s), within CONTROL_TIMESTEPS.
        residual: Whether an action shifts a target (else it is the target or force itself).
        residual_of: What a residual action shifts: `servo`, the servo's target (the action 0 is simbench's servo),
            or `reference`, the plan's reference itself (the action 0 lags it as a bare position servo does).
        residual_scale: The shift at an action of 1, one a joint or one for all (rad or m); None: RESIDUAL_SCALE.
        reward: `gaussian` or `shaped`.
        width: The reward's width (m).
        float32: Whether the action spec and the observation are float32.
        randomise: Domain randomisation: True (the defaults), a dict of Randomisation's fields, a Randomisation.
        noise: Observation and action noise: True (the defaults), a dict of Noise's fields, a Noise.
        seed: Seeds the randomisation and noise where the task has no `random` of its own (whose state they then
            share); None: fresh entropy. shimmy's `reset(seed=...)` reseeds either.
    """

    control_timestep: float = 0.02
    residual: bool = False
    residual_of: Literal["servo", "reference"] = "servo"
    residual_scale: float | tuple[float, ...] | None = None
    reward: Literal["gaussian", "shaped"] = "gaussian"
    width: float = 0.02
    float32: bool = False
    randomise: Randomisation | dict | bool | None = None
    noise: Noise | dict | bool | None = None
    seed: int | None = None

    def __post_init__(self):
        lo, hi = CONTROL_TIMESTEPS
        if not (isinstance(self.control_timestep, (int, float)) and lo - 1e-12 <= self.control_timestep <= hi + 1e-12):
            raise ValueError(f"rl control_timestep: {lo:g} to {hi:g} s expected, got {self.control_timestep!r}")
        if self.residual_of not in ("servo", "reference"):
            raise ValueError(f"rl residual_of: 'servo' or 'reference' expected, got {self.residual_of!r}")
        if self.reward not in ("gaussian", "shaped"):
            raise ValueError(f"rl reward: 'gaussian' or 'shaped' expected, got {self.reward!r}")
        if not (isinstance(self.width, (int, float)) and np.isfinite(self.width) and self.width > 0):
            raise ValueError(f"rl width: a distance > 0 (m) expected, got {self.width!r}")
        if self.residual_scale is not None:
            scale = np.atleast_1d(np.asarray(self.residual_scale, dtype=float))
            if scale.ndim != 1 or not (np.isfinite(scale).all() and (scale > 0).all()):
                raise ValueError(f"rl residual_scale: one scale > 0 a joint (or one for all) expected, got "
                                 f"{self.residual_scale!r}")
        object.__setattr__(self, "randomise", as_settings(Randomisation, self.randomise, "randomise"))
        object.__setattr__(self, "noise", as_settings(Noise, self.noise, "noise"))


def as_rl(value: RL | dict | bool) -> RL:
    """The RL mode's settings from True (the defaults), a dict of RL's fields or an RL."""
    if value is True:
        return RL()
    if isinstance(value, RL):
        return value
    if isinstance(value, dict):
        names = [f.name for f in dataclasses.fields(RL)]
        unknown = sorted(set(value) - set(names))
        if unknown:
            raise ValueError(f"rl: no setting {unknown[0]!r}; the settings are {', '.join(names)}")
        return RL(**value)
    raise ValueError(f"rl: True, a dict of settings or a simbench.env.rl_mode.RL expected, got {value!r}")


def with_rl(rl: RL | dict | bool = True, task_kwargs: dict | None = None,
            environment_kwargs: dict | None = None) -> tuple[dict, dict]:
    """The `task_kwargs` and `environment_kwargs` of `simbench.env.load` that make a task's RL mode.

    Args:
        rl: The settings: True (the defaults), a dict of RL's fields, an RL.
        task_kwargs: Other task arguments (`random`, `actuation`; `task` a subclass of RLTrack).
        environment_kwargs: Other environment arguments; a `control_timestep` here is the RL mode's.

    Returns:
        The two dicts, for `load` or `load_task`.

    Raises:
        ValueError: A setting out of its range, or `n_sub_steps` (the RL mode's control step is a time).
        TypeError: A `task` that is not an RLTrack.
    """
    task_kwargs, environment_kwargs = dict(task_kwargs or {}), dict(environment_kwargs or {})
    settings = as_rl(rl)
    task = task_kwargs.get("task", RLTrack)
    if not (isinstance(task, type) and issubclass(task, RLTrack)):
        raise TypeError(f"in the RL mode task_kwargs['task'] must be a subclass of simbench.env.rl_mode.RLTrack, "
                        f"got {task!r}")
    if "n_sub_steps" in environment_kwargs:
        raise ValueError("in the RL mode the control step is a time: give environment_kwargs' control_timestep "
                         "(or rl's), not n_sub_steps")
    if "control_timestep" in environment_kwargs:
        settings = dataclasses.replace(settings, control_timestep=environment_kwargs["control_timestep"])
    environment_kwargs["control_timestep"] = settings.control_timestep
    task_kwargs.update(task=task, rl=settings)
    return task_kwargs, environment_kwargs


class RLTrack(Track):
    """The scenario's episode in the RL mode (the module's docstring says what it is).

    Args:
        scenario: The scenario.
        plant: Its compiled robot.
        plan: Its plan.
        physics: The environment's physics.
        random: As Track's: a seed or a RandomState for random tasks at each reset.
        rl: The settings; None: the defaults.
        pool: As Track's: random tasks planned ahead.

    Attributes:
        rl: The settings.
        noise_random: What draws the randomisation and the noise.
        drawn: What the last reset's randomisation drew, by name (empty without randomisation; before the first
            reset, the model's nominal values: Randomiser.unchanged).

    Raises:
        ValueError: A residual action under torque actuation, or a residual_scale of the wrong length.
    """

    def __init__(self, scenario: Scenario, plant: Plant, plan: JointTrajectory, physics: Physics,
                 random: int | np.random.RandomState | None = None, rl: RL | None = None, pool: int | None = None):
        self.rl = rl = rl if rl is not None else RL()
        if rl.residual and plant.actuation != "position":
            raise ValueError("rl residual: a residual action shifts the servo's position target; load the task "
                             "with position actuation")
        super().__init__(scenario, plant, plan, physics, random, pool)
        model = physics.model.ptr
        self._tolerance = rl.width  # Track.get_reward's width: the gaussian reward
        self._scale = self._residual_scale(model, plant)
        self._servo = Servo.from_scenario(scenario)  # on the nominal model, whatever randomisation draws
        self._servo.bind(dataclasses.replace(plant, model=copy.copy(plant.model)), plan)
        self.noise_random = self.random if self.random is not None else np.random.RandomState(rl.seed)
        randomise: Randomisation | None = rl.randomise  # type: ignore[assignment]
        self._randomiser = Randomiser(randomise, model, plant) if randomise is not None else None
        self.drawn: dict[str, Array] = self._randomiser.unchanged() if self._randomiser is not None else {}
        self._noiseless = False  # (noiseless())
        self._queue: deque = deque()
        # The servo's targets of the references (the rows from `first`), found a stretch at a time, and the control
        # range the shifted targets are kept within
        self._targets: tuple[Array | None, int, Array] = (None, 0, np.zeros((0, model.nu)))
        self._joints_only = np.array_equal(plant.actuators, np.arange(model.nu))  # the joints' actuators, in order
        limited = model.actuator_ctrllimited.astype(bool)
        self._ctrl_range = (np.where(limited, model.actuator_ctrlrange[:, 0], -np.inf),
                            np.where(limited, model.actuator_ctrlrange[:, 1], np.inf))
        self._ctrl_tiles: dict[int, tuple[Array, Array]] = {}  # the range tiled by stretch length (_ctrl_rows)

    def _residual_scale(self, model: mujoco.MjModel, plant: Plant) -> Array:
        """Each joint's residual scale: the settings', or RESIDUAL_SCALE by joint type."""
        dof = plant.robot.dof
        if self.rl.residual_scale is None:
            joints = model.actuator_trnid[plant.actuators, 0]
            return np.array([RESIDUAL_SCALE[mujoco.mjtJoint(t)] for t in model.jnt_type[joints]])
        scale = np.atleast_1d(np.asarray(self.rl.residual_scale, dtype=float))
        if scale.size not in (1, dof):
            raise ValueError(f"rl residual_scale: one a joint ({dof}) or one for all expected, got {scale.size}")
        return np.broadcast_to(scale, (dof,)).copy()

    @property
    def _random(self) -> np.random.RandomState:
        """`noise_random` under dm_control's name, which shimmy's reset(seed=...) sets (random tasks' too)."""
        return self.noise_random

    @_random.setter
    def _random(self, value: np.random.RandomState) -> None:
        self.noise_random = value
        Track._random.fset(self, value)  # type: ignore[attr-defined]

    def initialize_episode(self, physics: Physics) -> None:
        """Draw the randomisation (if any), start the episode as Track does, and fill the delay with the action
        that holds the start.

        Args:
            physics: The physics.
        """
        if self._randomiser is not None:
            self.drawn = self._randomiser.draw(self.noise_random, physics.model.ptr, physics.data.ptr)
        super().initialize_episode(physics)
        delay = int(self.drawn["delay"][0]) if "delay" in self.drawn else 0
        self._queue = deque([self._holding_action()] * delay)

    def _holding_action(self) -> Array:
        """The action that holds the start: residual 0, or the servo's first target normalised (position), or
        no force (torque)."""
        if self.rl.residual or self.actuation == "torque":
            return np.zeros(self.plant.robot.dof)
        mid, half = self._mid_half()
        return np.clip((self._hold[self.plant.actuators] - mid) / half, -1.0, 1.0)

    def _mid_half(self) -> tuple[Array, Array]:
        """The middle and half-width of each joint's action bounds (read as they are now: random tasks may widen
        them after the task is made)."""
        lo, hi = self.bounds
        return (lo + hi) / 2, (hi - lo) / 2

    def before_step(self, action: Any, physics: Physics) -> None:
        """Take the action: noise added, clipped to [-1, 1], delayed where randomisation drew a delay.

        Args:
            action: One finite value a joint.
            physics: The physics.

        Raises:
            ValueError: The action is not one finite value a joint.
        """
        action = self.checked(action)
        noise: Noise | None = self.rl.noise  # type: ignore[assignment]
        if noise is not None and noise.action > 0:
            action = action + self.noise_random.normal(0.0, noise.action, action.shape)
        action = np.minimum(np.maximum(action, -1.0), 1.0)  # np.clip's, at a third less per step
        if self._queue:
            self._queue.append(action)
            action = self._queue.popleft()
        if self.rl.residual:  # the joints' shifts
            command = self._scale * action
        else:  # their targets
            mid, half = self._mid_half()
            command = mid + half * action
        if not self._joints_only:  # a row of data.ctrl: zero but for the joints' actuators
            command, joints = np.zeros(physics.model.ptr.nu), command
            command[self.plant.actuators] = joints
        self._command = command

    def controls(self, physics: Physics, steps: int) -> Array:
        """The command held (absolute), or the servo's targets for the next samples' references, shifted and kept
        within the control range (residual).

        Args:
            physics: The physics.
            steps: How many physics steps.

        Returns:
            One command a step (steps, nu).
        """
        if not self.rl.residual:
            return np.repeat(self._command[None], steps, axis=0)
        k = self.k
        refs, first, targets = self._targets
        if refs is not self.q_ref or not first <= k <= k + steps <= first + len(targets):
            # up to the next switch, after which the plan's feedback may revise the references (in place)
            stop = max(self._next_stop(k), k + steps)
            first, targets = k, self._residual_base(k, stop)
            self._targets = (self.q_ref, first, targets)
        shifted = targets[k - first:k - first + steps] + self._command
        lo, hi = self._ctrl_rows(steps)
        return np.minimum(np.maximum(shifted, lo, out=shifted), hi, out=shifted)

    def _ctrl_rows(self, steps: int) -> tuple[Array, Array]:
        """The control range as `steps` rows (steps, nu) each, made once a stretch length: a clip against arrays of
        its own shape costs a third of one that broadcasts a row, every control step."""
        if steps not in self._ctrl_tiles:
            self._ctrl_tiles[steps] = tuple(np.tile(bound, (steps, 1)) for bound in self._ctrl_range)
        return self._ctrl_tiles[steps]

    def _residual_base(self, start: int, stop: int) -> Array:
        """What a residual action shifts at samples start to stop (stop - start, nu): the servo's targets for the
        references, or the references themselves (`residual_of`)."""
        if self.rl.residual_of == "servo":
            return self._servo.targets(self.q_ref[start:stop], self.qd_ref[start:stop])
        base = np.zeros((stop - start, self.plant.model.nu))
        base[:, self.plant.actuators] = self.q_ref[start:stop]
        return base

    def action_spec(self, physics: Physics) -> specs.BoundedArray:
        """One value a joint in [-1, 1], float32 where the settings say so.

        Args:
            physics: The physics.

        Returns:
            The spec.
        """
        return specs.BoundedArray(shape=(self.plant.robot.dof,), dtype=np.float32 if self.rl.float32 else float,
                                  minimum=-1.0, maximum=1.0, name="action")

    def get_observation(self, physics: Physics) -> OrderedDict:
        """Track's observation with `tool_error`, the measured entries noisy where noise is on, `randomised` where
        the randomisation is observed; float32 where the settings say so.

        Args:
            physics: The physics.

        Returns:
            The observation.
        """
        obs = super().get_observation(physics)
        noise: Noise | None = self.rl.noise  # type: ignore[assignment]
        if noise is not None and not self._noiseless:
            for name in ("q", "qd", "tool"):
                obs[name] = obs[name] + self.noise_random.normal(0.0, getattr(noise, name), obs[name].shape)
        obs["tool_error"] = obs["tool"] - obs["tool_ref"]
        randomise: Randomisation | None = self.rl.randomise  # type: ignore[assignment]
        if randomise is not None and randomise.observe:
            drawn = [self.drawn[name] for name in DRAWN if name in self.drawn]
            obs["randomised"] = np.concatenate([np.zeros(0), *drawn])  # (empty where it draws nothing)
        if self.rl.float32:
            for name, value in obs.items():  # the values replaced in place, the order kept
                obs[name] = value.astype(np.float32)
        return obs

    @contextmanager
    def noiseless(self) -> Iterator[None]:
        """A block in which get_observation draws no noise (Track.noiseless's reason)."""
        self._noiseless = True
        try:
            yield
        finally:
            self._noiseless = False

    def get_reward(self, physics: Physics) -> float:
        """`gaussian`: Track's reward at `width`; `shaped`: exp(-d / width).

        Args:
            physics: The physics.

        Returns:
            The reward; 0 once the physics has failed.
        """
        if self.rl.reward == "gaussian" or self.failure is not None:
            return super().get_reward(physics)
        offset = physics.data.ptr.sensordata[self._tool] - self.plan.tool_ref[self.k]
        return float(np.exp(-np.sqrt(offset @ offset) / self.rl.width))
