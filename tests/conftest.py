"""Shared fixtures: shipped scenarios, and their simulations cached for the session."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import pytest  # noqa: E402

import simbench  # noqa: E402
from simbench.resources import scenarios_dir  # noqa: E402


def scenario_file(robot: str, name: str):
    """Path of a shipped scenario."""
    return scenarios_dir() / robot / f"{name}.yaml"


@pytest.fixture(scope="session")
def evaluated():
    """evaluated(robot, name) -> (scenario, Evaluation), simulated once per session."""
    cache = {}

    def get(robot: str, name: str):
        key = (robot, name)
        if key not in cache:
            scenario = simbench.load_scenario(scenario_file(robot, name))
            cache[key] = (scenario, simbench.evaluate(scenario))
        return cache[key]

    return get
