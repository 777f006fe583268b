"""The shipped controllers against independent truths (MuJoCo's mass matrix and bias forces, the servo they
replace), and a user's policy or controller through the CLI: tracked, reported, and refused in one line when it
is wrong."""

from __future__ import annotations

import json
import sys
import textwrap
from dataclasses import replace

import mujoco
import numpy as np
import pytest
import yaml
from simbench_planar3r import control as planar3r_control

import simbench
from simbench.cli import main
from simbench.core.plant import Plant
from simbench.physics.computed_torque import ComputedTorque, effective_inertia
from simbench.scenario import parse_scenario
from tests.conftest import scenario_file

PLANAR3R = planar3r_control.__file__.rsplit("/", 1)[0] + "/scenarios"


def with_control(robot: str, name: str, **control) -> simbench.Scenario:
    raw = yaml.safe_load(scenario_file(robot, name).read_text())
    raw["control"] = control
    return parse_scenario(raw, f"{robot}/{name}", default_name=name)


def test_the_feed_forward_is_the_rigid_body_dynamics_of_the_plan():
    """tau_ff = M(q) qdd + c(q, qd) - passive, with M from mj_fullM and c from qfrc_bias at the planned state:
    MuJoCo's inverse dynamics, checked against its forward-dynamics quantities."""
    scenario = with_control("puma600", "weld_seam", controller="computed_torque")
    plant = Plant.load(scenario.robot_def, scenario.sim.timestep, actuation="torque")
    traj = scenario.planner_def.plan(scenario, scenario.robot_def, float(plant.model.opt.timestep))
    ct = ComputedTorque()
    ct.bind(plant, traj)
    model, data = plant.model, mujoco.MjData(plant.model)
    qdd = np.gradient(traj.qd_ref, traj.dt, axis=0)
    full = np.zeros((model.nv, model.nv))
    for k in (0, len(traj.t) // 3, len(traj.t) // 2, len(traj.t) - 1):
        data.qpos[plant.qpos_adr], data.qvel[plant.dof_adr] = traj.q_ref[k], traj.qd_ref[k]
        mujoco.mj_forward(model, data)
        mujoco.mj_fullM(model, data, full)
        expected = full @ qdd[k] + data.qfrc_bias - data.qfrc_passive
        assert np.allclose(ct.tau_ff[k], expected[plant.dof_adr], rtol=1e-9, atol=1e-9)


def test_the_default_gains_come_from_the_inertia_the_joint_feels():
    """A serial arm's effective inertia is the diagonal of its mass matrix; an Agile Eye leg's is more than its
    own link's, as the other legs and the platform move with it."""
    for name, serial in (("puma600", True), ("agile_eye", False)):
        scenario = simbench.load_scenario(scenario_file(name, "weld_seam" if serial else "avoidance"))
        plant = Plant.load(scenario.robot_def, scenario.sim.timestep, actuation="torque")
        traj = scenario.planner_def.plan(scenario, scenario.robot_def, float(plant.model.opt.timestep))
        inertia = effective_inertia(plant, traj)
        data = mujoco.MjData(plant.model)
        data.qpos[:] = plant.initial_qpos(traj.q_ref[0])
        mujoco.mj_forward(plant.model, data)
        full = np.zeros((plant.model.nv, plant.model.nv))
        mujoco.mj_fullM(plant.model, data, full)
        own = np.diag(full)[plant.dof_adr]
        if serial:
            assert np.allclose(inertia, own, rtol=1e-6)
        else:
            assert (inertia > 1.02 * own).all()


@pytest.mark.parametrize("robot, name", [("spherical_arm", "case1"), ("puma600", "weld_seam")])
def test_computed_torque_tracks_a_serial_arm_far_better_than_the_servo(robot, name, evaluated):
    """With the model's own dynamics fed forward the PD only corrects what the plan's sampling leaves: the tool
    error is at least 5x smaller than the servo's, the run ok, and the report names the controller and gains."""
    _, servo = evaluated(robot, name)
    ev = simbench.evaluate(with_control(robot, name, controller="computed_torque"))
    assert ev.verdict.status == "ok"
    assert ev.analysis.tracking["tool_error_max"] < servo.analysis.tracking["tool_error_max"] / 5
    assert ev.control["controller"] == "computed_torque" and ev.control["actuation"] == "torque"
    assert len(ev.control["kp"]) == len(ev.control["kd"]) == len(servo.trajectory.q_ref[0])


def test_computed_torque_holds_the_agile_eyes_closed_chain():
    ev = simbench.evaluate(with_control("agile_eye", "avoidance", controller="computed_torque"))
    assert ev.verdict.status == "ok", ev.verdict
    assert "constrained" in ev.control["feedforward"]


def test_explicit_gains_are_used_and_reported():
    ev = simbench.evaluate(with_control("spherical_arm", "case1", controller="computed_torque",
                                        kp=[100, 2000, 100, 2000], kd=[5, 50, 5, 50]))
    assert ev.control["kp"] == [100, 2000, 100, 2000] and ev.control["kd"] == [5, 50, 5, 50]


def run_cli(args, capsys):
    code = main(args)
    return code, capsys.readouterr().err.strip().splitlines()


@pytest.mark.parametrize("scenario", ["line_policy", "line_joint_pd"])
def test_an_outside_policy_and_controller_run_through_the_cli(scenario, tmp_path, capsys):
    """The example package's policy and its controller (each an entry point, named in the scenario) track its line
    as its servo does (the same PD law), and report.json says which ran."""
    out = tmp_path / "out"
    code, _ = run_cli(["run", f"{PLANAR3R}/{scenario}.yaml", "--out", str(out), "--no-video", "--quiet"], capsys)
    report = json.loads((out / "report.json").read_text())
    assert code == 0 and report["status"] == "ok"
    assert report["control"]["actuation"] == "torque"
    assert report["tracking"]["tool_error_max"] < 1e-3
    assert {"timeseries.npz"} <= {p.name for p in out.iterdir()}


def _policy_scenario(tmp_path, module_body: str, policy: str = "userpolicy:make", action: str = "torque"):
    """A copy of the example's line with its policy taken from a module written into tmp_path."""
    (tmp_path / "userpolicy.py").write_text(textwrap.dedent(module_body))
    raw = yaml.safe_load(open(f"{PLANAR3R}/line_policy.yaml"))
    raw["control"] = {"controller": "policy", "policy": policy, "action": action}
    raw["timing"]["duration"] = 1.0
    path = tmp_path / "user.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


@pytest.fixture
def importable(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    yield
    sys.modules.pop("userpolicy", None)


@pytest.mark.parametrize("body, policy, expected", [
    ("", "userpolicy:make", "control.policy: cannot import userpolicy:make: AttributeError: module 'userpolicy' "
                            "has no attribute 'make'"),
    ("", "nosuchmodule.sub:make", "control.policy: cannot import nosuchmodule.sub:make: ModuleNotFoundError: No "
                                  "module named 'nosuchmodule'"),
    ("def make(scenario):\n    raise RuntimeError('no weights file')\n", "userpolicy:make",
     "control.policy: userpolicy:make raised RuntimeError: no weights file"),
    ("def make(scenario):\n    return 3\n", "userpolicy:make",
     "control.policy: userpolicy:make returned int, not a callable taking the observation"),
])
def test_a_policy_that_cannot_be_made_is_refused_before_the_run(body, policy, expected, tmp_path, capsys,
                                                                importable):
    path = _policy_scenario(tmp_path, body, policy)
    code, lines = run_cli(["run", str(path), "--out", str(tmp_path / "out"), "--quiet", "--allow-code"], capsys)
    assert (code, lines) == (2, [f"error: {path}: {expected}"])
    assert not (tmp_path / "out").exists()


def test_a_policy_name_that_is_not_module_colon_factory_is_a_field_error(tmp_path, capsys, importable):
    path = _policy_scenario(tmp_path, "", "userpolicy.make")
    code, lines = run_cli(["validate", str(path)], capsys)
    assert code == 2 and len(lines) == 1 and lines[0].startswith(f"error: {path}: control.policy:")


@pytest.mark.parametrize("act, when, cause", [
    ("return obs['q'] * (np.nan if obs['time'][0] > 0.5 else 0.0)", "at t = 0.5010 s",
     "controller 'policy' commanded nan to actuator 'q1'"),
    ("return np.zeros(2)", "while settling at the start pose (0.2000 s before the start)",
     "controller 'policy' raised ValueError: the policy's action has shape (2,); (3,) expected, one per joint "
     "(q1, q2, q3)"),
])
def test_a_bad_action_is_exit_1_with_the_time(act, when, cause, tmp_path, capsys, importable):
    body = f"import numpy as np\n\ndef make(scenario):\n    def act(obs):\n        {act}\n    return act\n"
    path = _policy_scenario(tmp_path, body)
    out = tmp_path / "out"
    code, lines = run_cli(["run", str(path), "--out", str(out), "--quiet", "--no-video", "--allow-code"], capsys)
    assert code == 1 and len(lines) == 1 and lines[0].startswith(f"run failed: control failed {when}: {cause}")
    report = json.loads((out / "report.json").read_text())
    assert report["status"] == "failed" and report["failure"]["cause"] == cause


def test_the_servo_follows_the_revised_rows_and_a_controller_without_revise_rows_still_hears_of_them():
    """After Servo.revise_rows(k0, k1) its commands equal those of the references revised whole (the rows outside
    k0..k1 were the same) and those of a servo bound to them afresh, for random spans; a controller that defines
    only `revise` gets the change through the default `revise_rows`."""
    from dataclasses import replace

    from simbench.api import Controller
    from simbench.physics.controllers import Servo

    scenario = simbench.load_scenario(scenario_file("rsmg", "three_turns"))
    plant = Plant.load(scenario.robot_def, scenario.sim.timestep)
    traj = scenario.planner_def.plan(scenario, scenario.robot_def, float(plant.model.opt.timestep))
    rng = np.random.default_rng(5)
    servo, whole = Servo(), Servo()
    servo.bind(plant, traj)
    whole.bind(plant, traj)
    q_ref, qd_ref = traj.q_ref.copy(), traj.qd_ref.copy()
    for _ in range(12):
        k0 = int(rng.integers(0, len(q_ref) - 1))
        k1 = int(rng.integers(k0 + 1, min(k0 + 2000, len(q_ref)) + 1))
        q_ref[k0:k1] += rng.normal(scale=0.01, size=(k1 - k0, q_ref.shape[1]))
        qd_ref[k0:k1] += rng.normal(scale=0.01, size=(k1 - k0, q_ref.shape[1]))
        servo.revise_rows(k0, k1, q_ref, qd_ref)
        whole.revise(k0, q_ref, qd_ref)
        assert np.array_equal(servo.open_loop(), whole.open_loop())
    fresh = Servo()
    fresh.bind(plant, replace(traj, q_ref=q_ref, qd_ref=qd_ref))  # every row from the revised references
    assert np.array_equal(servo.open_loop(), fresh.open_loop())

    class Heard(Controller):
        name, description = "heard", "records what revise is told"

        def commands(self, state):
            return np.zeros(plant.model.nu)

        def revise(self, k0, q_ref, qd_ref):
            self.told = (k0, q_ref)

    heard = Heard()
    heard.revise_rows(7, 9, q_ref, qd_ref)
    assert heard.told[0] == 7 and heard.told[1] is q_ref


def _line_servo():
    """The servo bound to the PUMA's line plan: (plant, plan, servo, its open-loop commands, Servo.targets of the
    whole plan)."""
    from simbench.physics.controllers import Servo

    scenario = simbench.load_scenario(scenario_file("puma600", "line"))
    plant = Plant.load(scenario.robot_def, scenario.sim.timestep)
    traj = scenario.planner_def.plan(scenario, scenario.robot_def, float(plant.model.opt.timestep))
    servo = Servo()
    servo.bind(plant, traj)
    return plant, traj, servo, servo.open_loop(), servo.targets(traj.q_ref, traj.qd_ref)


def test_the_servos_commands_found_as_asked_are_the_whole_plans_however_indexed():
    """The servo's open-loop commands are api.Commands, found a few rows at a time as the run asks: indexed as
    NumPy indexes an array (a row, a negative row, a 0-d array, a list, a mask, slices, row numbers in any order
    or of any shape, and with columns after, paired with row numbers as NumPy pairs them), they are the servo's
    targets for the whole plan at once (Servo.targets of every reference), and np.asarray gives them all; the
    run's recorded commands are those rows, at a recording stride too."""
    from simbench.api import Commands
    from simbench.physics.sim import simulate

    plant, traj, servo, commands, whole = _line_servo()
    assert isinstance(commands, Commands) and commands.shape == whole.shape and len(commands) == len(traj.t)
    act = plant.actuators
    rows = np.random.default_rng(3).integers(0, len(whole), 50)
    mask = np.zeros(len(whole), bool)
    mask[::97] = True
    pairs = np.array([5, 1, 7]), np.array([0, 2, 1])
    for index in (7, -1, np.int64(4), np.array(3), [1, 2, 3], mask, slice(10, 400, 3), slice(None, None, -5),
                  slice(None), rows, np.array([], int), (slice(None), act), (rows, 2), (slice(5, 9), act[1]),
                  (4, act[0]), pairs, (pairs[0][:, None], pairs[1]), (mask, 0), (3, slice(1, 4)), (3,)):
        assert np.array_equal(commands[index], whole[index]), index
    assert np.array_equal(np.asarray(commands), whole)
    assert np.array_equal(simulate(plant, traj, servo).ctrl, whole)
    thin = simulate(plant, traj, servo, record_every=7)
    assert np.array_equal(thin.ctrl, whole[thin.kept])




def test_the_servos_commands_read_from_the_stretch_kept_are_those_of_the_references_now():
    """The servo keeps the last stretch of commands it found for a slice and reads later rows within it from
    there (a run checks its commands, steps them and records them: found once): what it returns is the caller's
    to change without changing what it returns next, rows outside the stretch are found afresh, and once the
    references are revised the stretch kept is not read: every row is Servo.targets of the references then."""
    _, traj, servo, commands, whole = _line_servo()
    inside, across = np.array([100, 0, 150, 101, 100]), np.array([190, 250, 10])
    first = commands[0:200]
    assert np.array_equal(first, whole[:200])
    first[:] = np.nan  # the caller's own
    for index in (inside, across, slice(50, 120), slice(150, 210), np.array([-1, 5])):
        got = commands.rows(index)
        assert np.array_equal(got, whole[index]), index
        got[:] = np.nan
        assert np.array_equal(commands.rows(index), whole[index]), index
    assert np.array_equal(commands[0:200], whole[:200])  # kept again: rows 0..199
    q_ref, qd_ref = traj.q_ref + 0.01, traj.qd_ref * 2.0
    servo.revise(0, q_ref, qd_ref)
    revised = servo.targets(q_ref, qd_ref)
    assert not np.array_equal(revised[inside], whole[inside])
    for index in (inside, slice(0, 200), across):
        assert np.array_equal(commands.rows(index), revised[index]), index
@pytest.mark.parametrize("robot, name", [("rsmg", "three_turns"), ("puma600", "line")])
def test_computed_torque_redoes_the_feedforward_only_where_the_revised_rows_reach(robot, name):
    """revise_rows over random spans (and `revise` to the end) leaves the controller as binding it to the revised
    references would, bit for bit: on the RSMG (constrained: the acceleration's feed-forward is taken each step)
    qdd_ref, np.gradient of the whole revised qd_ref; on a serial arm also its inverse dynamics tau_ff, redone
    only at the rows the change reaches."""
    scenario = with_control(robot, name, controller="computed_torque")
    plant = Plant.load(scenario.robot_def, scenario.sim.timestep, actuation="torque")
    traj = scenario.planner_def.plan(scenario, scenario.robot_def, float(plant.model.opt.timestep))
    ct = ComputedTorque()
    ct.bind(plant, traj)
    assert (ct.tau_ff is None) == (robot == "rsmg")
    rng = np.random.default_rng(8)
    q_ref, qd_ref = traj.q_ref.copy(), traj.qd_ref.copy()
    n = len(q_ref)
    spans = [(0, 1), (0, 3), (n - 1, n), (n - 3, n), *((int(a), int(a) + int(rng.integers(1, 500)))
                                                       for a in rng.integers(1, n - 600, 10)), (n // 2, n)]
    for k0, k1 in spans:
        q_ref[k0:k1] += rng.normal(scale=0.01, size=(k1 - k0, q_ref.shape[1]))
        qd_ref[k0:k1] += rng.normal(scale=0.01, size=(k1 - k0, q_ref.shape[1]))
        if k1 == n:
            ct.revise(k0, q_ref, qd_ref)
        else:
            ct.revise_rows(k0, k1, q_ref, qd_ref)
        fresh = ComputedTorque()
        fresh.bind(plant, replace(traj, q_ref=q_ref.copy(), qd_ref=qd_ref.copy()))
        assert np.array_equal(ct.qdd_ref, fresh.qdd_ref), (k0, k1)
        assert ct.tau_ff is None or np.array_equal(ct.tau_ff, fresh.tau_ff), (k0, k1)
