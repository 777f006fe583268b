"""simbench.env through Gymnasium: every shipped task, wrapped by shimmy's DmControlCompatibilityV0, held to
Gymnasium's own environment checker, and its action space to what a Gymnasium agent samples from (finite bounds,
a limited joint's position targets within the joint's range in the MuJoCo model)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from simbench import env as simbench_env

gymnasium = pytest.importorskip("gymnasium", reason="Gymnasium (and shimmy) are in the [test] and [rl] extras")
shimmy = pytest.importorskip("shimmy", reason="shimmy (and Gymnasium) are in the [test] and [rl] extras")
from gymnasium.utils.env_checker import check_env  # noqa: E402

CASES = [pytest.param(robot, name, actuation, id=f"{robot}/{name}/{actuation}")
         for actuation in ("position", "torque") for robot, name in simbench_env.ALL_TASKS]


def gym_env(robot: str, name: str, actuation: str):
    """The shipped task as a Gymnasium environment, as a Gymnasium user wraps a dm_control one."""
    return shimmy.DmControlCompatibilityV0(simbench_env.load_task(robot, name, actuation=actuation))


@pytest.mark.parametrize("robot, name, actuation", CASES)
def test_check_env(robot, name, actuation):
    """Gymnasium's checker: spaces, reset and step signatures, seeded determinism, observations in their space."""
    env = gym_env(robot, name, actuation)
    with warnings.catch_warnings():
        # Its advice (a Box bounded by infinity, an action space not normalised to [-1, 1]) is not a failure:
        # dm_control's observations are unbounded and a joint's action is in its own unit.
        warnings.simplefilter("ignore", UserWarning)
        check_env(env, skip_render_check=True)
    env.close()


@pytest.mark.parametrize("robot, name, actuation", CASES)
def test_action_space_is_bounded(robot, name, actuation):
    """Every bound finite; a position target of a limited joint within that joint's range (the model's jnt_range),
    so that actions sampled from the space are ones the joint can reach."""
    dm_env = simbench_env.load_task(robot, name, actuation=actuation)
    env = shimmy.DmControlCompatibilityV0(dm_env)
    space = env.action_space
    assert isinstance(space, gymnasium.spaces.Box) and space.is_bounded("both")
    assert np.all(space.high < 1e6) and np.all(space.low > -1e6), (space.low, space.high)
    if actuation == "position":
        model = dm_env.physics.model.ptr
        joints = model.actuator_trnid[dm_env.task.plant.actuators, 0]
        limited = model.jnt_limited[joints].astype(bool)
        lo, hi = model.jnt_range[joints].T
        assert np.all(space.low[limited] >= lo[limited] - 1e-12), (space.low, lo)
        assert np.all(space.high[limited] <= hi[limited] + 1e-12), (space.high, hi)
    sample = space.sample()
    env.reset(seed=0)
    _, reward, terminated, truncated, _ = env.step(sample)
    assert 0.0 <= reward <= 1.0 and not truncated
    env.close()


def test_reset_seed_seeds_the_random_tasks():
    """shimmy's reset(seed=...) seeds a task made with task_kwargs={'random': ...} (dm_control's task._random):
    the same seed, the same task in another environment; another seed, another (and Gymnasium's checker passes);
    without `random`, the seed leaves the scenario's own task."""
    def goal(env, seed):
        env.reset(seed=seed)
        return env.unwrapped._env.task.plan.q_ref[-1].copy()

    def make(**task_kwargs):
        return shimmy.DmControlCompatibilityV0(simbench_env.load_task("spherical_arm", "case1",
                                                                      task_kwargs=task_kwargs))

    a, b = make(random=1), make(random=2)
    assert np.array_equal(goal(a, 5), goal(b, 5))
    assert not np.array_equal(goal(a, 5), goal(b, 6))
    plain = make()
    shipped = plain.unwrapped._env.task.plan.q_ref[-1].copy()
    assert np.array_equal(goal(plain, 5), shipped)
    with warnings.catch_warnings():  # Gymnasium's checker: the same seed, the same observations
        warnings.simplefilter("ignore", UserWarning)
        check_env(make(random=1), skip_render_check=True)
