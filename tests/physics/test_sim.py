"""The simulator's stepping paths against each other and against MuJoCo's own functions: the closed-loop loop
(mj_step1, a controller, mj_step2) against mujoco.rollout's open loop, faults and bad commands stopped at the
right step, torque actuation against the MJCF's force ranges, actuators found by their joint, and the state a
controller is shown against a fresh forward pass."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import yaml

import simbench
from simbench.api import Controller, State, registry
from simbench.core.errors import ControlError, PhysicsError, RegistryError
from simbench.core.faults import MAX_SPEED
from simbench.core.plant import Plant, scene_spec
from simbench.physics.controllers import Servo
from simbench.physics.sim import simulate
from simbench.scenario import parse_scenario
from tests.conftest import scenario_file


def shipped(robot: str, name: str, duration: float | None = None, **sections) -> simbench.Scenario:
    """A shipped scenario, its duration shortened and sections replaced where asked."""
    raw = yaml.safe_load(scenario_file(robot, name).read_text())
    if duration is not None:
        raw["timing"] = {**raw["timing"], "duration": duration, "hold": 0.1}
    raw.update(sections)
    return parse_scenario(raw, f"{robot}/{name}", default_name=name)


def planned(scenario: simbench.Scenario, actuation: str = "position") -> tuple[Plant, object]:
    robot = scenario.robot_def
    plant = Plant.load(robot, scenario.sim.timestep, actuation=actuation)
    return plant, scenario.planner_def.plan(scenario, robot, float(plant.model.opt.timestep))


class ClosedServo(Servo):
    """The servo's very commands, asked for step by step: the closed-loop path with an open-loop law."""

    name = "closed_servo"

    def open_loop(self):
        return None


@pytest.mark.parametrize("robot, name", [("spherical_arm", "demo"), ("rsmg", "three_turns")])
def test_the_closed_loop_stepper_equals_rollout(robot, name):
    """mj_step1 + mj_step2 in Python and mujoco.rollout in C take the same steps: the same recording to the
    last bit of rounding, on an arm and on the RSMG with its weld switches and its plan's feedback."""
    plant, traj = planned(shipped(robot, name))
    fast = simulate(plant, traj, Servo())
    slow = simulate(plant, traj, ClosedServo())
    assert fast.q.shape == slow.q.shape
    assert np.abs(fast.qpos - slow.qpos).max() < 1e-12
    assert np.abs(fast.force - slow.force).max() < 1e-9
    assert np.array_equal(fast.ctrl, slow.ctrl)
    for eq in fast.eq_active:
        assert np.array_equal(fast.eq_active[eq], slow.eq_active[eq])
    if robot == "rsmg":
        assert fast.q_ref is not None and np.array_equal(fast.q_ref, slow.q_ref)  # the feedback revised both


class Scripted(Controller):
    """Zero torque, except what `bad(k)` returns from sample k on (NaN, the wrong shape, or an exception)."""

    name = "scripted"
    description = "test controller"
    actuation = "torque"

    def __init__(self, bad, at: int):
        self.bad, self.at = bad, at

    def bind(self, plant, trajectory):
        self.nu = plant.model.nu

    def commands(self, state: State):
        return self.bad(self.nu) if state.k >= self.at else np.zeros(self.nu)


def _boom(nu):
    raise KeyError("no gain for q3")


@pytest.mark.parametrize("bad, cause", [
    (lambda nu: np.full(nu, np.nan), "controller 'scripted' commanded nan to actuator 'q1'"),
    (lambda nu: np.zeros(nu + 1), "controller 'scripted' returned commands of shape (5,); (4,) expected, one per "
                                  "actuator"),
    (_boom, "controller 'scripted' raised KeyError: 'no gain for q3'"),
])
def test_a_bad_command_stops_the_run_at_its_time_with_what_came_before(bad, cause):
    plant, traj = planned(shipped("spherical_arm", "case1", duration=1.0), "torque")
    with pytest.raises(ControlError) as caught:
        simulate(plant, traj, Scripted(bad, at=250), settle=0.05)
    err = caught.value
    assert err.cause == cause and str(err).startswith("control failed at t = 0.2500 s")
    assert err.recording.t.size == 250 and np.isclose(err.recording.t[-1], 0.249)  # the rows before it
    assert np.isfinite(err.recording.qpos).all()


def test_a_bad_command_while_settling_has_no_recording():
    plant, traj = planned(shipped("spherical_arm", "case1", duration=1.0), "torque")
    with pytest.raises(ControlError, match=r"control failed while settling .*0\.0500 s before") as caught:
        simulate(plant, traj, Scripted(lambda nu: np.full(nu, np.inf), at=0), settle=0.05)
    assert caught.value.recording is None


