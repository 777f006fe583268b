"""simbench.env: every shipped scenario as a dm_control environment, held to dm_env's own contract test, and its
episodes against `simulate` (the servo or computed torque as the policy reproduce it), against `simbench.run`
(the same report and timeseries), and driven by a policy from an outside package."""

from __future__ import annotations

import functools
import json
import re
import unittest

import dm_env
import numpy as np
import pytest
import yaml
from dm_control.rl import control
from dm_control.utils import rewards
from dm_env import test_utils
from simbench_planar3r import control as planar3r_control

import simbench
from simbench import env as simbench_env
from simbench.api import State
from simbench.commands import pipeline
from simbench.physics.computed_torque import ComputedTorque
from simbench.physics.controllers import Servo
from simbench.physics.policy import make
from simbench.physics.sim import simulate
from simbench.scenario import parse_scenario
from tests.conftest import SHIPPED, scenario_file

PLANAR3R = planar3r_control.__file__.rsplit("/", 1)[0] + "/scenarios"
SERIAL = [task for task in simbench_env.ALL_TASKS if task[0] != "rsmg"]
RSMG = [task for task in simbench_env.ALL_TASKS if task[0] == "rsmg"]
SHORT = {"duration": 0.05, "hold": 0.0}  # 50 steps: episodes that end within the contract test's sequence


def shortened(robot: str, name: str, **timing) -> simbench.Scenario | None:
    """A shipped scenario with its timing changed and a 10 ms settle; None if its planner cannot plan it so (the
    Agile Eye's avoidance windows, the RSMG's tumble)."""
    raw = yaml.safe_load(scenario_file(robot, name).read_text())
    raw["timing"].update(timing)
    raw.setdefault("sim", {})["settle"] = 0.01
    try:
        scenario = parse_scenario(raw, f"{robot}/{name}", default_name=name)
        scenario.planner_def.plan(scenario, scenario.robot_def, scenario.sim.timestep or 0.001)
    except (simbench.ScenarioError, simbench.RunError):
        return None
    return scenario


@functools.cache
def environment(robot: str, name: str, short: bool = False, actuation: str = "position"):
    """The environment of a shipped scenario, shortened (SHORT) where its planner can plan it so, made once: its
    plan is made when it is loaded."""
    scenario = shortened(robot, name, **SHORT) if short else None
    if short and scenario is None:
        return environment(robot, name, False, actuation)
    return simbench_env.load(scenario or simbench.load_scenario(scenario_file(robot, name)), actuation=actuation)


def fresh(env) -> control.Environment:
    """A new Environment (never reset nor stepped) over the physics and task of `env`: its plan is not made
    again."""
    return control.Environment(env.physics, env.task)


def servo_policy(env):
    """The servo as a policy: simbench.env.servo_policy, the position targets `simulate` commands (Servo.targets)
    for the references the observation shows (revised where the plan's feedback revised them)."""
    return simbench_env.servo_policy(env)


def episode(env, policy) -> tuple[int, list[float]]:
    """Reset, then step with policy(observation) to the episode's end: the steps taken and the rewards."""
    step, rewards_ = env.reset(), []
    while not step.last():
        step = env.step(policy(step.observation))
        rewards_.append(step.reward)
    return len(rewards_), rewards_


# --- dm_env's contract, over every shipped scenario ------------------------------------------------------------

def _contract(robot: str, name: str):
    """dm_env.test_utils.EnvironmentTestMixin over the scenario's environment (shortened where its planner can:
    its sequence then passes the episode's end twice), the servo's actions as the action sequence."""

    class Contract(test_utils.EnvironmentTestMixin, unittest.TestCase):
        def make_object_under_test(self):
            return fresh(environment(robot, name, short=True))

        def make_action_sequence(self):
            env = self.environment
            servo = Servo.from_scenario(env.task.scenario)
            servo.bind(env.task.plant, env.task.plan)
            for _ in range(120):
                k = env.task.k
                yield servo.targets(env.task.q_ref[k][None], env.task.qd_ref[k][None])[0, env.task.plant.actuators]

    Contract.__name__ = Contract.__qualname__ = f"TestContract_{robot}_{name}"
    return Contract


