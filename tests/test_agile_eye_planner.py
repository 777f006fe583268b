"""Paper 003's planner: the smoothness of the bent path, and the avoidance of the obstacle and the singularity
checked with the exact forward kinematics."""

import numpy as np
import pytest

from simbench.planners import avoidance_4567 as method
from simbench.robots import agile_eye as E
from simbench.timing import TimeLaw


@pytest.mark.parametrize("order", range(4))
def test_bump_and_its_first_three_derivatives_vanish_at_both_ends(order):
    """Near each end the k-th derivative of b must shrink as eps^(4 - k) (a fourth-order zero): ten times closer,
    10^(4 - k) times smaller (within the next term's share at eps = 0.01; a zero of another order is 10 times
    off)."""
    small, big = (np.abs(method.bump(np.array([eps, 1 - eps]), order)) for eps in (1e-3, 1e-2))
    np.testing.assert_allclose(small / big, 10.0 ** -(4 - order), rtol=0.15)
    assert method.bump(np.array([0.5]))[0] == pytest.approx(1.0)
    assert np.all(method.bump(np.array([-0.1, 1.1]), order) == 0.0)


def smooth_plan():
    law = TimeLaw("4567", 4.0)
    windows = (method.Window(0.7, 1.0, np.array([0.6, -0.8, 0.0]), 0.3),
               method.Window(2.2, 1.0, np.array([0.0, 0.6, 0.8]), 0.2))
    return method.Plan(np.array([0.1, -0.2, 0.3]), np.array([1.2, 0.4, -0.9]), law, windows)


@pytest.mark.parametrize("order", range(4))
def test_planned_path_is_continuous_in_position_velocity_acceleration_and_jerk(order):
    plan = smooth_plan()
    for edge in (0.7, 1.7, 2.2, 3.2):  # the windows' ends
        # Across a continuous function the step shrinks with the gap; across a jump it would not.
        steps = [np.abs(np.subtract(*plan.theta(np.array([edge + eps, edge - eps]), order))).max()
                 for eps in (1e-4, 1e-6)]
        assert steps[1] < 0.05 * steps[0] + 1e-9
    ends = plan.theta(np.array([0.0, 4.0]), order)
    if order:
        assert np.abs(ends).max() < 1e-9  # at rest, no acceleration and no jerk at both ends


def test_derivatives_are_those_of_the_path():
    plan = smooth_plan()
    t = np.linspace(0.0, 4.0, 40001)
    for order in range(1, 4):
        fd = np.gradient(plan.theta(t, order - 1), t, axis=0)
        assert np.abs(fd - plan.theta(t, order))[5:-5].max() < 1e-3 * max(1.0, np.abs(fd).max())


def test_avoidance_scenario_plain_path_violates_and_optimised_path_clears(evaluated):
    scenario, ev = evaluated("agile_eye", "avoidance")
    info = ev.trajectory.info
    need = info["margins"]
    plain = info["plain_path"]["clearance"]
    assert plain["obstacle1"] < 0  # the plain 4-5-6-7 path runs through the obstacle
    assert plain["type2"] < np.deg2rad(5)  # and within 5 deg of a type 2 singular curve
    # The optimised path keeps every margin, by the exact FK of the planned joints, recomputed here.
    theta = ev.trajectory.q_ref
    rot = E.fk_track(theta, scenario.task.start.matrix())
    clear = method.clearances(scenario.task, theta, rot)
    for name, margin in need.items():
        assert clear[name].min() >= margin - 1e-9, name
    assert E.kci(theta, rot).mean() >= 0.30  # the paper's 0.30-0.42
    assert np.rad2deg(E.rotation_angle(rot[-1:], scenario.task.goal.matrix()[None]))[0] < 1e-4
    for window in info["windows"]:
        assert window["feasible"]
        assert {"alpha", "beta", "gamma", "L"} <= set(window)
        assert window["alpha"] ** 2 + window["beta"] ** 2 + window["gamma"] ** 2 == pytest.approx(1.0, abs=1e-6)
    assert any(w["estimator"] == "network" for w in info["windows"])


def test_through_singularity_plan_reports_the_crossing(evaluated):
    _, ev = evaluated("agile_eye", "through_singularity")
    assert ev.trajectory.info["singular_crossings"]
    assert any("may change assembly mode" in w for w in ev.trajectory.warnings)
    assert {v["kind"] for v in ev.trajectory.violations} == {"clearance_margin", "singular_crossing", "goal_missed"}
    assert ev.verdict.as_expected