class Kick(Controller):
    """Zero torque, then from sample `at` a huge one on every joint: the physics must diverge."""

    name = "kick"
    description = "test controller"
    actuation = "torque"

    def bind(self, plant, trajectory):
        self.nu = plant.model.nu

    def commands(self, state: State):
        return np.full(self.nu, 1e12 if state.k >= 100 else 0.0)


def test_diverging_physics_under_closed_loop_control_is_stopped_at_the_first_unsound_step():
    scenario = shipped("spherical_arm", "case1", duration=1.0)
    plant = Plant.load(scenario.robot_def, scenario.sim.timestep, force_limits=False, actuation="torque")
    traj = scenario.planner_def.plan(scenario, scenario.robot_def, float(plant.model.opt.timestep))
    with pytest.raises(PhysicsError) as caught:
        simulate(plant, traj, Kick(), settle=0.0)
    rec = caught.value.recording
    assert rec is not None and rec.t.size >= 100
    assert np.isfinite(rec.qpos).all() and np.abs(rec.qd).max() <= MAX_SPEED  # every kept row is sound
    assert "passed 1000 rad/s" in caught.value.cause or "NaN" in caught.value.cause


class Constant(Controller):
    """A constant command on every actuator."""

    name = "constant"
    description = "test controller"
    actuation = "torque"

    def __init__(self, u: float):
        self.u = u

    def bind(self, plant, trajectory):
        self.nu = plant.model.nu

    def commands(self, state: State):
        return np.full(self.nu, self.u)


def test_torque_actuation_applies_the_command_within_the_mjcf_force_range():
    """A motor's force is its command, clamped to the force range the MJCF gives the servo (read here from the
    spec, not from simbench's plant)."""
    scenario = shipped("puma600", "weld_seam", duration=0.2)
    plant, traj = planned(scenario, "torque")
    spec = scene_spec(str(scenario.robot_def.scene)).compile()
    bound = np.array([abs(spec.actuator(name).forcerange).min() if spec.actuator(name).forcelimited else np.inf
                      for name in scenario.robot_def.joints])
    small = 0.5 * bound.min()
    rec = simulate(plant, traj, Constant(small), settle=0.0)
    assert np.allclose(rec.force[:-1], small)
    rec = simulate(plant, traj, Constant(1e6), settle=0.0)
    assert np.allclose(rec.force[:-1], bound)


class Probe(Controller):
    """Zero commands; keeps what the state showed at a few steps."""

    name = "probe"
    description = "test controller"

    def bind(self, plant, trajectory):
        self.servo = Servo()
        self.servo.bind(plant, trajectory)
        self.seen = []

    def commands(self, state: State):
        if state.k in (0, 300, 700):
            d = state.data
            self.seen.append((state.qpos.copy(), state.qvel.copy(), d.qfrc_bias.copy(), d.sensordata.copy()))
        return self.servo.commands(state)


def test_a_controller_sees_the_data_of_the_state_it_is_asked_about():
    """What the State's data holds (bias forces, sensors) equals a fresh mj_forward at that state's qpos, qvel."""
    plant, traj = planned(shipped("puma600", "weld_seam", duration=1.0))
    probe = Probe()
    simulate(plant, traj, probe, settle=0.0)
    fresh = mujoco.MjData(plant.model)
    assert len(probe.seen) >= 3
    for qpos, qvel, bias, sensors in probe.seen:
        fresh.qpos[:], fresh.qvel[:] = qpos, qvel
        mujoco.mj_forward(plant.model, fresh)
        assert np.allclose(bias, fresh.qfrc_bias, atol=1e-12)
        tool = plant.sensors[plant.robot.tool_sensor]
        assert np.allclose(sensors[tool], fresh.sensordata[tool], atol=1e-12)


def test_actuators_are_found_by_the_joint_they_drive(tmp_path):
    """Renaming the actuators changes nothing; a joint driven by two actuators is refused naming it."""
    robot = registry.robots()["spherical_arm"]
    spec = mujoco.MjSpec.from_file(str(robot.scene))
    for actuator in spec.actuators:
        actuator.name = "motor_" + actuator.name
    renamed = _robot_with_scene(robot, spec, tmp_path / "renamed")
    plant = Plant.load(renamed)
    assert [plant.model.actuator(a).name for a in plant.actuators] == [f"motor_{j}" for j in robot.joints]
    spec.add_actuator(name="twin", target=robot.joints[2], trntype=mujoco.mjtTrn.mjTRN_JOINT)
    with pytest.raises(RegistryError, match=f"joint '{robot.joints[2]}' is driven by 2 actuators"):
        Plant.load(_robot_with_scene(robot, spec, tmp_path / "twin"))


def _robot_with_scene(robot, spec: mujoco.MjSpec, folder) -> object:
    """The robot with its scene replaced by `spec` written into `folder` (meshes and includes flattened)."""
    import copy

    folder.mkdir()
    path = folder / "scene.xml"
    path.write_text(spec.to_xml())
    clone = copy.copy(robot)
    clone.scene = path
    return clone
