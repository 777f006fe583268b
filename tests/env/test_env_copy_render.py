"""simbench.env as an RL researcher uses it: frames rendered whichever of shimmy and simbench.env is imported first,
environments and snapshots deep-copied and pickled (the copy steps as the original, step for step), dm_control's
`visualize_reward`, and the RSMG's random tasks within the action spec."""

from __future__ import annotations

import copy
import os
import pickle
import subprocess
import sys

import mujoco
import numpy as np
import pytest

from simbench import env as simbench_env
from simbench.env.pixels import CAMERAS, OUTLINE_SHARE, facets

linux = pytest.mark.skipif(sys.platform != "linux", reason="EGL and the MUJOCO_GL values tested are Linux's")

WIDTH, HEIGHT = 80, 56  # a frame's asked size, not the model's offscreen buffer's

RENDER = """
import sys
import numpy as np
order, out, width, height = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
if order == "shimmy first":
    from shimmy import DmControlCompatibilityV0
    from simbench import env
else:
    from simbench import env
env_ = env.load_task("spherical_arm", "case1")
env_.reset()
frames = [env_.physics.render(height=height, width=width)]
if order == "shimmy first":  # through the Gymnasium environment too
    gym = DmControlCompatibilityV0(env_, render_mode="rgb_array", render_kwargs={"height": height, "width": width})
    frames.append(gym.render())
else:  # a video drawn between two frames
    from simbench.outputs.render import render_video
    task = env_.task
    render_video(task.plant.robot.scene, env.recording(env_), task.plan.tool_ref, out + ".mp4", width=64, height=48,
                 fps=5)
    frames.append(env_.physics.render(height=height, width=width))
np.save(out, np.stack(frames))
"""


def _process_env(**chosen: str) -> dict[str, str]:
    """This process's environment without a GL choice or a display, and with `chosen`."""
    unset = ("MUJOCO_GL", "PYOPENGL_PLATFORM", "DISPLAY", "WAYLAND_DISPLAY")
    return {**{k: v for k, v in os.environ.items() if k not in unset}, **chosen}


