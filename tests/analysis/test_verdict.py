"""Honest status: a run that breaks a limit, a motor's force range or the scenario's tolerances does not end
`ok`, each broken promise checked against what the plan and the recording themselves show."""

import json

import mujoco
import numpy as np
import pytest
import yaml

import simbench
from simbench.cli import EXIT_LIMITS, main
from simbench.core.plant import Plant
from simbench.robots import puma600
from simbench.scenario import parse_scenario
from tests.conftest import scenario_file

# A torch line that in righty / up / noflip needs q4 beyond its range; righty / up / flip keeps 22 deg inside
# every range (found with Craig's IK, puma600.ik, over the 8 configurations).
BEYOND = {
    "robot": "puma600", "planner": "decoupled_path", "units": {"angle": "deg", "length": "mm"},
    "task": {"path": [{"line": {"start": [474, 62, -304], "end": [455, -95, -224]}}],
             "orientation": {"convention": "zyx", "value": [-119.5, 145.5, 24.1]},
             "configuration": {"arm": "righty", "elbow": "up", "wrist": "noflip"}},
    "timing": {"law": "quintic", "duration": 2.0, "hold": 0.3},
}


def _write(tmp_path, doc: dict, name: str = "scenario"):
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_a_puma_line_beyond_a_joint_range_ends_limits_with_its_exit_code(tmp_path, capsys):
    path = _write(tmp_path, BEYOND)
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "--no-video"]) == EXIT_LIMITS
    report = json.loads((out / "report.json").read_text())
    assert report["status"] == "limits"
    q_ref = np.load(out / "timeseries.npz")["q_ref"]
    beyond = {puma600.JOINTS[j] for j in range(6)
              if (q_ref[:, j] < puma600.LOWER[j] - 1e-9).any() or (q_ref[:, j] > puma600.UPPER[j] + 1e-9).any()}
    assert beyond  # the plan itself, read from the timeseries, leaves a range
    named = {v["joint"] for v in report["violations"] if v["kind"] == "joint_limit"}
    assert named == beyond
    printed = capsys.readouterr().out
    assert "status: limits" in printed and all(f"joint_limit: {j} is asked for" in printed for j in beyond)


def test_validate_names_the_plans_limits_without_simulating(tmp_path, capsys):
    path = _write(tmp_path, BEYOND)
    assert main(["validate", str(path)]) == EXIT_LIMITS
    printed = capsys.readouterr().out
    assert f"{path}: valid" in printed and "plan: limits" in printed and "joint_limit: q4" in printed
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scenario.yaml"]  # nothing written
    assert main(["validate", "--no-plan", str(path)]) == 0


def test_velocity_violations_are_the_joints_whose_commanded_speed_passes_the_limit(evaluated):
    """Against finite differences of the commanded trajectory, not the plan's own rates."""
    _, ev = evaluated("puma600", "wrist_singularity")
    traj = ev.trajectory
    speed = np.abs(np.gradient(traj.q_ref, traj.t, axis=0)).max(axis=0)
    over = {puma600.JOINTS[j] for j in np.flatnonzero(speed > puma600.QD_MAX * 1.01)}
    found = {v["joint"]: v for v in ev.verdict.violations if v["kind"] == "velocity_limit"}
    assert over == set(found) == {"q4", "q6"}
    for name, v in found.items():
        j = puma600.JOINTS.index(name)
        assert v["ratio"] == pytest.approx(speed[j] / puma600.QD_MAX[j], rel=0.01)


def test_actuator_saturation_is_where_the_servo_law_asks_more_than_the_force_range(evaluated):
    """The recorded forces are MuJoCo's; the servo's demand kp (ctrl - q) - kv qd is computed here from the
    model's gains: the saturation events are exactly where the demand passes the range."""
    scenario, ev = evaluated("spherical_arm", "case2")
    rec = ev.recording
    plant = Plant.load(scenario.robot_def, scenario.sim.timestep)
    m, act = plant.model, plant.actuators
    demand = m.actuator_gainprm[act, 0] * rec.ctrl[:, act] + m.actuator_biasprm[act, 1] * rec.q \
        + m.actuator_biasprm[act, 2] * rec.qd
    limit = np.abs(m.actuator_forcerange[act, 1])
    np.testing.assert_allclose(rec.force, np.clip(demand, -limit, limit), atol=1e-9)
    saturated = np.abs(demand) >= limit
    events = [e for e in ev.analysis.limit_events if e["kind"] == "actuator_saturation"]
    flagged = np.zeros_like(saturated)
    for e in events:
        j = scenario.robot_def.joints.index(e["detail"]["joint"])
        flagged[(rec.t >= e["t_start"] - 1e-12) & (rec.t <= e["t_end"] + 1e-12), j] = True
    assert saturated.any() and np.array_equal(flagged, saturated)
    assert {v["kind"] for v in ev.verdict.violations} >= {"actuator_saturation"}


