"""simbench.env as an RL researcher trains on it: bounded actions that random policies may take on every task,
action repeat and time limits as dm_control's suite.load takes them, episodes cut short and evaluated, exact
snapshots, the servo as a public policy, and seeded random tasks."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from dm_control.rl import control

import simbench
from simbench import env as simbench_env
from simbench.physics.controllers import Servo
from simbench.physics.sim import simulate

TASKS = simbench_env.ALL_TASKS


@functools.cache
def environment(robot: str, name: str, actuation: str = "position", **env_kwargs):
    return simbench_env.load_task(robot, name, environment_kwargs=env_kwargs or None, actuation=actuation)


def run(env, policy) -> list:
    """Reset, then step with policy(timestep) to the episode's end: every TimeStep."""
    steps = [env.reset()]
    while not steps[-1].last():
        steps.append(env.step(policy(steps[-1])))
    return steps


def uniform(env, seed: int):
    spec, rng = env.action_spec(), np.random.default_rng(seed)
    return lambda _: rng.uniform(spec.minimum, spec.maximum)


# --- bounded actions -------------------------------------------------------------------------------------------

@pytest.mark.parametrize("actuation", ["position", "torque"])
@pytest.mark.parametrize("robot, name", TASKS, ids=[f"{r}/{n}" for r, n in TASKS])
def test_uniform_random_actions_within_the_spec_run_a_whole_episode(robot, name, actuation):
    """Every bound finite, within MuJoCo's joint range (limited joints) and force range (torque); uniform random
    actions raise nothing and the episode ends (LAST) at the plan's end or where the physics failed (discount 0),
    and is evaluated: `failed` exactly where the physics failed, else `ok` or `limits`."""
    env = environment(robot, name, actuation)
    model, plant = env.physics.model.ptr, env.task.plant
    spec = env.action_spec()
    assert np.isfinite(spec.minimum).all() and np.isfinite(spec.maximum).all() and (spec.minimum < spec.maximum).all()
    jnt = model.actuator_trnid[plant.actuators, 0]
    if actuation == "position":
        limited = model.jnt_limited[jnt].astype(bool)
        assert (spec.minimum[limited] >= model.jnt_range[jnt[limited], 0]).all()
        assert (spec.maximum[limited] <= model.jnt_range[jnt[limited], 1]).all()
    else:
        bound = np.abs(model.actuator_forcerange[plant.actuators]).min(axis=1)
        forced = model.actuator_forcelimited[plant.actuators].astype(bool)
        assert (np.abs(spec.minimum[forced]) <= bound[forced]).all() and (spec.maximum[forced] <= bound[forced]).all()
    steps = run(env, uniform(env, 7))
    assert steps[-1].last() and all(not s.last() for s in steps[:-1])
    status = simbench_env.evaluation(env).verdict.status
    if env.task.failure is None:
        assert env.task.k == env.task.n - 1 and steps[-1].discount == 1.0 and status in ("ok", "limits")
    else:
        assert steps[-1].discount == 0.0 and status == "failed"
    assert all(np.isfinite(v).all() for v in steps[-1].observation.values())


# --- action repeat and time limits -----------------------------------------------------------------------------

def test_the_servo_tracks_the_weld_seam_at_a_fifth_of_the_steps():
    """control_timestep 0.005 s (five 1 ms physics steps an action): the servo policy's episode takes a fifth
    of the steps, records every physics step (the plan's samples) and is `ok`; physics.time() is the plan's
    time, the settle excluded."""
    env = environment("puma600", "weld_seam", control_timestep=0.005)
    task = env.task
    steps = run(env, simbench_env.servo_policy(env))
    assert len(steps) - 1 == int(np.ceil((task.n - 1) / 5)) and env.control_timestep() == pytest.approx(0.005)
    assert env.physics.time() == pytest.approx(task.plan.t[-1], abs=1e-9)
    assert steps[-1].observation["time"][0] == pytest.approx(task.plan.t[-1])
    rec = simbench_env.recording(env)
    assert np.array_equal(rec.t, task.plan.t)
    assert np.array_equal(rec.ctrl[5:10], np.repeat(rec.ctrl[5:6], 5, axis=0))  # the action held 5 steps
    assert simbench_env.evaluation(env).verdict.status == "ok"