@linux
def test_frames_render_in_either_import_order_and_under_the_users_egl(tmp_path):
    """Each in a fresh process: shimmy imported first (it imports dm_control, which then picked GLFW and could not
    draw without a display), simbench.env first, and MUJOCO_GL=egl: the same non-blank frame of the asked size,
    and a clean exit (no traceback from the GL contexts freed at exit)."""
    pytest.importorskip("shimmy")
    runs = {"shimmy first": _process_env(), "simbench first": _process_env(), "egl": _process_env(MUJOCO_GL="egl")}
    procs = {name: subprocess.Popen([sys.executable, "-c", RENDER, name, str(tmp_path / name.replace(" ", "_")),
                                     str(WIDTH), str(HEIGHT)],
                                    env=environ, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for name, environ in runs.items()}
    frames = {}
    for name, proc in procs.items():
        _, stderr = proc.communicate(timeout=300)
        assert proc.returncode == 0, f"{name}: {stderr[-3000:]}"
        assert "Traceback" not in stderr and "Exception ignored" not in stderr, f"{name}: {stderr[-3000:]}"
        frames[name] = np.load(tmp_path / f"{name.replace(' ', '_')}.npy")
    first = frames["simbench first"][0]
    assert first.shape == (HEIGHT, WIDTH, 3) and first.dtype == np.uint8
    assert first.std() > 10  # a scene, not a blank frame
    for name, drawn in frames.items():
        for frame in drawn:  # shimmy's frame; the one after a video
            assert np.array_equal(frame, first), name


def _servo_actions(env, steps: int, seed: int) -> np.ndarray:
    """The servo's targets for the next control steps along the plan, with noise: actions that keep the robot on
    its path, but not exactly."""
    task, spec = env.task, env.action_spec()
    policy = simbench_env.servo_policy(env)
    stride = round(env.control_timestep() / env.physics.timestep())
    k = np.minimum(task.k + np.arange(1, steps + 1) * stride, task.n - 1)
    servo = np.array([policy({"q_ref": task.q_ref[i], "qd_ref": task.qd_ref[i]}) for i in k])
    noise = np.random.default_rng(seed).normal(0.0, 0.01, servo.shape)
    return np.clip(servo + noise, spec.minimum, spec.maximum)


def _assert_same_steps(original, copies, actions) -> None:
    """Each copy's time steps equal the original's, bit for bit: observations, rewards, discounts, kinds."""
    for i, action in enumerate(actions):
        expected = original.step(action)
        for other in copies:
            got = other.step(action)
            assert (got.step_type, got.reward, got.discount) == (expected.step_type, expected.reward,
                                                                 expected.discount), i
            for key, value in expected.observation.items():
                assert np.array_equal(got.observation[key], value), (i, key)


@pytest.fixture(scope="module")
def rsmg():
    """The RSMG's three turns at 5 physics steps a control step, 100 control steps in: its grips switch at steps
    525 and 1125, and the plan's feedback revises the references there."""
    env = simbench_env.load_task("rsmg", "three_turns", environment_kwargs={"n_sub_steps": 5})
    env.reset()
    for action in _servo_actions(env, 100, seed=0):
        env.step(action)
    return env


def test_a_deep_copy_and_an_unpickled_environment_step_as_the_original(rsmg):
    """200 control steps with the same actions, across two switches: the same observations, rewards and discounts;
    the copy's time is the original's (it lost the settle before), and it keeps recording into its own track."""
    copied, unpickled = copy.deepcopy(rsmg), pickle.loads(pickle.dumps(rsmg))
    for other in (copied, unpickled):
        assert other.physics.time() == rsmg.physics.time() == pytest.approx(rsmg.task.plan.t[rsmg.task.k])
        assert other.task is not rsmg.task and other.physics.track is other.task
    k = rsmg.task.k
    _assert_same_steps(rsmg, [copied, unpickled], _servo_actions(rsmg, 200, seed=1))
    assert copied.task.k == unpickled.task.k == rsmg.task.k == k + 1000
    assert np.array_equal(simbench_env.recording(copied).q, simbench_env.recording(rsmg).q)


def test_an_episode_copied_at_its_start_ends_where_the_original_does():
    """A copy steps no further than the plan (it ran 4,000 steps of a 2,900-step plan when it lost its track)."""
    env = simbench_env.load_task("puma600", "line", environment_kwargs={"n_sub_steps": 50})
    env.reset()
    copied = copy.deepcopy(env)
    actions = _servo_actions(env, 58, seed=2)
    _assert_same_steps(env, [copied], actions)
    assert env.task.k == copied.task.k == env.task.n - 1 == 2900
    assert copied.step(actions[-1]).first()  # the episode ended: the next step starts another


def test_a_pickled_snapshot_restores_the_episode(rsmg):
    """restore(unpickled snapshot) then the same actions replay the episode as it went on from the snapshot."""
    snap = pickle.loads(pickle.dumps(simbench_env.snapshot(rsmg)))
    actions = _servo_actions(rsmg, 50, seed=3)
    went_on = [rsmg.step(action) for action in actions]
    simbench_env.restore(rsmg, snap)
    for action, expected in zip(actions, went_on):
        got = rsmg.step(action)
        assert got.reward == expected.reward
        for key, value in expected.observation.items():
            assert np.array_equal(got.observation[key], value), key


def test_the_gymnasium_environment_pickles_and_steps_as_the_original(rsmg):
    shimmy = pytest.importorskip("shimmy")
    original = shimmy.DmControlCompatibilityV0(copy.deepcopy(rsmg))
    unpickled = pickle.loads(pickle.dumps(original))
    for action in _servo_actions(rsmg, 50, seed=4):
        expected, got = original.step(action), unpickled.step(action)
        assert got[1:4] == expected[1:4]
        for key, value in expected[0].items():
            assert np.array_equal(got[0][key], value), key


UNPICKLE = """
import pickle, sys
import numpy as np
env = pickle.loads(sys.stdin.buffer.read())
print([env.step(action).reward for action in np.load(sys.argv[1])])
"""


def test_an_environment_unpickles_in_a_fresh_process(tmp_path):
    """A random joint move's environment: its scenario's class, made per planner and controller (pydantic's
    create_model), is found by its name in a process that has not made it yet, and the episode goes on there as
    here."""
    env = simbench_env.load_task("spherical_arm", "case1", {"random": 7}, {"n_sub_steps": 4})
    env.reset()
    assert env.task.scenario.planner == "joint_move"
    actions = _servo_actions(env, 30, seed=5)
    np.save(tmp_path / "actions.npy", actions)
    done = subprocess.run([sys.executable, "-c", UNPICKLE, str(tmp_path / "actions.npy")], input=pickle.dumps(env),
                          capture_output=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr.decode()[-2000:]
    assert done.stdout.decode().strip() == repr([env.step(action).reward for action in actions])


def _moving_geoms(model: mujoco.MjModel, actuated_joints: np.ndarray) -> np.ndarray:
    """The geoms MuJoCo's kinematics moves when any actuated joint turns (mj_kinematics before and after)."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    before = data.geom_xpos.copy(), data.geom_xmat.copy()
    data.qpos[model.jnt_qposadr[actuated_joints]] += 0.3
    mujoco.mj_kinematics(model, data)
    moved = (np.abs(data.geom_xpos - before[0]).max(axis=1) > 1e-9) | \
        (np.abs(data.geom_xmat - before[1]).max(axis=1) > 1e-9)
    return np.flatnonzero(moved)


FITTED = """
import sys
import numpy as np
from dm_control.mujoco import Physics
from simbench import env
from simbench.outputs.drawn_planes import planes_drawn_finite
env_ = env.load_task("puma600", "line")
env_.reset()
model = env_.physics.model.ptr
vis, floor = model.vis, model.geom_size.copy()
file = (vis.global_.offwidth, vis.global_.offheight, vis.quality.shadowsize)
plain, endless = (Physics.from_model(env_.physics.model) for _ in range(2))  # dm_control's own, as the file says
for physics in (plain, endless):
    physics.data.qpos[:] = env_.physics.data.qpos
    physics.forward()
out = {}
for i, (width, height) in enumerate(((84, 84), (640, 480), (84, 84))):
    ours = env_.physics.render(height, width, camera_id=0)
    with planes_drawn_finite(model):
        finite = plain.render(height, width, camera_id=0)
    out[f"{i}"] = np.stack([ours, finite, endless.render(height, width, camera_id=0)])
    out[f"{i} fitted"] = np.array(env_.physics._fitted)
    assert (vis.global_.offwidth, vis.global_.offheight, vis.quality.shadowsize) == file, "the model's own changed"
    assert (model.geom_size == floor).all(), "the floor's size changed"
np.savez(sys.argv[1], **out)
"""


def test_round_geoms_get_the_fewest_facets_that_keep_their_outline_within_half_a_pixel():
    """facets(n): the polygon's sagitta for a geom OUTLINE_SHARE of the frame across is at most half a pixel, and one
    facet fewer would exceed it (the chord's distance from its arc, r (1 - cos(pi / n)))."""
    for longer in (16, 48, 84, 100, 240, 480, 640, 1080, 1920):
        radius = OUTLINE_SHARE * longer / 2
        n = facets(longer)
        assert radius * (1 - np.cos(np.pi / n)) <= 0.5 < radius * (1 - np.cos(np.pi / (n - 1)))


@linux
def test_frames_are_fitted_to_their_size_and_look_as_dm_controls(tmp_path):
    """An 84x84 frame is drawn in an 84x84 buffer with a 256 shadow map (SHADOW_TEXELS a pixel of its longer side) and
    round geoms of 11 x 7 facets, a later 640x480 one in a remade 640x480 buffer with a 2048 map and the file's 28 x 16
    facets (kept for the 84x84 frame after it), the model's own settings left as the file has them; the frames are
    dm_control's own render of the same state with the file's 1920x1080 buffer, 4096 map and facets, the floor drawn
    finite, but for the shadows' resolution and the outlines (a mean difference under 1 of 255, seen: 0.62 at 84x84
    with 11 facets, 0.07 with 28); and the floor drawn finite looks as MuJoCo's endless one (a mean difference under
    4 of 255, seen: 1.7 at 84x84, 3.0 at 640x480, where the checker's edge lines fall a pixel apart)."""
    done = subprocess.run([sys.executable, "-c", FITTED, str(tmp_path / "frames.npz")], env=_process_env(),
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    frames = np.load(tmp_path / "frames.npz")
    assert [frames[f"{i} fitted"].tolist() for i in range(3)] == [[84, 84, 256, 11, 7], [640, 480, 2048, 28, 16],
                                                                   [640, 480, 2048, 28, 16]]
    for i, shape in enumerate(((84, 84, 3), (480, 640, 3), (84, 84, 3))):
        ours, theirs, endless = frames[f"{i}"].astype(float)
        assert ours.shape == theirs.shape == shape and ours.std() > 10  # a picture, not a blank
        assert np.abs(ours - theirs).mean() < 1.0
        assert np.abs(theirs - endless).mean() < 4.0


KEPT_CAMERAS = """
import gc
import sys
import weakref
import numpy as np
from dm_control.mujoco import engine
from simbench import env
from simbench.outputs.drawn_planes import planes_drawn_finite
env_ = env.load_task("rsmg", "three_turns")
env_.reset()
physics, out = env_.physics, {}
camera = physics.model.ptr.camera(0).name
for kind, options in (("rgb", {}), ("depth", {"depth": True}), ("segmentation", {"segmentation": True})):
    for view in (0, camera, -1):
        first = physics.render(84, 84, camera_id=view, **options)
        kept = first.copy()
        for _ in range(20):  # the rotor turned on
            env_.step(np.zeros(env_.action_spec().shape))
        second = physics.render(84, 84, camera_id=view, **options)  # the kept Camera's next frame
        with planes_drawn_finite(physics.model.ptr):  # dm_control's own: a Camera made for the frame
            theirs = engine.Physics.render(physics, 84, 84, camera_id=view, **options)
        out[f"{kind} {view}"] = np.stack([first, kept, second, theirs])
out["cameras"] = np.array(len(physics._cameras))
before = physics.render(84, 84)  # the free camera, kept
physics.model.ptr.vis.global_.azimuth += 60  # the model's view of a free camera turned
moved = physics.render(84, 84)
with planes_drawn_finite(physics.model.ptr):
    out["free view"] = np.stack([before, moved, engine.Physics.render(physics, 84, 84)])
gc.disable()  # a physics no longer used is freed at once (its Cameras hold it weakly)
probe = env.load_task("puma600", "line")
probe.reset()
probe.physics.render(84, 84, camera_id=0)
freed = weakref.ref(probe.physics)
del probe
out["freed"] = np.array(freed() is None)
physics.reload_from_xml_string('<mujoco><worldbody><light pos="0 0 1"/><geom type="sphere" size=".1"/>'
                               '<camera name="c" pos="0 -1 0" xyaxes="1 0 0 0 0 1"/></worldbody></mujoco>')
physics.render(84, 84, camera_id="c")
context = physics.contexts.mujoco.ptr
out["reloaded"] = np.array([context.offWidth, context.offHeight, context.shadowSize])
np.savez(sys.argv[1], **out)
"""


@linux
def test_a_kept_camera_draws_dm_controls_frames_and_hands_out_its_own_copy(tmp_path):
    """A frame's Camera is kept for the next frame of its size and camera: its RGB, depth and segmentation frames
    (camera by index, by name, the free camera) are dm_control's own render of the same state (a Camera made for the
    frame) bit for bit, and a frame handed out stays as it was drawn after the next (of a later state, which looks
    otherwise); at most CAMERAS are kept; the kept free camera takes the model's view as it is at each frame (turned
    between two frames: dm_control's frame of the turned view); a physics no longer used is freed at once (the
    garbage collector off); a physics reloaded from another model fits its GL context again (an 84x84 buffer, a 256
    shadow map)."""
    done = subprocess.run([sys.executable, "-c", KEPT_CAMERAS, str(tmp_path / "frames.npz")], env=_process_env(),
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    frames = np.load(tmp_path / "frames.npz")
    for key in (k for k in frames.files if k not in ("cameras", "reloaded", "free view", "freed")):
        first, kept, second, theirs = frames[key]
        assert np.array_equal(first, kept) and not np.array_equal(second, first), key
        assert np.array_equal(second, theirs), key
        assert first.std() > 0, key  # a picture, not a blank
    assert frames["cameras"] <= CAMERAS
    before, moved, theirs = frames["free view"]
    assert not np.array_equal(moved, before) and np.array_equal(moved, theirs)
    assert frames["freed"]
    assert frames["reloaded"].tolist() == [84, 84, 256]


def test_visualize_reward_colours_the_arm_by_the_reward():
    """dm_control's meaning: at each reset and step the arm's geoms (those its joints move) take their own colour
    blended toward the suite's highlight by reward ** 4; nothing else changes colour."""
    env = simbench_env.load_task("puma600", "line", None, {"n_sub_steps": 10}, True)
    model = env.physics.model.ptr
    arm = _moving_geoms(model, model.actuator_trnid[env.task.plant.actuators, 0])
    own = model.geom_rgba.copy()  # MuJoCo draws a geom in its material's colour unless it sets its own rgba
    of_material = (model.geom_matid >= 0) & (own == [0.5, 0.5, 0.5, 1.0]).all(axis=1)
    own[of_material] = model.mat_rgba[model.geom_matid[of_material]]
    others = np.setdiff1d(np.arange(model.ngeom), arm)
    others_rgba = model.geom_rgba[others].copy()
    highlight = np.array([0.0, 0.5, 0.3, 1.0])  # dm_control's suite/common/materials.xml, self_highlight
    step = env.reset()
    policy = simbench_env.servo_policy(env)
    rewards = []
    for offset in (0.0, 0.0, 0.05, 0.15):  # on the path, then targets further and further off it
        step = env.step(policy(step) + offset)
        blend = step.reward ** 4
        np.testing.assert_allclose(model.geom_rgba[arm], blend * highlight + (1 - blend) * own[arm], atol=1e-6)
        assert np.array_equal(model.geom_rgba[others], others_rgba)
        rewards.append(step.reward)
    assert rewards[1] > 0.9 and rewards[-1] < 0.1  # from near the highlight to near the arm's own colour
    plain = simbench_env.load_task("puma600", "line", None, {"n_sub_steps": 10})
    rgba = plain.physics.model.ptr.geom_rgba.copy()
    plain.step(policy(plain.reset()) + 0.15)
    assert np.array_equal(plain.physics.model.ptr.geom_rgba, rgba)
    with pytest.raises(ValueError, match="visualize_reward must be a bool, got int"):
        env.visualize_reward = 1


def test_the_rsmgs_random_tasks_stay_within_the_action_spec():
    """24 seeded draws (turns of up to 5 rotor turns, and tumbles): every reference of every task a reset draws
    lies within the action spec, the same from reset to reset, and each is the generator's first draw (none
    drawn again for leaving the spec; 5 of 6 left it when a joint without a range was bounded by the shipped
    plan's span and pi)."""
    env = simbench_env.load_task("rsmg", "three_turns", task_kwargs={"random": 0})
    spec, generator = env.action_spec(), env.task.scenario.planner_def
    kinds = set()
    for seed in range(24):
        env.task.random = np.random.RandomState(seed)
        env.reset()
        q_ref, drawn = env.task.plan.q_ref, env.task.scenario
        assert (q_ref >= spec.minimum).all() and (q_ref <= spec.maximum).all(), seed
        assert env.action_spec() == spec
        first = generator.random_task(drawn.robot_def, np.random.RandomState(seed))
        assert drawn.timing.duration == first["timing"]["duration"], seed
        kinds.add(drawn.task.motion.kind)
    assert kinds == {"turns", "tumble"}
