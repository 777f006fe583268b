"""The RL mode of a task (simbench.env.rl_mode): normalised actions mapped onto the joints' MuJoCo ranges, the
residual action 0 against `simulate`'s servo run, the reward's width against MuJoCo's own tool site, every
Gymnasium id against Gymnasium's checker, the C loop's substeps against the Python loop, and seeded domain
randomisation and noise against the model's nominal values and the true state."""

from __future__ import annotations

import copy
import warnings

import mujoco
import numpy as np
import pytest

from simbench import env as simbench_env
from simbench.env.rl_mode import RESIDUAL_SCALE, RL, with_rl
from simbench.physics.controllers import Servo
from simbench.physics.sim import simulate


def rl_env(robot: str, name: str, rl=True, task_kwargs=None, environment_kwargs=None, **kwargs):
    """A shipped task's RL mode, made as `with_rl` documents."""
    return simbench_env.load_task(robot, name, *with_rl(rl, task_kwargs, environment_kwargs), **kwargs)


def run(env, actions) -> list:
    """Reset, then one action a control step until the actions or the episode run out: the timesteps."""
    steps = [env.reset()]
    for action in actions:
        if steps[-1].last():
            break
        steps.append(env.step(action))
    return steps


# --- actions ---------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("float32", [False, True])
def test_actions_are_minus_one_to_one_mapped_onto_the_joint_ranges(float32):
    """The action spec is [-1, 1] a joint (float32 where asked, with the observation); an absolute action of -1,
    0 and 1 commands each limited joint's lower end, middle and upper end of MuJoCo's jnt_range."""
    env = rl_env("puma600", "line", {"float32": float32})
    spec = env.action_spec()
    assert spec.shape == (6,) and spec.dtype == (np.float32 if float32 else np.float64)
    assert np.all(spec.minimum == -1.0) and np.all(spec.maximum == 1.0)
    model, act = env.physics.model.ptr, env.task.plant.actuators
    joints = model.actuator_trnid[act, 0]
    assert model.jnt_limited[joints].all()
    lo, hi = model.jnt_range[joints].T
    step = env.reset()
    assert all(value.dtype == (np.float32 if float32 else np.float64) for value in step.observation.values())
    for a, expected in ((-1.0, lo), (0.0, (lo + hi) / 2), (1.0, hi)):
        env.step(np.full(6, a, dtype=spec.dtype))
        np.testing.assert_allclose(env.physics.data.ptr.ctrl[act], expected, rtol=0, atol=1e-12)
    assert env.control_timestep() == pytest.approx(0.02)


@pytest.mark.parametrize("robot, name, control_steps", [("puma600", "line", 1000), ("rsmg", "three_turns", 160)])
def test_the_residual_action_zero_is_simulates_servo_run(robot, name, control_steps):
    """With residual actions of 0 at the default 20 ms control step the episode is `simulate`'s servo run of the
    plan, every physics step of it (on the RSMG past its first weld switches, the grip feedback revising the
    references); the PUMA's return is the gaussian reward recomputed from simulate's tool at each control step's
    end: 0.99 of the most a step at least."""
    env = rl_env(robot, name, {"residual": True})
    task = env.task
    steps = run(env, [np.zeros(task.plant.robot.dof)] * control_steps)
    expected = simulate(task.plant, task.plan, Servo.from_scenario(task.scenario), settle=task.scenario.sim.settle)
    rec, rows = simbench_env.recording(env), task.k + 1
    for key in ("q", "qd", "tool"):
        np.testing.assert_allclose(getattr(rec, key), getattr(expected, key)[:rows], rtol=0, atol=1e-12, err_msg=key)
    # the forces of every step taken (an episode cut short records no command after its last row)
    np.testing.assert_allclose(rec.force[:-1], expected.force[:rows - 1], rtol=0, atol=1e-12)
    if robot == "rsmg":
        assert rows > 3045 and rec.q_ref is not None
        np.testing.assert_array_equal(rec.q_ref[:rows], expected.q_ref[:rows])
        return
    assert steps[-1].last() and len(steps) - 1 == 145
    samples = np.minimum(np.arange(1, 146) * 20, task.n - 1)
    d = np.linalg.norm(expected.tool[samples] - task.plan.tool_ref[samples], axis=1)
    total = sum(step.reward for step in steps[1:])
    assert total == pytest.approx(np.sum(0.5 ** ((d / 0.02) ** 2)), rel=1e-9)
    assert total >= 0.99 * 145


