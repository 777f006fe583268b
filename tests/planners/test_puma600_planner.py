"""Paper 002's method on random reachable lines and arcs: on the path, and equal to Craig's analytic IK."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from simbench.maths.paths import Arc, Line
from simbench.planners import decoupled_path as method
from simbench.robots import puma600 as P

S = np.linspace(0.0, 1.0, 2001)


def random_paths(n: int, seed: int):
    """(path, rotation, flags) for random lines and arcs whose tool points the arm reaches."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        rot = Rotation.random(random_state=rng).as_matrix()
        flags = rng.choice([-1.0, 1.0], size=3)
        if rng.random() < 0.5:
            a, b = rng.uniform([-0.7, -0.7, -0.6], [0.7, 0.7, 0.5], size=(2, 3))
            path = Line(a, b)
        else:
            path = Arc.from_plane(rng.uniform([-0.5, -0.5, -0.4], [0.5, 0.5, 0.3]), rng.uniform(0.03, 0.25),
                                  rng.normal(size=3), *np.sort(rng.uniform(-np.pi, 2 * np.pi, 2)))
        rots = np.broadcast_to(rot, (S.size, 3, 3))
        q = method.solve(path.point(S), rots, flags)
        if not np.isnan(q).any():
            out.append((path, rots, flags, q))
    return out


@pytest.mark.parametrize("path, rots, flags, q", random_paths(40, seed=7))
def test_method_puts_the_wrist_centre_and_the_tool_on_the_path(path, rots, flags, q):
    wrist_commanded = path.point(S) - rots @ P.TOOL
    assert np.abs(P.wrist_center(q) - wrist_commanded).max() < 1e-9
    pos, rot = P.tool_pose(q)
    assert np.abs(pos - path.point(S)).max() < 1e-9
    assert np.abs(rot - rots).max() < 1e-9


@pytest.mark.parametrize("path, rots, flags, q", random_paths(40, seed=8))
def test_method_agrees_with_the_analytic_ik_of_the_same_configuration(path, rots, flags, q):
    ik = P.ik(path.point(S), rots, flags)
    regular = np.abs(np.sin(q[:, 4])) > 1e-3  # away from the wrist singularity, where q4, q6 are unique
    assert np.abs(np.angle(np.exp(1j * (ik - q))))[regular].max() < 1e-8
    assert np.all(P.configuration(q) == flags)


def test_distance_equation_has_real_roots_exactly_within_reach():
    """Eq. 14 is solvable where |K - C| <= sqrt(A^2 + B^2) (paper 002's Errata), i.e. between the folded and
    stretched arm."""
    amp = np.hypot(method.COEF_A, method.COEF_B)
    k = method.COEF_C + amp * np.array([-1.001, -0.999, 0.0, 0.999, 1.001])
    q3 = method.q3_from_distance(k, np.ones(5))
    assert np.isnan(q3[[0, 4]]).all() and not np.isnan(q3[1:4]).any()
    # Each root puts the wrist centre at that distance (eq. 9 corrected), checked through the forward kinematics.
    for sign in (1.0, -1.0):
        q3 = method.q3_from_distance(k[1:4], np.full(3, sign))
        q = np.zeros((3, 6))
        q[:, 2] = q3
        assert np.allclose(np.sum(P.wrist_center(q) ** 2, axis=1), k[1:4], atol=1e-12)


def test_continuous_keeps_every_joint_on_one_turn_and_in_range_at_the_start():
    q = np.tile(np.deg2rad([-170.0, 30.0, -200.0, 10.0, 20.0, 200.0]), (5, 1))
    q[:, 0] += np.linspace(0, 0.5, 5)
    out = method.continuous(np.angle(np.exp(1j * q)))
    assert np.allclose(np.diff(out[:, 0]), 0.125)
    assert np.all((out[0] >= P.LOWER) & (out[0] <= P.UPPER))
