"""Project issue 19 on the Agile Eye: the physics starts in the plan's assembly mode, and a path across a type 2
singular curve is bent or searched round it, or refused, or (accepted) reported as what it breaks. Each is
checked against an independent truth: MuJoCo's body pose of the platform, the exact FK along the plan's own
joint samples."""

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import simbench
from simbench.core.errors import RunError
from simbench.core.plant import Plant
from simbench.physics.sim import simulate
from simbench.physics.switches import at_start
from simbench.robots import agile_eye as E
from simbench.scenario import parse_scenario

DT = 0.0005


def scenario(task: dict, duration: float = 3.0):
    """An avoidance_4567 scenario for the task (angles in degrees)."""
    return parse_scenario({"robot": "agile_eye", "planner": "avoidance_4567", "units": {"angle": "deg", "length": "m"},
                           "task": task, "timing": {"law": "4567", "duration": duration, "hold": 0.0}}, "test")


def quat(rot: np.ndarray) -> dict:
    x, y, z, w = Rotation.from_matrix(rot).as_quat()
    return {"convention": "quat", "value": [float(w), float(x), float(y), float(z)]}


def plan(sc):
    return sc.planner_def.plan(sc, E.ROBOT, DT)


def test_platform_at_step_0_is_the_planned_start_for_200_random_starts():
    """Uniform in SO(3) (the base joints have no limits): MuJoCo's platform pose after the start-up (passive
    joints assembled, the plan's `initial` set) within 0.1 deg of the commanded start, every one."""
    plant = Plant.load(E.ROBOT)
    errors = []
    for rot in Rotation.random(200, random_state=np.random.default_rng(19)).as_matrix():
        # A motion of no length: only the start-up matters; starts near a singular curve break the default
        # 10 deg margin, accepted here.
        traj = plan(scenario({"start": quat(rot), "goal": quat(rot), "avoidance": {"enabled": False, "window": 0.01},
                              "accept_margin_violation": True}, duration=0.01))
        model, data, _ = at_start(plant, traj)
        mujoco.mj_kinematics(model, data)
        posed = data.body("platform").xmat.reshape(1, 3, 3)
        # and after the settling the run starts with (sim.simulate), at the recording's first row
        settled = E.quat_to_matrix(simulate(plant, traj).sensors["platform_quat"][:1])
        errors.append([E.rotation_angle(r, rot[None])[0] for r in (posed, settled)])
    assert np.all(np.rad2deg(np.max(errors, axis=0)) < 0.1)


def test_far_start_runs_ok_in_the_plans_assembly_mode():
    """The issue's case: 150 deg of roll at the start, 120 at the goal; before, the physics started 180 deg away."""
    sc = scenario({"start": {"convention": "zyx", "value": [0, 0, 150]},
                   "goal": {"convention": "zyx", "value": [0, 0, 120]}}, duration=2.0)
    ev = simbench.evaluate(sc)
    assert ev.verdict.status == "ok", ev.verdict.violations
    assert ev.analysis.extra["orientation_error_max"] < np.deg2rad(1.0)


def exact_check(task, q_ref: np.ndarray) -> dict:
    """The plan's platform by the exact FK followed along its own joint samples: least angle to the singular
    curves, det A sign changes, end errors."""
    rot = E.fk_track(q_ref, task.start.matrix())
    det = np.linalg.det(E.jacobians(q_ref, rot)[0])
    return {"gap": E.axis_gaps(rot).min(), "flips": int(np.sum(det[1:] * det[:-1] < 0)),
            "start": E.rotation_angle(rot[:1], task.start.matrix()[None])[0],
            "goal": E.rotation_angle(rot[-1:], task.goal.matrix()[None])[0]}


CROSSING = {"start": {"convention": "zyx", "value": [2.6, 61.9, 56.1]},  # through_singularity.yaml's ends
            "goal": {"convention": "zyx", "value": [-175.3, -48.4, -1.0]}}


def test_crossing_path_is_bent_to_keep_the_margin_or_refused():
    sc = scenario(CROSSING)
    assert plan(scenario({**CROSSING, "avoidance": {"enabled": False},
                          "accept_margin_violation": True})).info["singular_crossings"]  # the plain path crosses
    try:
        traj = plan(sc)
    except RunError as err:
        assert "margin 10.00 deg" in str(err) and "clearance" in str(err)
        return
    check = exact_check(sc.task, traj.q_ref)
    assert check["gap"] >= sc.task.singularity_clearance - 1e-9
    assert check["flips"] == 0
    assert max(check["start"], check["goal"]) < 1e-6
    assert traj.violations == () and traj.warnings == ()


def test_no_path_keeping_the_margin_is_refused_naming_margin_and_best_clearance():
    """Identity to a half turn about x keeping 80 deg from every singular curve: the ends keep it (90 deg), no
    path between them does."""
    task = {"start": {"convention": "zyx", "value": [0, 0, 0]}, "goal": {"convention": "zyx", "value": [0, 0, 180]},
            "singularity_clearance": 80, "avoidance": {"time_budget": 1.0}}
    with pytest.raises(RunError, match=r"type2 clearance \d+\.\d\d deg \(margin 80\.00 deg, "
                                       r"task\.singularity_clearance\).*accept_margin_violation"):
        plan(scenario(task))


def test_accepted_crossing_is_handed_over_with_its_violations_and_warnings():
    traj = plan(scenario({**CROSSING, "avoidance": {"enabled": False}, "accept_margin_violation": True,
                          "kci_min": 0.1}))
    kinds = {v["kind"]: v for v in traj.violations}
    assert set(kinds) == {"clearance_margin", "singular_crossing", "goal_missed"}
    margins = [v["message"] for v in traj.violations if v["kind"] == "clearance_margin"]
    assert any(m.startswith("type2 clearance") for m in margins) and any(m.startswith("kci") for m in margins)
    assert 0.9 < kinds["singular_crossing"]["t"] < 1.0  # where the platform meets the curve (about 0.93 s)
    assert kinds["goal_missed"]["error"] > np.deg2rad(90)
    # The KCI is a number, not an angle (it once printed "clearance 0.48 deg is below its margin 5.73 deg").
    kci = [w for w in traj.warnings if w.startswith("kci")]
    assert kci and "deg" not in kci[0] and "floor 0.100" in kci[0]
    assert any("singular surface" in w for w in traj.warnings)