def test_a_time_limit_truncates_the_episode_and_its_evaluation_is_never_ok():
    """time_limit 1 s with n_sub_steps 2: 500 control steps, 1000 physics steps recorded, discount 1 (a
    truncation), and the evaluation of what ran `truncated` though the servo tracks it well."""
    env = simbench_env.load_task("puma600", "line", environment_kwargs={"time_limit": 1.0, "n_sub_steps": 2})
    steps = run(env, simbench_env.servo_policy(env))
    assert len(steps) - 1 == 500 and steps[-1].discount == 1.0 and env.task.k == 1000
    assert simbench_env.recording(env).t[-1] == pytest.approx(1.0)
    ev = simbench_env.evaluation(env)
    assert ev.verdict.status == "truncated" and ev.verdict.violations[0].kind == "truncated"
    assert ev.recording.t.size == ev.trajectory.t.size == 1001


# --- snapshots -------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("robot, name, k", [("puma600", "weld_seam", 300), ("rsmg", "three_turns", 2990)])
def test_a_snapshot_replays_bit_for_bit(robot, name, k):
    """Run k steps, snapshot, run m recording the observations and rewards, restore, run the same m actions:
    identical bytes (on the RSMG across its weld switches, the grip feedback revising the references)."""
    env = environment(robot, name)
    policy, m = simbench_env.servo_policy(env), 600
    noise = np.random.default_rng(1).normal(0, 1e-3, (m, env.action_spec().shape[0]))
    step = env.reset()
    for _ in range(k):
        step = env.step(policy(step))
    snap = simbench_env.snapshot(env)
    actions = []

    def rollout(actions_in=None):
        out, s = [], step
        for i in range(m):
            a = policy(s) + noise[i] if actions_in is None else actions_in[i]
            actions.append(a) if actions_in is None else None
            s = env.step(a)
            out.append((s.reward, s.discount, {key: v.tobytes() for key, v in s.observation.items()}))
        return out, simbench_env.recording(env)

    first, rec1 = rollout()
    simbench_env.restore(env, snap)
    second, rec2 = rollout(actions)
    assert first == second
    for field in ("q", "qd", "tool", "ctrl", "t"):
        assert getattr(rec1, field).tobytes() == getattr(rec2, field).tobytes(), field


# --- the servo as a public policy ------------------------------------------------------------------------------

def test_the_servo_policy_reproduces_simulate_on_a_flat_observation():
    """With flat observations the policy reads the task's public references: simulate()'s run, exactly."""
    scenario = simbench.load_scenario(simbench.core.resources.scenarios_dir() / "spherical_arm" / "case1.yaml")
    env = simbench_env.load(scenario, environment_kwargs={"flat_observation": True})
    run(env, simbench_env.servo_policy(env))
    task = env.task
    expected = simulate(task.plant, task.plan, Servo.from_scenario(scenario), settle=scenario.sim.settle)
    assert np.array_equal(simbench_env.recording(env).q, expected.q)


# --- random tasks ----------------------------------------------------------------------------------------------

def starts(env, resets: int = 3) -> list[np.ndarray]:
    out = []
    for _ in range(resets):
        step = env.reset()
        out.append(np.concatenate([step.observation["q"], env.task.plan.q_ref[-1]]))
    return out