for _robot, _name in simbench_env.ALL_TASKS:
    globals()[f"TestContract_{_robot}_{_name}"] = _contract(_robot, _name)


class TestContractTorque(test_utils.EnvironmentTestMixin, unittest.TestCase):
    """The contract under torque actuation, dm_env's own test actions (every joint at its least torque)."""

    def make_object_under_test(self):
        return fresh(environment("puma600", "weld_seam", short=True, actuation="torque"))

    def make_action_sequence(self):
        for _ in range(120):
            yield self.make_action()


def test_all_tasks_are_the_shipped_scenarios():
    assert sorted(simbench_env.ALL_TASKS) == sorted((p.parent.name, p.stem) for p in SHIPPED)
    env = simbench_env.load_task("spherical_arm", "case1_joint_move")
    assert env.task.scenario.name == "case1_joint_move"


# --- equivalence with simulate ---------------------------------------------------------------------------------

@pytest.mark.parametrize("robot, name", SERIAL, ids=[f"{r}/{n}" for r, n in SERIAL])
def test_the_servo_as_a_policy_reproduces_simulate(robot, name):
    """The servo's commands as actions give simulate's run of the same plan bit for bit (every joint, the tool
    and the actuator forces; the first step after reset too), in an episode of exactly len(t) - 1 steps."""
    env = environment(robot, name)
    task = env.task
    steps, _ = episode(env, servo_policy(env))
    rec = simbench_env.recording(env)
    expected = simulate(task.plant, task.plan, Servo.from_scenario(task.scenario), settle=task.scenario.sim.settle)
    assert steps == task.plan.t.size - 1 == rec.t.size - 1
    for key in ("q", "qd", "tool", "force"):
        assert np.array_equal(getattr(rec, key), getattr(expected, key)), key


@pytest.mark.parametrize("name", [n for _, n in RSMG])
def test_the_servo_as_a_policy_reproduces_simulate_on_the_rsmg(name):
    """On the RSMG the welds switch at the same steps, the grip feedback revises the references the same way,
    and the joints and the rotor are simulate's bit for bit."""
    env = environment("rsmg", name)
    task = env.task
    steps, _ = episode(env, servo_policy(env))
    rec = simbench_env.recording(env)
    expected = simulate(task.plant, task.plan, Servo.from_scenario(task.scenario), settle=task.scenario.sim.settle)
    assert steps == task.plan.t.size - 1
    assert len(task.plan.switches) > 10 and rec.eq_active.keys() == expected.eq_active.keys()
    for grip, active in rec.eq_active.items():
        assert np.array_equal(active, expected.eq_active[grip]), grip
    assert rec.q_ref is not None and np.array_equal(rec.q_ref, expected.q_ref)
    assert np.array_equal(rec.sensors["rotor_quat"], expected.sensors["rotor_quat"])
    assert np.array_equal(rec.q, expected.q)


def test_torque_actuation_settles_and_steps_as_simulate_does_with_computed_torque():
    """Under torque actuation the episode starts as simulate settles computed_torque, so the controller as a
    policy (its commands from the observed state) reproduces simulate's computed_torque run."""
    env = environment("puma600", "weld_seam", actuation="torque")
    task, data = env.task, env.physics.data.ptr
    controller = ComputedTorque()
    controller.bind(task.plant, task.plan)

    def policy(obs):
        state = State(k=task.k, t=float(obs["time"][0]), q=obs["q"], qd=obs["qd"], qpos=data.qpos,
                      qvel=data.qvel, data=data)
        return controller.commands(state)[task.plant.actuators]

    episode(env, policy)
    expected = simulate(task.plant, task.plan, ComputedTorque(), settle=task.scenario.sim.settle)
    assert np.abs(simbench_env.recording(env).q - expected.q).max() <= 1e-9


# --- an episode's steps, specs and reward ----------------------------------------------------------------------