def test_a_residual_action_shifts_the_servos_target_by_its_scale():
    """A residual action a moves each joint's target by scale * a from the servo's (RESIDUAL_SCALE: 0.05 rad a
    hinge by default, or the scale given): each control step's command differs from the action-0 episode's by
    exactly that (the servo's targets depend on the plan alone)."""
    actions = np.random.default_rng(0).uniform(-1, 1, (5, 6))
    scale = np.array([0.01, 0.02, 0.03, 0.04, 0.05, 0.06])
    commands = {}
    for name, rl in (("zero", {"residual": True}), ("default", {"residual": True}),
                     ("scaled", {"residual": True, "residual_scale": tuple(scale)})):
        env = rl_env("puma600", "line", rl)
        env.reset()
        commands[name] = []
        for action in actions:
            env.step(np.zeros(6) if name == "zero" else action)
            commands[name].append(simbench_env.recording(env).ctrl[-1].copy())
    act = env.task.plant.actuators
    assert RESIDUAL_SCALE[mujoco.mjtJoint.mjJNT_HINGE] == 0.05
    for name, per_joint in (("default", 0.05), ("scaled", scale)):
        shift = np.array(commands[name]) - np.array(commands["zero"])
        np.testing.assert_allclose(shift[:, act], per_joint * actions, rtol=0, atol=1e-12)


