"""Contract tests over the registry (after dm_control's suite_test.py and Menagerie's model_test.py): every
registered robot, shipped or brought by an installed package, and every robot x planner pair.

Each robot's scene loads and steps under random controls with no MuJoCo warning; its fk (where it has one)
equals MuJoCo's tool site at random joint values; a run is deterministic. Each pair either validates and runs a
generated task, or is refused at validation with one line naming the planner.
"""

import importlib.metadata

import mujoco
import numpy as np
import pytest
import yaml

from simbench import api
from simbench.api import registry
from simbench.cli import main
from simbench.commands import pipeline
from simbench.core.errors import RegistryError, ScenarioError
from simbench.core.plant import Plant, compiled_scene
from simbench.scenario import parse_scenario

ROBOTS = sorted(registry.robots())
PLANNERS = sorted(registry.planners())


def test_the_example_package_is_registered_through_its_entry_points():
    """examples/planar3r is installed (README's test command) and found like any outside package."""
    assert "planar3r" in ROBOTS and "dls_line" in PLANNERS
    assert registry.origin("robot", "planar3r").startswith("entry point simbench_planar3r.robot:ROBOT")
    assert registry.origin("robot", "puma600") == "simbench" and registry.broken("robot") == {}


@pytest.mark.parametrize("name", ROBOTS)
def test_the_scene_steps_under_random_controls_with_no_warning(name):
    robot = registry.robots()[name]
    model = compiled_scene(str(robot.scene))
    data = mujoco.MjData(model)
    mid = (np.maximum(robot.lower, -np.pi) + np.minimum(robot.upper, np.pi)) / 2  # joints without limits: 0
    data.qpos[:] = Plant.load(robot).initial_qpos(mid)
    rng = np.random.default_rng(0)
    lo, hi = model.actuator_ctrlrange.T
    for _ in range(20):
        data.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_step(model, data, nstep=50)
    assert all(w.number == 0 for w in data.warning), [mujoco.mjtWarning(i).name for i, w in enumerate(data.warning)
                                                      if w.number]
    assert np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()
    assert [model.actuator(n).name for n in robot.joints] == list(robot.joints)  # actuators named after joints


@pytest.mark.parametrize("name", [n for n in ROBOTS if registry.robots()[n].has_fk])
def test_fk_is_mujocos_tool_site(name):
    """At 30 random joint values inside the ranges (passive joints assembled), to a micrometre."""
    robot = registry.robots()[name]
    plant = Plant.load(robot)
    model, data = plant.model, mujoco.MjData(plant.model)
    rng = np.random.default_rng(1)
    lo, hi = np.maximum(robot.lower, -np.pi), np.minimum(robot.upper, np.pi)
    q = rng.uniform(lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo), size=(30, robot.dof))
    expected = robot.fk(q)
    for qi, xi in zip(q, expected):
        data.qpos[:] = plant.initial_qpos(qi)
        mujoco.mj_forward(model, data)
        assert np.linalg.norm(data.site(robot.tool_site).xpos - xi) < 1e-6


def _joint_move(robot, seed: int = 0) -> dict:
    """A short joint move between two random configurations well inside the ranges (10 % of each range)."""
    rng = np.random.default_rng(seed)
    lo, hi = np.maximum(robot.lower, -np.pi), np.minimum(robot.upper, np.pi)
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    start, goal = (mid + rng.uniform(-0.1, 0.1, robot.dof) * half for _ in range(2))
    return {"robot": robot.name, "planner": "joint_move", "task": {"start": start.tolist(), "goal": goal.tolist()},
            "timing": {"duration": 0.5, "hold": 0.1}}


@pytest.mark.parametrize("name", ROBOTS)
def test_joint_move_runs_deterministically_or_is_refused_by_name(name, tmp_path, capsys):
    """The one planner for any robot: on a robot with fk it runs, twice the same; on one without it is refused
    at validation with one line naming the planner (never a run that ends in an internal error)."""
    robot = registry.robots()[name]
    doc = _joint_move(robot)
    if not robot.has_fk:
        path = tmp_path / "s.yaml"
        path.write_text(yaml.safe_dump(doc))
        assert main(["validate", str(path)]) == 2
        err = capsys.readouterr().err.splitlines()
        assert len(err) == 1 and ": planner: 'joint_move' needs the robot's forward kinematics" in err[0], err
        return
    first, second = (pipeline.evaluate(parse_scenario(doc, "test")) for _ in range(2))
    assert np.array_equal(first.recording.qpos, second.recording.qpos)
    assert np.array_equal(first.recording.ctrl, second.recording.ctrl)
    # the tool's planned path is the robot's fk of the planned joints, and the physics tracks it
    assert np.allclose(first.trajectory.tool_ref, robot.fk(first.trajectory.q_ref))
    assert first.analysis.tracking["tool_max"] < 0.01


@pytest.mark.parametrize("planner", PLANNERS)
@pytest.mark.parametrize("robot", ROBOTS)
def test_every_pair_is_refused_at_validation_or_supported(robot, planner):
    """A planner written for other robots is refused naming them; the pairs the registry accepts are the
    planner's own robots, or any robot with what it needs."""
    r, p = registry.robots()[robot], registry.planners()[planner]
    doc = {"robot": robot, "planner": planner, "task": {}, "timing": {"duration": 1.0}}
    refusal = p.refuses(r)
    try:
        parse_scenario(doc, "test")
    except ScenarioError as err:
        if refusal:
            assert err.field == "planner" and err.message == refusal
            return
        assert err.field.startswith("task"), err  # a supported pair: only the empty task is wrong
        return
    pytest.fail(f"{robot} x {planner}: an empty task was accepted")


def test_a_wrong_plugin_is_refused_with_what_is_wrong():
    with pytest.raises(RegistryError, match="expected a simbench.api.Robot instance"):
        registry.register_robot("puma600")  # type: ignore[arg-type]
    with pytest.raises(RegistryError, match="already registered"):
        registry.register_robot(type(registry.robots()["puma600"])())
    with pytest.raises(RegistryError, match="qd_max has 2 items, one per joint expected"):
        type("Bad", (api.Robot,), {"measures": lambda s, r: {}, "singular_sets": lambda s, r, t: []})(
            name="bad", description="", scene="x.xml", joints=("a", "b", "c"), kinds=("revolute",) * 3,
            lower=[-1] * 3, upper=[1] * 3, qd_max=[1, 1], tool_site="t", tool_sensor="t")


def test_a_broken_entry_point_is_named_and_does_not_block_the_others(monkeypatch):
    """An installed package whose entry point fails to import: the other robots load, and a scenario naming
    it is told why."""
    fake = importlib.metadata.EntryPoint(name="ghost", value="no_such_module:ROBOT", group="simbench.robots")
    robots = registry._Registry("simbench.robots", api.Robot)
    monkeypatch.setattr(registry, "_ROBOTS", robots)
    monkeypatch.setitem(registry._REGISTRIES, "robot", robots)
    real = importlib.metadata.entry_points
    monkeypatch.setattr(importlib.metadata, "entry_points",
                        lambda group: [fake] if group == "simbench.robots" else real(group=group))
    assert registry.robots() == {} and "ModuleNotFoundError" in registry.broken("robot")["ghost"]
    with pytest.raises(ScenarioError, match="entry point no_such_module:ROBOT .* cannot be used"):
        parse_scenario({"robot": "ghost", "planner": "joint_move"}, "test")