def test_specs_describe_the_actions_and_observations():
    """One action per joint bounded by its joint's range within its actuator's control range (a joint with none:
    the plan's span +- pi), and every observation of an episode of the spec's shapes, float64 and finite."""
    env = environment("spherical_arm", "case1", short=True)
    model, act = env.physics.model.ptr, env.task.plant.actuators
    spec = env.action_spec()
    assert spec.shape == (4,) and spec.dtype == np.float64
    for i, a in enumerate(act):
        j = model.actuator_trnid[a, 0]
        if model.jnt_limited[j]:
            lo, hi = model.jnt_range[j]
            if model.actuator_ctrllimited[a]:
                lo, hi = max(lo, model.actuator_ctrlrange[a, 0]), min(hi, model.actuator_ctrlrange[a, 1])
        else:
            lo, hi = env.task.plan.q_ref[:, i].min() - np.pi, env.task.plan.q_ref[:, i].max() + np.pi
        assert (spec.minimum[i], spec.maximum[i]) == (lo, hi)
    assert not model.jnt_limited[model.actuator_trnid[act[0], 0]] and model.jnt_limited[model.actuator_trnid[act[1], 0]]
    obs_spec = env.observation_spec()
    assert list(obs_spec) == ["time", "q", "qd", "tool", "q_ref", "qd_ref", "tool_ref", "q_ref_ahead"]
    assert obs_spec["q_ref_ahead"].shape == (12,)
    step, policy = env.reset(), servo_policy(env)
    while not step.last():
        for key, value in step.observation.items():
            obs_spec[key].validate(value)
            assert np.isfinite(value).all(), key
        step = env.step(policy(step.observation))
    flat = simbench_env.load(env.task.scenario, flat_observation=True)
    assert flat.reset().observation["observations"].shape == (sum(s.shape[0] for s in obs_spec.values()),)


def test_episodes_are_deterministic():
    """Two resets and the same (random, within the spec) actions give the same observations and rewards, bit for
    bit; the episode ends with discount 1 after len(t) - 1 steps, and the next step starts a new one."""
    env = environment("puma600", "line", short=True)
    spec = env.action_spec()
    actions = np.random.default_rng(5).uniform(spec.minimum, spec.maximum, (env.task.n - 1, spec.shape[0]))
    runs = []
    for _ in range(2):
        steps = [env.reset()]
        for action in actions:
            steps.append(env.step(action))
        runs.append(steps)
    assert [s.step_type for s in runs[0]] == [dm_env.StepType.FIRST] + [dm_env.StepType.MID] * (len(actions) - 1) \
        + [dm_env.StepType.LAST]
    assert runs[0][-1].discount == 1.0
    for a, b in zip(*runs):
        assert a.reward == b.reward
        for key in a.observation:
            assert np.array_equal(a.observation[key], b.observation[key]), key
    assert env.step(actions[0]).first()


def test_the_reward_is_one_on_the_reference_and_falls_off_it():
    """The reward is dm_control's tolerance of the tool's error (1 at none, 0.5 at the path tolerance), in [0, 1];
    the servo's episode earns more than one that holds the start."""
    env = environment("spherical_arm", "case1", short=True)
    task, physics = env.task, env.physics
    data, tol = physics.data.ptr, task.scenario.analysis.path_tolerance
    _, served = episode(env, servo_policy(env))
    _, held = episode(env, lambda obs: task.plan.q_ref[0])
    assert all(0 <= r <= 1 for r in served + held)
    assert np.mean(served) > np.mean(held) and min(held) < 0.9
    tool = task.plant.sensors[task.plant.robot.tool_sensor]
    for offset, expected in ((0.0, 1.0), (tol, 0.5), (3 * tol, 0.5 ** 9)):
        data.sensordata[tool] = task.plan.tool_ref[task.k] + [0.0, offset, 0.0]
        reward = task.get_reward(physics)
        assert reward == pytest.approx(expected, rel=1e-12)
        assert reward == pytest.approx(rewards.tolerance(offset, bounds=(0, 0), margin=tol, sigmoid="gaussian",
                                                         value_at_margin=0.5), rel=1e-12)