def test_a_residual_of_the_reference_shifts_the_plans_reference_itself():
    """residual_of='reference': every physics step's target is the plan's reference at that step (its sample,
    read from the plan, not from the environment) plus scale * action."""
    env = rl_env("puma600", "line", {"residual": True, "residual_of": "reference"})
    plan, act = env.task.plan, env.task.plant.actuators
    actions = np.random.default_rng(1).uniform(-1, 1, (4, 6))
    env.reset()
    for action in actions:
        env.step(action)
    ctrl = simbench_env.recording(env).ctrl
    substeps = round(env.control_timestep() / env.physics.timestep())
    for k in range(len(actions) * substeps):
        np.testing.assert_allclose(ctrl[k, act], plan.q_ref[k] + 0.05 * actions[k // substeps], rtol=0, atol=1e-12)


# --- the reward --------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("reward, width", [("gaussian", 0.02), ("shaped", 0.02), ("gaussian", 0.01)])
def test_the_reward_has_its_documented_width(reward, width):
    """The arm posed off its reference (joint offsets that put the tool about `width` away): the reward is
    0.5 ** ((d / width) ** 2) (gaussian) or exp(-d / width) (shaped), d the distance of MuJoCo's tool site
    (mj_kinematics on a data of its own) from the plan's tool reference."""
    env = rl_env("puma600", "line", {"reward": reward, "width": width})
    env.reset()
    task, physics = env.task, env.physics
    model, data = physics.model.ptr, physics.data.ptr
    site = int(model.sensor(task.plant.robot.tool_sensor).objid[0])
    k = task.k
    for offset in (0.0, 0.01, 0.025, 0.05):
        q = task.plan.q_ref[k] + offset * np.array([1.0, -1.0, 1.0, 0.0, 0.0, 0.0])
        data.qpos[task.plant.qpos_adr] = q
        mujoco.mj_forward(model, data)
        fresh = mujoco.MjData(model)
        fresh.qpos[task.plant.qpos_adr] = q
        mujoco.mj_kinematics(model, fresh)
        d = np.linalg.norm(fresh.site_xpos[site] - task.plan.tool_ref[k])
        expected = 0.5 ** ((d / width) ** 2) if reward == "gaussian" else np.exp(-d / width)
        assert task.get_reward(physics) == pytest.approx(expected, rel=1e-9, abs=1e-15)
        if offset == 0.025:
            assert 0.5 * width < d < 4 * width and 0.01 < expected < 0.9


# --- Gymnasium -------------------------------------------------------------------------------------------------

def test_every_task_has_a_gymnasium_id_that_passes_gymnasiums_checker():
    """Importing simbench.env.gym_ids registers simbench/<robot>-<task>-v0 for every task load_task knows;
    gymnasium.make makes each (the RL mode, float32, actions in [-1, 1]) and Gymnasium's check_env passes on it."""
    gymnasium = pytest.importorskip("gymnasium", reason="Gymnasium (and shimmy) are in the [rl] extra")
    pytest.importorskip("shimmy", reason="shimmy (and Gymnasium) are in the [rl] extra")
    from gymnasium.utils.env_checker import check_env

    from simbench.env import gym_ids

    ids = {gym_ids.gym_id(robot, name) for robot, name in simbench_env.ALL_TASKS}
    assert "simbench/puma600-line-v0" in ids and ids <= set(gymnasium.registry)
    for env_id in sorted(ids):
        env = gymnasium.make(env_id)
        space = env.action_space
        assert space.dtype == np.float32 and np.all(space.low == -1) and np.all(space.high == 1), env_id
        with warnings.catch_warnings():  # the checker's advice on unbounded observation boxes is no failure
            warnings.simplefilter("ignore", UserWarning)
            check_env(env.unwrapped, skip_render_check=True)
        env.close()


# --- the C loop ------------------------------------------------------------------------------------------------

def recorded(env) -> dict:
    """An episode's timeseries as simbench records it."""
    rec = simbench_env.recording(env)
    return {"t": rec.t, "q": rec.q, "qd": rec.qd, "tool": rec.tool, "ctrl": rec.ctrl, "force": rec.force,
            **{f"eq {name}": active for name, active in rec.eq_active.items()}}


@pytest.mark.parametrize("robot, name, rl, control_steps", [
    ("puma600", "line", {"residual": True}, 40),
    ("puma600", "line", {"noise": True, "seed": 4}, 40),
    ("rsmg", "three_turns", None, 160),  # past its first weld switches (at steps 2445 and 3045)
])
def test_the_c_loop_steps_as_the_python_loop(robot, name, rl, control_steps):
    """The same actions through the C loop (mujoco.rollout over a control step) and the Python loop (one mj_step2
    and mj_step1 at a time): the same timeseries to 1e-12, the same rewards, the same switches."""
    actions = np.random.default_rng(1).uniform(-1, 1, (control_steps, 8))
    episodes = {}
    for c_loop in (True, False):
        if rl is None:  # the default task, its own actions: the servo's targets held 20 physics steps
            env = simbench_env.load_task(robot, name, environment_kwargs={"n_sub_steps": 20})
            policy = simbench_env.servo_policy(env)
            env.physics.c_loop = c_loop
            step, rewards = env.reset(), []
            for _ in range(control_steps):
                step = env.step(policy(step))
                rewards.append(step.reward)
        else:
            env = rl_env(robot, name, rl)
            env.physics.c_loop = c_loop
            dof = env.task.plant.robot.dof
            rewards = [step.reward for step in run(env, actions[:, :dof])[1:]]
        episodes[c_loop] = recorded(env), rewards, env.task.k
    (c, c_rewards, c_k), (py, py_rewards, py_k) = episodes[True], episodes[False]
    assert c_k == py_k == control_steps * 20 and c.keys() == py.keys()
    for key in c:
        np.testing.assert_allclose(c[key], py[key], rtol=0, atol=1e-12, err_msg=key)
    np.testing.assert_allclose(c_rewards, py_rewards, rtol=1e-12)
    if robot == "rsmg":
        assert any(not np.all(active == active[0]) for key, active in c.items() if key.startswith("eq "))


def test_a_failure_inside_a_control_step_is_found_at_its_physics_step_by_either_loop():
    """Gains raised a millionfold and a far target mid-episode: the C loop's stretch goes wrong, is stepped again
    in Python and ends the episode at the same physics step, with the same cause and recording, as the Python loop
    alone."""
    outcomes = []
    for c_loop in (True, False):
        env = simbench_env.load_task("spherical_arm", "case1", environment_kwargs={"n_sub_steps": 10})
        env.physics.c_loop = c_loop
        policy, step = simbench_env.servo_policy(env), env.reset()
        for _ in range(3):
            step = env.step(policy(step))
        model, act = env.physics.model.ptr, env.task.plant.actuators
        model.actuator_gainprm[act, 0] *= 1e6
        model.actuator_biasprm[act, 1] *= 1e6
        model.actuator_forcelimited[act] = 0
        model.jnt_actfrclimited[:] = 0
        step = env.step(np.full(4, 1e3))
        assert step.last() and step.discount == 0.0
        outcomes.append((env.task.k, env.task.failure, recorded(env)))
    (k_c, why_c, rec_c), (k_py, why_py, rec_py) = outcomes
    assert k_c == k_py and 30 <= k_c < 40 and why_c == why_py
    for key in rec_c:
        np.testing.assert_array_equal(rec_c[key], rec_py[key], err_msg=key)


# --- randomisation and noise ---------------------------------------------------------------------------------

def nominal_model(robot: str, name: str) -> mujoco.MjModel:
    """The task's model as loaded, never randomised."""
    return copy.copy(simbench_env.load_task(robot, name).physics.model.ptr)


def test_randomisation_is_seeded_within_its_ranges_and_in_the_model():
    """The same seed draws the same values, another seed others; every value lies within its range; and the
    model holds them: masses and inertias the nominal ones times the factors, damping, dry friction (a fraction of
    the force limit), sliding friction and the servos' kp (gain and bias) as drawn; the next reset draws anew."""
    spec = {"mass": (0.7, 1.3), "damping": (0.5, 2.0), "friction": (0.0, 0.02), "contact_friction": (0.9, 1.1),
            "gain": (0.8, 1.2), "delay": (0, 3)}

    def draws(seed: int, resets: int = 2):
        env = rl_env("spherical_arm", "case1", {"randomise": spec, "seed": seed})
        out = []
        for _ in range(resets):
            env.reset()
            out.append({key: value.copy() for key, value in env.task.drawn.items()})
        return env, out

    env, a = draws(1)
    _, b = draws(1)
    _, c = draws(2)
    assert list(a[0]) == list(spec)
    for key in spec:
        assert np.array_equal(a[0][key], b[0][key]) and np.array_equal(a[1][key], b[1][key]), key
        assert not np.array_equal(a[0][key], a[1][key]) or key == "delay"
        assert not np.array_equal(a[0][key], c[0][key]) or key == "delay"
    for draw in a + c:
        for key, (lo, hi) in spec.items():
            assert np.all(draw[key] >= lo) and np.all(draw[key] <= hi), key
        assert float(draw["delay"][0]).is_integer()
    drawn, model, nominal = a[1], env.physics.model.ptr, nominal_model("spherical_arm", "case1")
    plant = env.task.plant
    dof, act = plant.dof_adr, plant.actuators
    np.testing.assert_allclose(model.body_mass[1:], nominal.body_mass[1:] * drawn["mass"], rtol=1e-12)
    np.testing.assert_allclose(model.body_inertia[1:], nominal.body_inertia[1:] * drawn["mass"][:, None], rtol=1e-12)
    np.testing.assert_allclose(model.dof_damping[dof], nominal.dof_damping[dof] * drawn["damping"], rtol=1e-12)
    limit = np.abs(nominal.actuator_forcerange[act]).min(axis=1)
    np.testing.assert_allclose(model.dof_frictionloss[dof], nominal.dof_frictionloss[dof] + drawn["friction"] * limit,
                               rtol=1e-12)
    np.testing.assert_allclose(model.geom_friction[:, 0], nominal.geom_friction[:, 0] * drawn["contact_friction"],
                               rtol=1e-12)
    np.testing.assert_allclose(model.actuator_gainprm[act, 0], nominal.actuator_gainprm[act, 0] * drawn["gain"],
                               rtol=1e-12)
    np.testing.assert_allclose(model.actuator_biasprm[act, 1], nominal.actuator_biasprm[act, 1] * drawn["gain"],
                               rtol=1e-12)


def test_a_drawn_delay_holds_each_action_back_by_that_many_control_steps():
    """With a delay of 2 control steps, the commands are the undelayed episode's two steps late, the first two
    holding the start; the observation's `randomised` entry shows the delay."""
    actions = np.random.default_rng(3).uniform(-1, 1, (6, 4))
    ctrl = {}
    for delay in (0, 2):
        env = rl_env("spherical_arm", "case1", {"randomise": {**dict.fromkeys(
            ("mass", "damping", "friction", "contact_friction", "gain")), "delay": (delay, delay), "observe": True}})
        step, ctrl[delay] = env.reset(), []
        assert np.array_equal(step.observation["randomised"], [delay])
        for action in actions:
            env.step(action)
            ctrl[delay].append(env.physics.data.ptr.ctrl.copy())
    np.testing.assert_array_equal(ctrl[2][2:], ctrl[0][:-2])
    start = env.task.plan.q_ref[0]
    np.testing.assert_allclose(ctrl[2][0][env.task.plant.actuators], start, atol=1e-9)


def test_noise_is_seeded_and_of_its_stated_size():
    """Observation noise: the observed q minus the true joint positions (MuJoCo's qpos) has about the stated
    standard deviation; the same seed gives the same noisy observations, another seed others; shimmy's
    reset(seed=...) reseeds the randomisation as the seed does."""
    def episode(seed):
        env = rl_env("puma600", "line", {"noise": {"q": 0.002, "action": 0.0}, "seed": seed})
        errors, observed = [], []
        step = env.reset()
        for _ in range(60):
            step = env.step(np.zeros(6))
            true_q = env.physics.data.ptr.qpos[env.task.plant.qpos_adr]
            errors.append(step.observation["q"] - true_q)
            observed.append(step.observation["q"])
        return np.array(errors), np.array(observed)

    errors, a = episode(7)
    _, b = episode(7)
    _, c = episode(8)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert 0.0017 < errors.std() < 0.0023 and abs(errors.mean()) < 3e-4
    shimmy = pytest.importorskip("shimmy", reason="shimmy is in the [rl] extra")
    gyms = [shimmy.DmControlCompatibilityV0(rl_env("spherical_arm", "case1", {"randomise": True, "seed": s}))
            for s in (1, 2)]
    drawn = []
    for env in gyms:
        env.reset(seed=5)
        drawn.append(env.unwrapped._env.task.drawn["mass"].copy())
    assert np.array_equal(drawn[0], drawn[1])


@pytest.mark.parametrize("task_kwargs", [None, {"random": 3}])
def test_asking_for_the_observation_spec_leaves_the_seeded_episodes_as_they_are(task_kwargs):
    """With noise (and random tasks, which draw from the same random state), an environment asked for its
    observation spec before its reset (as shimmy's wrapper asks when it is made) gives the same episode, noisy
    observations and task, as one never asked; the spec is the observations' (shapes and dtypes)."""
    def episode(ask: bool):
        env = rl_env("puma600", "line", {"noise": True, "seed": 0}, task_kwargs)
        spec = env.observation_spec() if ask else None
        steps = run(env, np.zeros((30, 6)))
        return spec, [step.observation for step in steps], env.task.plan.t[-1]

    spec, asked, asked_end = episode(True)
    _, plain, plain_end = episode(False)
    assert asked_end == plain_end
    for a, b in zip(asked, plain, strict=True):
        assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    assert all(spec[k].shape == value.shape and spec[k].dtype == value.dtype for k, value in asked[-1].items())


def test_the_gymnasium_wrapper_pickles_mid_episode_with_noise_as_the_original():
    """shimmy's wrapper rebuilds itself on unpickling, asking the environment for its spec: with noise on, the
    copy's observations, rewards and ends are the original's, step for step."""
    shimmy = pytest.importorskip("shimmy", reason="shimmy is in the [rl] extra")
    import pickle

    gym = shimmy.DmControlCompatibilityV0(rl_env("puma600", "line", {"noise": True, "seed": 0}))
    gym.reset(seed=1)
    for _ in range(10):
        gym.step(np.zeros(6))
    copied = pickle.loads(pickle.dumps(gym))
    for _ in range(20):
        a, b = gym.step(np.full(6, 0.1)), copied.step(np.full(6, 0.1))
        assert all(np.array_equal(a[0][k], b[0][k]) for k in a[0]) and a[1:4] == b[1:4]


@pytest.mark.parametrize("draws", [True, False])
def test_an_observed_randomisation_has_its_spec_before_the_first_reset(draws):
    """With `observe`, the observation spec asked before any reset (as shimmy's wrapper and gymnasium.make ask for
    it) holds `randomised` as a reset's observation has it: one value a body's mass (the world's excepted), a
    joint's damping and dry friction, the contact friction, an actuator's gain and the delay; empty where nothing is
    drawn (every range None)."""
    quantities = ("mass", "damping", "friction", "contact_friction", "gain", "delay")
    randomise = {"observe": True} if draws else {**dict.fromkeys(quantities), "observe": True}
    env = rl_env("puma600", "line", {"randomise": randomise, "seed": 0})
    model = env.physics.model.ptr
    spec = env.observation_spec()["randomised"]
    drawn = env.reset().observation["randomised"]
    expected = (model.nbody - 1) + 6 + 6 + 1 + model.nu + 1 if draws else 0
    assert spec.shape == drawn.shape == (expected,)


def test_a_snapshot_replays_an_rl_episode_with_noise_and_a_delay():
    """Action and observation noise, a drawn delay of 2 control steps and the default randomisation: restored at
    a snapshot of control step 10, the same 30 actions give the same observations and rewards bit for bit (the
    noise drawn again as it was, the delayed actions queued as they were); after a reset that drew another
    model too (the snapshot's draw comes back)."""
    rl = {"residual": True, "noise": {"action": 0.05}, "randomise": {"delay": (2, 2)}, "seed": 3}
    env = simbench_env.load_task("puma600", "line", task_kwargs={"rl": rl})
    actions = np.random.default_rng(4).uniform(-1, 1, (40, 6))
    env.reset()
    for action in actions[:10]:
        env.step(action)
    snap, mass = simbench_env.snapshot(env), env.physics.model.ptr.body_mass.copy()
    went_on = [env.step(action) for action in actions[10:]]
    for after_a_reset in (False, True):
        if after_a_reset:
            env.reset()
            assert not np.array_equal(env.physics.model.ptr.body_mass, mass)  # another draw
        simbench_env.restore(env, snap)
        assert np.array_equal(env.physics.model.ptr.body_mass, mass) and len(env.task._queue) == 2
        for i, (action, expected) in enumerate(zip(actions[10:], went_on)):
            got = env.step(action)
            assert got.reward == expected.reward, (after_a_reset, i)
            for key, value in expected.observation.items():
                assert np.array_equal(got.observation[key], value), (after_a_reset, i, key)


# --- bad settings ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("rl, kwargs, message", [
    ({"control_timestep": 0.005}, {}, "rl control_timestep: 0.01 to 0.04 s expected, got 0.005"),
    ({"reward": "sparse"}, {}, "rl reward: 'gaussian' or 'shaped' expected"),
    ({"residual": True, "residual_of": "plan"}, {}, "rl residual_of: 'servo' or 'reference' expected"),
    ({"width": 0}, {}, "rl width: a distance > 0"),
    ({"randomise": {"mass": (1.2, 0.8)}}, {}, "rl randomise.mass: a range"),
    ({"randomise": {"delay": (0, 1.5)}}, {}, "rl randomise.delay: a range (low, high) of whole numbers"),
    ({"noise": {"q": -1}}, {}, "rl noise.q: a standard deviation >= 0"),
    ({"colour": 1}, {}, "rl: no setting 'colour'"),
    ({}, {"environment_kwargs": {"n_sub_steps": 20}}, "in the RL mode the control step is a time"),
    ({"residual": True}, {"actuation": "torque"}, "rl residual: a residual action shifts the servo's position"),
    ({"residual": True, "residual_scale": (0.1, 0.2)}, {}, "rl residual_scale: one a joint (6) or one for all"),
])
def test_bad_settings_are_refused_in_one_line(rl, kwargs, message):
    with pytest.raises(ValueError) as err:
        rl_env("puma600", "line", rl, **kwargs)
    assert message in str(err.value) and "\n" not in str(err.value)
