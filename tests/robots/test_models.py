"""Every robot's MJCF, in the manner of Menagerie's model tests: loads, steps, stays finite, is deterministic."""

import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest

from simbench.api import registry

ROBOTS = sorted(registry.robots())


def robot_xml(name: str):
    return ET.parse(registry.robots()[name].scene.parent / f"{name}.xml")


@pytest.mark.parametrize("name", ROBOTS)
def test_every_body_has_explicit_inertial(name):
    bodies = [b for b in robot_xml(name).iter("body") if b.find("joint") is not None or b.find("freejoint") is not None]
    assert bodies
    assert all(b.find("inertial") is not None for b in bodies), [b.get("name") for b in bodies]


@pytest.mark.parametrize("name", ROBOTS)
def test_scene_has_cameras_keyframe_tool_site_and_named_actuators(name):
    robot = registry.robots()[name]
    model = mujoco.MjModel.from_xml_path(str(robot.scene))
    assert model.ncam >= 2
    assert model.key("home").id >= 0
    assert model.site(robot.tool_site).id >= 0
    assert [model.actuator(j).name for j in robot.joints] == list(robot.joints)
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    for j, joint in enumerate(robot.joints):
        jnt = model.joint(joint)
        if np.isfinite(robot.lower[j]):
            assert jnt.range.tolist() == pytest.approx([robot.lower[j], robot.upper[j]])


def random_rollout(model: mujoco.MjModel, seed: int, steps: int = 2000) -> np.ndarray:
    rng = np.random.default_rng(seed)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    lo, hi = model.actuator_ctrlrange.T
    lo = np.where(model.actuator_ctrllimited, lo, -np.pi)
    hi = np.where(model.actuator_ctrllimited, hi, np.pi)
    out = np.empty((steps, model.nq))
    for k in range(steps):
        if k % 200 == 0:
            data.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_step(model, data)
        out[k] = data.qpos
    assert all(w.number == 0 for w in data.warning), [mujoco.mjtWarning(i).name for i, w in
                                                     enumerate(data.warning) if w.number]
    return out


@pytest.mark.parametrize("name", ROBOTS)
def test_random_controls_step_without_warnings_and_stay_finite(name):
    model = mujoco.MjModel.from_xml_path(str(registry.robots()[name].scene))
    qpos = random_rollout(model, seed=0)
    assert np.all(np.isfinite(qpos))


@pytest.mark.parametrize("name", ROBOTS)
def test_stepping_is_deterministic(name):
    model = mujoco.MjModel.from_xml_path(str(registry.robots()[name].scene))
    assert np.array_equal(random_rollout(model, seed=3, steps=500), random_rollout(model, seed=3, steps=500))