def test_wrong_actions_and_calls_are_refused_in_one_line():
    env = environment("spherical_arm", "case1", short=True)
    env.reset()
    with pytest.raises(ValueError, match=r"one value per joint \(q1, q2, q3, q4\): shape \(4,\) expected, got \(3,\)"):
        env.step(np.zeros(3))
    with pytest.raises(ValueError, match="the action for joint 'q3' is nan"):
        env.step([0.0, 0.1, np.nan, 0.1])
    with pytest.raises(RuntimeError, match="the episode has taken no step since its reset"):
        simbench_env.evaluation(env)
    with pytest.raises(TypeError, match="expected an environment of simbench.env.load"):
        simbench_env.recording(object())
    with pytest.raises(ValueError, match="no shipped scenario spherical_arm/nope"):
        simbench_env.load_task("spherical_arm", "nope")
    with pytest.raises(ValueError, match="actuation must be 'position' or 'torque'"):
        simbench_env.load(env.task.scenario, actuation="velocity")


@pytest.mark.parametrize("kwargs", [{"n_sub_steps": 0}, {"n_sub_steps": -2}])
def test_a_control_step_of_no_physics_step_is_refused(kwargs):
    """A control step of no physics steps would never reach the episode's end (a policy loop until LAST hangs):
    refused in one line when the environment is made (dm_control refuses a control_timestep of 0 itself)."""
    with pytest.raises(ValueError, match="a control step must be at least one physics step"):
        simbench_env.load_task("spherical_arm", "case1", environment_kwargs=kwargs)


@pytest.mark.parametrize("random", [np.random.default_rng(0), "7", 2.5, True])
def test_a_random_that_is_neither_a_seed_nor_a_randomstate_is_refused_in_one_line(random):
    """task_kwargs' random is dm_control's: an int seed or a numpy.random.RandomState; a Generator (Gymnasium's
    kind), a string, a float or a bool is refused naming what it got, not deep in NumPy."""
    with pytest.raises(TypeError, match=rf"random must be a seed \(an int\) or a numpy.random.RandomState, got "
                                        rf"{type(random).__name__}"):
        simbench_env.load_task("spherical_arm", "case1", task_kwargs={"random": random})


def test_diverging_physics_ends_the_episode_with_the_time_and_the_joint():
    """Torques far beyond what the arm takes, its force limits lifted (the spec then bounds nothing: refused):
    the first step ends the episode (LAST, discount 0, reward 0), saying when and which joint, as simbench says
    it of a run; the recording holds the sound rows and the observation the last sound state; with no sound step,
    the evaluation is refused saying so and why."""
    raw = yaml.safe_load(scenario_file("spherical_arm", "case1").read_text())
    raw["timing"].update(SHORT)
    raw.setdefault("sim", {})["force_limits"] = False
    scenario = parse_scenario(raw, "spherical_arm/case1", default_name="case1")
    with pytest.raises(ValueError, match="no force limits"):
        simbench_env.load(scenario, actuation="torque")
    env = simbench_env.load(scenario)  # position targets far beyond the range, gains raised: the same divergence
    model = env.physics.model.ptr
    model.actuator_gainprm[env.task.plant.actuators, 0] *= 1e6
    model.actuator_biasprm[env.task.plant.actuators, 1] *= 1e6
    start = env.reset()
    step = env.step(np.full(4, 1e3))
    assert step.last() and step.discount == 0.0 and step.reward == 0.0
    assert np.array_equal(step.observation["q"], start.observation["q"])
    assert re.fullmatch(r"the physics failed at t = 0\.0010 s: .* DOF 0 \(joint 'q1'\).*", env.task.failure)
    rec = simbench_env.recording(env)
    assert rec.t.size == 1 and np.isfinite(rec.q).all()
    with pytest.raises(RuntimeError, match=r"nothing to evaluate: the episode's first step failed \(the physics "
                                           r"failed at t = 0\.0010 s: .*joint 'q1'"):
        simbench_env.evaluation(env)
    assert env.step(np.zeros(4)).first()


# --- an episode as a run ----------------------------------------------------------------------------------------

def no_plots(monkeypatch) -> None:
    """Skip the matplotlib plots (about a second a run): what these tests compare is the analysis."""
    monkeypatch.setattr(pipeline, "write_plots", lambda *args: [])


