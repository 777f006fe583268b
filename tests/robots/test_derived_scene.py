"""A derived arm's scene is lit and framed as the shipped robots' are (robots.model_stage): a frame of it is about as
bright as one of the shipped PUMA's scene, the arm's geoms cover a good share of it, in the video's renderer and in
an environment's, and the stage adds only what the model lacks, its floor colliding with the arm."""

from importlib.metadata import distribution

import mujoco
import numpy as np
import pytest

from simbench import env as simbench_env
from simbench.core.plant import compiled_scene
from simbench.robots.model_stage import CAMERA, FLOOR
from simbench.scenario.robot_mapping import load_robot
from simbench.scenario.schema import Units

ERD = distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data") / "robots"
UR5 = ERD / "ur_description" / "urdf" / "ur5_robot.urdf"
JACO = distribution("dm-control").locate_file("dm_control/third_party/kinova/jaco_arm.xml")
ARMS = {"ur5": {"model": str(UR5), "tool": {"body": "tool0"}},
        "jaco": {"model": str(JACO), "tool": {"site": "wristsite"}, "speed_limits": [0.6, 0.6, 0.6, 0.8, 0.8, 0.8]}}
SHIPPED_PUMA = "models/puma600/scene.xml"
BRIGHT = 0.75  # a derived arm's frame at least this share of the shipped PUMA's mean brightness
ARM_SHARE = 0.04  # the least share of a frame the arm's geoms cover at the reference pose
WIDTH, HEIGHT = 320, 240


def _frame(model: mujoco.MjModel, qpos: np.ndarray, camera: int | str) -> tuple[float, float]:
    """The mean brightness (of 255) of a frame of `model` at `qpos` from `camera`, and the share of its pixels that
    geoms on bodies its joints move cover."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    with mujoco.Renderer(model, height=HEIGHT, width=WIDTH) as renderer:
        renderer.update_scene(data, camera=camera)
        brightness = float(renderer.render().mean())
        renderer.enable_segmentation_rendering()
        renderer.update_scene(data, camera=camera)
        return brightness, _arm_share(model, renderer.render())


def _arm_share(model: mujoco.MjModel, segmentation: np.ndarray) -> float:
    """The share of a segmentation frame's pixels (object id, object type) that geoms on moved bodies cover."""
    ids = segmentation[..., 0][segmentation[..., 1] == mujoco.mjtObj.mjOBJ_GEOM]
    return float((model.body_weldid[model.geom_bodyid[ids]] != 0).sum() / segmentation[..., 0].size)


def _reference(robot, model: mujoco.MjModel) -> np.ndarray:
    """The scene's reference pose: qpos0, the arm's joints clipped into their ranges."""
    qpos = model.qpos0.copy()
    for name, lo, hi in zip(robot.joints, robot.lower, robot.upper):
        adr = model.joint(name).qposadr[0]
        qpos[adr] = np.clip(qpos[adr], lo, hi)
    return qpos


@pytest.fixture(scope="module")
def puma_brightness() -> float:
    model = compiled_scene(SHIPPED_PUMA)
    return _frame(model, model.qpos0, 0)[0]


@pytest.mark.parametrize("name", ARMS)
def test_a_derived_arms_frame_is_lit_and_filled_by_the_arm(name, puma_brightness):
    robot = load_robot(ARMS[name], "src", Units())
    model = compiled_scene(str(robot.scene))
    brightness, share = _frame(model, _reference(robot, model), model.camera(0).name)
    assert model.camera(0).name == CAMERA
    assert brightness > BRIGHT * puma_brightness and share > ARM_SHARE


def test_the_stage_adds_a_textured_colliding_floor_a_sky_and_lights():
    robot = load_robot(ARMS["ur5"], "src", Units())
    model = compiled_scene(str(robot.scene))
    floor = model.geom(FLOOR)
    assert robot.arm.added == ("floor", "sky", "lights", "camera")
    assert floor.contype[0] == floor.conaffinity[0] == 1 and model.mat_texid[floor.matid[0]].max() >= 0
    assert (model.tex_type == mujoco.mjtTexture.mjTEXTURE_SKYBOX).sum() == 1 and model.nlight == 2


def test_a_model_with_its_own_stage_keeps_it(tmp_path):
    path = tmp_path / "arm.xml"
    path.write_text("""<mujoco><worldbody><light name="own"/><camera name="own" pos="0 -2 1"/>
      <geom name="ground" type="plane" size="1 1 0.1"/>
      <body name="link"><joint name="j" axis="0 0 1"/><geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.05"/>
        <site name="tip" pos="0.5 0 0"/></body></worldbody></mujoco>""")
    robot = load_robot({"model": str(path), "tool": {"site": "tip"}, "speed_limits": [1]}, "src", Units())
    model = compiled_scene(str(robot.scene))
    assert robot.arm.added == ("sky",) and robot.arm.camera == "'own' (the model's, of 1)"
    assert model.ncam == model.nlight == 1 and model.ngeom == 2


def test_an_environments_render_of_a_derived_arm_is_lit(tmp_path, puma_brightness):
    scenario = tmp_path / "move.yaml"
    scenario.write_text(f"robot: {{model: {UR5}, tool: {{body: tool0}}}}\nplanner: joint_move\nunits: {{angle: deg}}\n"
                        "task: {start: [0, -60, 60, -90, -90, 0], goal: [30, -80, 90, -100, -60, 40]}\n"
                        "timing: {duration: 0.2, hold: 0.0}\n")
    env = simbench_env.load(str(scenario))
    env.reset()
    frame = env.physics.render(height=HEIGHT, width=WIDTH)
    segmentation = env.physics.render(height=HEIGHT, width=WIDTH, segmentation=True)
    assert frame.mean() > BRIGHT * puma_brightness
    assert _arm_share(env.physics.model.ptr, segmentation) > ARM_SHARE
