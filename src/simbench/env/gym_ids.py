"""Gymnasium ids for every shipped task in the RL mode: `simbench/<robot>-<task>-v0` (`simbench.env.ALL_TASKS`;
`simbench/puma600-line-v0`, `simbench/spherical_arm-case1-v0`), registered when this module is imported.

    import gymnasium
    import simbench.env.gym_ids  # noqa: F401  (or gymnasium.make("simbench.env.gym_ids:simbench/puma600-line-v0"))
    env = gymnasium.make("simbench/puma600-line-v0", rl={"residual": True})

Each is the task's RL mode (`simbench.env.rl_mode`, float32 by default here: Gymnasium agents' usual dtype) wrapped
by shimmy's DmControlCompatibilityV0; `gymnasium.make`'s keyword arguments reach `make`. Gymnasium 1.x reads no
plugin entry points, so the ids exist once this module is imported (or named in the id, as above).
"""

from __future__ import annotations

from typing import Any

import gymnasium

from simbench.core.plant import Actuation
from simbench.env import ALL_TASKS, load_task
from simbench.env.rl_mode import RL, with_rl

VERSION = 0


def gym_id(robot: str, name: str) -> str:
    """The Gymnasium id of a shipped task."""
    return f"simbench/{robot}-{name}-v{VERSION}"


def make(robot: str, name: str, rl: RL | dict | bool = True, task_kwargs: dict | None = None,
         environment_kwargs: dict | None = None, actuation: Actuation = "position", render_mode: str | None = None,
         render_kwargs: dict[str, Any] | None = None) -> gymnasium.Env:
    """A shipped task's RL mode as a Gymnasium environment (what the ids make).

    Args:
        robot: The robot's folder, as in ALL_TASKS.
        name: The scenario's name, as in ALL_TASKS.
        rl: The RL mode's settings (simbench.env.rl_mode.RL's fields), float32 unless they say otherwise.
        task_kwargs: As simbench.env.load's (`random`).
        environment_kwargs: As simbench.env.load's (`time_limit`, `flat_observation`).
        actuation: `"position"` or `"torque"`.
        render_mode: shimmy's (`rgb_array`, `depth_array`, `human`, `multi_camera`).
        render_kwargs: shimmy's (`width`, `height`, `camera_id`).

    Returns:
        The environment.
    """
    from shimmy import DmControlCompatibilityV0

    if rl is True or isinstance(rl, dict):
        rl = {"float32": True, **(rl if isinstance(rl, dict) else {})}
    env = load_task(robot, name, *with_rl(rl, task_kwargs, environment_kwargs), actuation=actuation)
    return DmControlCompatibilityV0(env, render_mode=render_mode, render_kwargs=render_kwargs)


for _robot, _name in ALL_TASKS:
    gymnasium.register(gym_id(_robot, _name), entry_point="simbench.env.gym_ids:make",
                       kwargs={"robot": _robot, "name": _name})