def test_an_outside_policy_tracks_through_the_environment(tmp_path, monkeypatch):
    """The example package's policy (the factory its scenario names) drives the environment on torques, tracks
    the line to a quarter of a millimetre, and its tool error is the one `simbench.run` reports to 0.1 % (the run
    settles with the policy itself, the environment with computed torque: at rest at the start, both hold it)."""
    no_plots(monkeypatch)
    scenario = simbench.load_scenario(f"{PLANAR3R}/line_policy.yaml")
    env = simbench_env.load(scenario, actuation="torque")
    episode(env, make(scenario.control.policy, scenario))
    tracking = simbench_env.evaluation(env, {"policy": scenario.control.policy}).analysis.tracking
    report = simbench.run(scenario, out=tmp_path / "run", video=False).report
    assert report["status"] == "ok" and report["control"]["controller"] == "policy"
    assert tracking["tool_error_max"] < 1e-3
    assert tracking["tool_error_max"] == pytest.approx(report["tracking"]["tool_error_max"], rel=1e-3)
    assert tracking["tool_rms"] == pytest.approx(report["tracking"]["tool_rms"], rel=1e-3)


def test_a_derived_arms_episode_reports_the_servos_designed_for_it(tmp_path, monkeypatch):
    """The Jaco (its MJCF as dm-control ships it, no actuator of its own): an episode written out says what servos
    simbench designed for the plan (derived_arm.servos, control.servo_design), as `simbench.run`'s report of the
    same scenario does, the same gains (it said none)."""
    from tests.planners.test_cartesian_path import TOOL0, _scenario

    no_plots(monkeypatch)
    path = _scenario(tmp_path, TOOL0 + [0.0, 100.0, 0.0], duration=1.0)
    env = simbench_env.load(str(path))
    episode(env, servo_policy(env))
    mine = simbench_env.write_outputs(env, tmp_path / "env", video=False)
    theirs = simbench.run(str(path), out=tmp_path / "run", video=False)
    a, b = (json.loads((r.out / "report.json").read_text()) for r in (mine, theirs))
    assert len(b["control"]["servo_design"]) == 6 and b["derived_arm"]["servos"] == b["control"]["servo_design"]
    assert a["control"]["servo_design"] == b["control"]["servo_design"]
    assert a["derived_arm"]["servos"] == b["derived_arm"]["servos"]


def test_an_episode_written_out_is_the_run_simbench_writes(tmp_path, monkeypatch):
    """The servo's episode written by write_outputs: the same report (status, tracking, events, plan) and the
    same timeseries as `simbench.run` of the scenario, but for the controller's name and the last row's command
    (a closed loop repeats the one before; the servo has its own)."""
    no_plots(monkeypatch)
    scenario = shortened("spherical_arm", "case1", duration=1.5, hold=0.2)
    env = simbench_env.load(scenario)
    episode(env, servo_policy(env))
    mine = simbench_env.write_outputs(env, tmp_path / "env", video=False, control_info={"policy": "servo"})
    theirs = simbench.run(scenario, out=tmp_path / "run", video=False)
    a, b = (json.loads((r.out / "report.json").read_text()) for r in (mine, theirs))
    assert a["control"] == {"controller": "simbench.env", "actuation": "position", "policy": "servo"}
    assert a["outputs"] == b["outputs"] and a["status"] == b["status"] == "ok"
    for key in ("tracking", "singularity_events", "limit_events", "violations", "samples", "plan", "warnings"):
        assert a[key] == b[key], key  # the physics is the same to the last bit
    with np.load(mine.out / "timeseries.npz") as x, np.load(theirs.out / "timeseries.npz") as y:
        assert set(x.files) == set(y.files)
        for key in x.files:
            if x[key].dtype.kind in "fb":
                left, right = (x[key][:-1], y[key][:-1]) if key == "ctrl" else (x[key], y[key])
                assert np.allclose(left, right, rtol=0, atol=1e-9, equal_nan=True), key
            else:
                assert np.array_equal(x[key], y[key]), key
