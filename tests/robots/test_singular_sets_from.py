"""Robot.singular_sets_from: the sets the analysis makes from measures it has already computed are the sets
`singular_sets` computes from the recording, number for number, on every shipped robot's runs and on random
joint values (PUMA 600) and random joint noise (RSMG), where the measures are those very gaps."""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from simbench.robots import Tolerance, puma600

TOL = Tolerance(np.deg2rad(5.0), 0.01)


def assert_same_sets(robot, rec):
    """singular_sets_from(rec, tol, measures(rec)) equals singular_sets(rec, tol), bit for bit."""
    direct = robot.singular_sets(rec, TOL)
    given = robot.singular_sets_from(rec, TOL, robot.measures(rec))
    assert [(s.name, s.family, s.condition) for s in given] == [(s.name, s.family, s.condition) for s in direct]
    for a, b in zip(given, direct):
        np.testing.assert_array_equal(a.distance, b.distance)
        assert a.gaps.keys() == b.gaps.keys()
        for key in a.gaps:
            np.testing.assert_array_equal(a.gaps[key], b.gaps[key])


@pytest.mark.parametrize(("robot", "name"), [("spherical_arm", "case2"), ("puma600", "wrist_singularity"),
                                             ("puma600", "circle"), ("agile_eye", "through_singularity"),
                                             ("rsmg", "three_turns")])
def test_the_sets_from_the_measures_are_the_sets_of_the_run(evaluated, robot, name):
    scenario, ev = evaluated(robot, name)
    assert_same_sets(scenario.robot_def, ev.recording)


def test_puma600_on_random_joint_values():
    """300 random configurations within the joint ranges, and 50 on each singular set (where the gaps are 0)."""
    rng = np.random.default_rng(23)
    q = rng.uniform(puma600.LOWER, puma600.UPPER, size=(450, 6))
    q[300:350, 4] = 0.0  # wrist
    q[350:400, 2] = puma600.STRETCH  # elbow
    assert_same_sets(puma600.ROBOT, SimpleNamespace(q=q))


def test_rsmg_on_noisy_joints(evaluated):
    """The RSMG's run with its joints moved by random noise (seeded): other grips' gammas and minors."""
    scenario, ev = evaluated("rsmg", "three_turns")
    rng = np.random.default_rng(29)
    for _ in range(5):
        noisy = replace(ev.recording, q=ev.recording.q + rng.normal(0.0, 0.3, ev.recording.q.shape))
        assert_same_sets(scenario.robot_def, noisy)