@pytest.mark.parametrize("robot, name", [("spherical_arm", "case1"), ("spherical_arm", "case1_joint_move")])
def test_seeded_random_tasks_are_deterministic_and_differ_by_seed(robot, name):
    """task_kwargs={'random': seed}, a planner that draws no random tasks (Planner.random_task not overridden):
    each reset a new joint move, its start and goal within the action bounds
    (the settled start within 1e-3 of the plan's), the same for the same seed (also a RandomState), different for
    another; the episode runs to its end under the servo."""
    def make(random):
        return simbench_env.load_task(robot, name, task_kwargs={"random": random})

    env = make(3)
    a, b, c = starts(env), starts(make(np.random.RandomState(3))), starts(make(4))
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not np.allclose(a[0], c[0]) and not np.allclose(a[0], a[1])
    lo, hi = env.task.bounds
    for x in a:
        q, goal = np.split(x, 2)
        assert (lo <= goal).all() and (goal <= hi).all()
    assert env.task.scenario.planner == "joint_move"
    steps = run(env, simbench_env.servo_policy(env))
    assert steps[-1].discount == 1.0 and env.task.k == env.task.n - 1


def plans(env, resets: int) -> list[tuple[np.ndarray, np.ndarray]]:
    out = []
    for _ in range(resets):
        env.reset()
        out.append((env.task.plan.t, env.task.plan.q_ref))
    return out


def same(a, b) -> bool:
    return a[0].shape == b[0].shape and np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


@pytest.mark.parametrize("robot, name, planner", [("agile_eye", "avoidance", "avoidance_4567"),
                                                  ("rsmg", "three_turns", "round_robin"),
                                                  ("puma600", "line", "decoupled_path")])
def test_the_scenario_planners_random_tasks_are_deterministic_and_differ_by_seed(robot, name, planner):
    """A planner that draws random tasks (Planner.random_task) gives the resets' tasks, planned by it: two resets
    with seed 1 plan the same as a fresh environment's two with seed 1, differ from each other and from seed 2's."""
    def make(seed):
        return simbench_env.load_task(robot, name, task_kwargs={"random": seed})

    env = make(1)
    a, b, c = plans(env, 2), plans(make(1), 2), plans(make(2), 1)
    assert env.task.scenario.planner == planner
    assert same(a[0], b[0]) and same(a[1], b[1])
    assert not same(a[0], a[1]) and not same(a[0], c[0])


def test_an_agile_eye_random_task_has_obstacles_its_plan_clears():
    """The Agile Eye's random tasks (start, goal, 1 or 2 obstacles): over three resets, both counts of obstacles;
    the planned platform orientation (by scipy's Rotation) starts at the task's start, ends at its goal and stays
    beyond every obstacle's radius (and its clearance) from the obstacle's centre."""
    from scipy.spatial.transform import Rotation

    env = simbench_env.load_task("agile_eye", "avoidance", task_kwargs={"random": 5})
    counts = set()
    for _ in range(3):
        env.reset()
        task = env.task.scenario.task
        counts.add(len(task.obstacles))
        platform = Rotation.from_quat(env.task.plan.series["platform_quat_ref"], scalar_first=True)
        start, goal = (Rotation.from_matrix(end.matrix()) for end in (task.start, task.goal))
        assert (start.inv() * platform[0]).magnitude() < 1e-6 and (goal.inv() * platform[-1]).magnitude() < 1e-6
        for obstacle in task.obstacles:
            away = (Rotation.from_matrix(obstacle.center.matrix()).inv() * platform).magnitude()
            assert away.min() > obstacle.radius + task.obstacle_clearance - 1e-3
    assert counts == {1, 2}


def test_an_rsmg_random_episode_runs_under_the_servo():
    """The RSMG's random tasks (rotor motions with general contacts): 300 steps of a random episode under the
    servo policy raise nothing and the physics stays sound; with the planner's hook gone, the RSMG (no forward
    kinematics of its joints, so no joint moves) is refused in one line."""
    env = simbench_env.load_task("rsmg", "three_turns", task_kwargs={"random": 3})
    policy, step = simbench_env.servo_policy(env), env.reset()
    assert env.task.scenario.task.contacts == "general" and env.task.n > 300
    for _ in range(300):
        step = env.step(policy(step))
    assert env.task.failure is None and not step.last()
    assert all(np.isfinite(v).all() for v in step.observation.values())