def test_a_scenario_that_expects_a_failure_exits_0_only_for_that_failure(tmp_path, capsys):
    doc = yaml.safe_load(scenario_file("spherical_arm", "case3").read_text())
    assert doc["expect"]["violations"] == ["velocity_limit"]
    run = ["--no-video", "--out"]
    assert main(["run", str(_write(tmp_path, doc, "as_expected")), *run, str(tmp_path / "a")]) == 0
    del doc["expect"]
    assert main(["run", str(_write(tmp_path, doc, "unexpected")), *run, str(tmp_path / "b")]) == EXIT_LIMITS
    doc["expect"] = {"status": "limits", "violations": ["joint_limit"]}
    assert main(["run", str(_write(tmp_path, doc, "wrong")), *run, str(tmp_path / "c")]) == EXIT_LIMITS
    printed = capsys.readouterr().out
    assert "NOT as the scenario expects (limits: joint_limit); unexpected: velocity_limit; missing: joint_limit" \
        in printed
    report = json.loads((tmp_path / "c" / "report.json").read_text())
    assert report["status"] == "limits" and report["expected"]["met"] is False


def test_an_expectation_must_name_known_violations(tmp_path, capsys):
    doc = yaml.safe_load(scenario_file("spherical_arm", "case3").read_text())
    doc["expect"] = {"status": "limits", "violations": ["velocity_limt"]}
    path = _write(tmp_path, doc)
    assert main(["validate", str(path)]) == 2
    assert "expect.violations" in capsys.readouterr().err


def test_tolerances_decide_off_path(evaluated):
    """A tolerance below what the tool really did breaks the promise; one above keeps it."""
    scenario, ev = evaluated("puma600", "line")
    worst = ev.analysis.tracking["tool_max"]
    assert ev.verdict.status == "ok"
    doc = yaml.safe_load(scenario_file("puma600", "line").read_text())
    for tolerance, broken in ((0.5 * worst, True), (2 * worst, False)):
        doc["analysis"] = {**doc.get("analysis", {}), "path_tolerance": tolerance * 1e3}  # the file is in mm
        again = simbench.evaluate(parse_scenario(doc, "line"))
        assert ("off_path" in {v["kind"] for v in again.verdict.violations}) == broken


def test_without_gravity_compensation_the_servos_carry_the_arms_weight():
    """At rest on the start pose the actuators give the gravity torques MuJoCo computes for that pose (qfrc_bias
    with zero velocity, in a model without gravcomp); with the compensation on they give almost none."""
    doc = {**BEYOND, "task": {**BEYOND["task"], "configuration": {"arm": "righty", "elbow": "up",
                                                                  "wrist": "flip"}},
           "sim": {"settle": 1.0, "gravity_compensation": False}}
    heavy = simbench.evaluate(parse_scenario(doc, "heavy"))
    light = simbench.evaluate(parse_scenario({**doc, "sim": {"settle": 1.0}}, "light"))
    plant = Plant.load(puma600.ROBOT, gravity_compensation=False)
    data = mujoco.MjData(plant.model)
    data.qpos[:] = heavy.recording.qpos[0]
    mujoco.mj_forward(plant.model, data)
    gravity = data.qfrc_bias[plant.dof_adr]
    assert np.abs(gravity).max() > 10.0  # N m: the shoulder holds the arm
    np.testing.assert_allclose(heavy.recording.force[0], gravity, atol=0.02 * np.abs(gravity).max())
    assert np.abs(light.recording.force[0]).max() < 0.01 * np.abs(gravity).max()