def test_a_robot_with_neither_random_tasks_nor_joint_moves_is_refused(monkeypatch):
    from simbench.planners.round_robin import RoundRobin

    monkeypatch.setattr(RoundRobin, "random_task", lambda self, robot, random: None)
    with pytest.raises(ValueError, match="no random tasks for the rsmg: its planner 'round_robin' draws none"):
        simbench_env.load_task("rsmg", "three_turns", task_kwargs={"random": 1})


def test_the_benchmarks_draw_their_tasks_from_simbench():
    """The benchmarks whose generators moved into simbench draw the same tasks as those generators."""
    from benchmarks import bench_agile_eye_planning, bench_rsmg_contacts
    from simbench.planners.random_tasks import agile_eye_tasks
    from simbench.planners.rsmg_contacts import random_motions

    assert bench_agile_eye_planning.tasks(2) == agile_eye_tasks(2, bench_agile_eye_planning.SEED)
    assert bench_rsmg_contacts.random_motions is random_motions


def test_a_task_subclass_brings_its_own_reward():
    class Still(simbench_env.Track):
        def get_reward(self, physics):
            return -float(np.abs(physics.data.qvel).sum())

    env = simbench_env.load_task("puma600", "line", task_kwargs={"task": Still})
    env.reset()
    step = env.step(env.task.plan.q_ref[0])
    assert step.reward == -np.abs(env.physics.data.qvel).sum()
    with pytest.raises(TypeError, match="subclass of simbench.env.Track"):
        simbench_env.load_task("puma600", "line", task_kwargs={"task": control.Task})


def test_an_episode_the_physics_ended_is_evaluated_failed():
    """Ten sound steps, then gains raised a millionfold, force limits lifted and a target far off: the episode
    ends at step 11
    (discount 0), and the evaluation analyses the ten steps that ran, status `failed`, the failure first."""
    env = simbench_env.load_task("spherical_arm", "case1")
    policy, step = simbench_env.servo_policy(env), env.reset()
    for _ in range(10):
        step = env.step(policy(step))
    act = env.task.plant.actuators
    env.physics.model.ptr.actuator_gainprm[act, 0] *= 1e6
    env.physics.model.ptr.actuator_biasprm[act, 1] *= 1e6
    env.physics.model.ptr.actuator_forcelimited[act] = 0
    env.physics.model.ptr.jnt_actfrclimited[:] = 0
    step = env.step(np.full(4, 1e3))
    assert step.last() and step.discount == 0.0 and env.task.k == 10
    ev = simbench_env.evaluation(env)
    assert ev.verdict.status == "failed" and ev.verdict.violations[0].kind == "failed"
    assert ev.verdict.violations[0].message.startswith("the physics failed at t = 0.0110 s")
    assert ev.recording.t.size == ev.trajectory.t.size == 11


def test_random_tasks_on_a_planar_arm_and_an_arm_derived_from_its_urdf(tmp_path):
    """The example's planar 3R (a plugin robot) and the UR5 read from its URDF: seeded random joint moves whose
    goals lie within MuJoCo's joint ranges, the same for the same seed."""
    from importlib.metadata import distribution

    urdf = distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")
    path = tmp_path / "ur5.yaml"
    path.write_text(f"robot: {{model: {urdf}, tool: {{body: wrist_3_link}}}}\nplanner: joint_move\n"
                    "units: {angle: deg}\n"
                    "task: {start: [0, -60, 60, -90, -90, 0], goal: [30, -80, 90, -100, -60, 40]}\n"
                    "timing: {duration: 0.5, hold: 0.1}\n")
    planar = planar3r_scenarios() / "line.yaml"
    for source in (planar, path):
        envs = [simbench_env.load(source, task_kwargs={"random": 11}) for _ in range(2)]
        a, b = starts(envs[0], 2), starts(envs[1], 2)
        assert all(np.array_equal(x, y) for x, y in zip(a, b)) and not np.allclose(a[0], a[1])
        model, act = envs[0].physics.model.ptr, envs[0].task.plant.actuators
        jnt = model.actuator_trnid[act, 0]
        goal = envs[0].task.plan.q_ref[-1]
        limited = model.jnt_limited[jnt].astype(bool)
        assert (goal[limited] >= model.jnt_range[jnt[limited], 0]).all()
        assert (goal[limited] <= model.jnt_range[jnt[limited], 1]).all()


def planar3r_scenarios():
    from pathlib import Path

    from simbench_planar3r import control as planar3r_control
    return Path(planar3r_control.__file__).parent / "scenarios"


def test_random_joint_moves_under_torque_actuation_stay_within_the_joints_ranges():
    """Under torque actuation the action bounds are force limits: the random joint moves are still drawn within
    the joints' positions (MuJoCo's jnt_range of a limited joint), the same moves as under position actuation."""
    envs = {act: simbench_env.load_task("spherical_arm", "case1", task_kwargs={"random": 1}, actuation=act)
            for act in ("position", "torque")}
    model, plant = envs["torque"].physics.model.ptr, envs["torque"].task.plant
    jnt = model.actuator_trnid[plant.actuators, 0]
    limited = model.jnt_limited[jnt].astype(bool)
    lo, hi = model.jnt_range[jnt[limited]].T
    for _ in range(3):
        plans = {act: (env.reset(), env.task.plan.q_ref)[1] for act, env in envs.items()}
        q = plans["torque"][:, limited]
        assert (q >= lo).all() and (q <= hi).all(), (q.min(axis=0), q.max(axis=0), lo, hi)
        assert np.array_equal(plans["torque"], plans["position"])


@pytest.mark.parametrize("robot, name", [("puma600", "line"), ("agile_eye", "through_singularity")])
def test_a_reset_leaves_the_data_as_mj_step1_leaves_it(robot, name):
    """After reset (dm_control's after_reset runs mj_forward with the actuators off), the data's position- and
    velocity-dependent quantities are MuJoCo's mj_step1 of the settled state: the actuators' velocities, which the
    servos' damping uses in the first step, included."""
    import copy

    import mujoco

    env = simbench_env.load_task(robot, name)
    env.reset()
    model, data = env.physics.model.ptr, env.physics.data.ptr
    fresh = copy.copy(data)
    mujoco.mj_step1(model, fresh)
    assert np.abs(fresh.actuator_velocity).max() > 0
    for field in ("actuator_velocity", "actuator_length", "qfrc_bias", "sensordata", "xpos"):
        assert np.array_equal(getattr(data, field), getattr(fresh, field)), field


@pytest.mark.parametrize("share_model", [False, True])
def test_a_physics_copy_keeps_the_time_and_steps_as_the_environment(share_model):
    """dm_control's physics.copy() mid-episode: the copy's time is the episode's (the plan's sample time), and a
    step of it (the same control) lands where the environment's own step lands, leaving the episode unrecorded."""
    env = simbench_env.load_task("puma600", "line")
    policy, step = simbench_env.servo_policy(env), env.reset()
    for _ in range(5):
        step = env.step(policy(step))
    ahead = env.physics.copy(share_model=share_model)
    assert ahead.time() == env.physics.time() == pytest.approx(env.task.plan.t[5], abs=1e-12)
    action = policy(step)
    ahead.data.ptr.ctrl[env.task.plant.actuators] = action
    ahead.step()
    assert env.task.k == 5
    env.step(action)
    assert np.array_equal(ahead.data.ptr.qpos, env.physics.data.ptr.qpos)
    assert ahead.time() == pytest.approx(env.physics.time(), abs=1e-12)
