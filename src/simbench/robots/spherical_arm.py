"""The 4-DOF RPRP "spherical" arm of paper 000: analytic kinematics and singular sets.

Joints (paper 000, Table 1; docs/papers/000-spherical-arm.md): q1 turntable about z, q2 vertical lift, q3
elevation of the radial link, q4 radial extension. The tool point is (eq. 19)

    x = L cos q3 cos q1,   y = L cos q3 sin q1,   z = d1 + q2 + L sin q3,   L = q4 + d4.

The paper prints 0 <= q1 <= 360 deg: one turn, and its own paths cross 360 deg (Table 2, cases 2 and 4), so q1
is a continuous joint here and the range is where waypoints report it.
"""

from __future__ import annotations

import numpy as np

from simbench.robots import PRISMATIC, REVOLUTE, SingularSet, Tolerance, joint_set
from simbench.robots.serial import SerialArm

D1 = 0.030
D4 = 0.030
_Q2_MAX = 0.4
_Q4_MAX = 0.4
_Q3_MIN = np.deg2rad(-75.0)
_Q3_MAX = np.pi

JOINTS = ("q1", "q2", "q3", "q4")
KINDS = (REVOLUTE, PRISMATIC, REVOLUTE, PRISMATIC)
LOWER = np.array([-np.inf, 0.0, _Q3_MIN, 0.0])
UPPER = np.array([np.inf, _Q2_MAX, _Q3_MAX, _Q4_MAX])
# Speeds a small servo-driven arm reaches (the paper gives none): to flag references no drive could follow.
QD_MAX = np.array([2 * np.pi, 0.5, 2 * np.pi, 0.5])


def fk(q: np.ndarray) -> np.ndarray:
    """Tool point (N, 3) of configurations q (N, 4), eq. 19."""
    q = np.atleast_2d(q)
    q1, q2, q3, q4 = q.T
    reach = q4 + D4
    return np.stack([reach * np.cos(q3) * np.cos(q1),
                     reach * np.cos(q3) * np.sin(q1),
                     D1 + q2 + reach * np.sin(q3)], axis=-1)


def jacobian(q: np.ndarray) -> np.ndarray:
    """Position Jacobian dX/dq (N, 3, 4) of the tool point (paper 000, eq. 20)."""
    q = np.atleast_2d(q)
    q1, _, q3, q4 = q.T
    reach = q4 + D4
    s1, c1, s3, c3 = np.sin(q1), np.cos(q1), np.sin(q3), np.cos(q3)
    zero, one = np.zeros_like(q1), np.ones_like(q1)
    return np.stack([
        np.stack([-reach * c3 * s1, zero, -reach * s3 * c1, c3 * c1], axis=-1),
        np.stack([reach * c3 * c1, zero, -reach * s3 * s1, c3 * s1], axis=-1),
        np.stack([zero, one, reach * c3, s3], axis=-1),
    ], axis=1)


def manipulability(q: np.ndarray) -> np.ndarray:
    """Yoshikawa's measure sqrt(det(J J^T)) of the 3x4 position Jacobian; zero where cos q3 = 0. In closed form by
    Cauchy-Binet, |c3| L sqrt(L^2 (1 + s3^2) + c3^2), L = q4 + d4: no square root of a near-zero determinant."""
    q = np.atleast_2d(q)
    reach = q[:, 3] + D4
    c3, s3 = np.cos(q[:, 2]), np.sin(q[:, 2])
    return np.abs(c3) * np.abs(reach) * np.sqrt(reach * reach * (1.0 + s3 * s3) + c3 * c3)


def axis_distance(q: np.ndarray) -> np.ndarray:
    """Distance (m) of the tool point from the lift axis, L |cos q3|: zero on the Jacobian's singular set."""
    q = np.atleast_2d(q)
    return (q[:, 3] + D4) * np.abs(np.cos(q[:, 2]))


def measures(q: np.ndarray) -> dict[str, np.ndarray]:
    """Per-sample singularity measures recorded in timeseries.npz."""
    return {"manipulability": manipulability(q), "axis_distance": axis_distance(q)}


# Paper 000's S(3) = {p3..p14}: every pair of joints at a limit, in the paper's order (q1 has no limit).
# _LIMITS: each limited joint's limits, worded as the paper; _S3's rows: (joint, value), (joint, value), wording.
_LIMITS = {1: ((0.0, "0"), (_Q2_MAX, "400 mm")), 2: ((_Q3_MIN, "-75 deg"), (_Q3_MAX, "180 deg")),
           3: ((0.0, "0"), (_Q4_MAX, "400 mm"))}
_S3 = tuple(((ja, va), (jb, vb), f"q{ja + 1} = {wa}, q{jb + 1} = {wb}")
            for ja in (1, 2) for va, wa in _LIMITS[ja] for jb in range(ja + 1, 4) for vb, wb in _LIMITS[jb])


def singular_sets(q: np.ndarray, tol: Tolerance) -> list[SingularSet]:
    """Paper 000's singular sets along q (N, 4), eqs. 15-18: S(2) = {p1, p2}, S(3) = {p3..p14}; and where the
    Jacobian loses rank (cos q3 = 0), which the paper's S(1) misses."""
    q = np.atleast_2d(q)
    args = (KINDS, JOINTS, tol, {})  # the sets share their gaps (joint_set)
    half_pi = np.pi / 2
    sets = [
        joint_set("cos_q3_zero", "Jacobian rank < 3", "cos q3 = 0 (tool on the lift axis)", q, {2: half_pi}, *args),
        joint_set("p1", "S(2)", "q3 = 90 deg, q4 = 0", q, {2: half_pi, 3: 0.0}, *args),
        joint_set("p2", "S(2)", "q3 = 90 deg, q4 = 400 mm", q, {2: half_pi, 3: _Q4_MAX}, *args),
    ]
    for index, ((ja, va), (jb, vb), condition) in enumerate(_S3, start=3):
        sets.append(joint_set(f"p{index}", "S(3)", condition, q, {ja: va, jb: vb}, *args))
    return sets


class SphericalArm(SerialArm):
    def __init__(self):
        super().__init__(
            name="spherical_arm",
            description="4-DOF RPRP spherical arm (turntable, lift, elevation, radial extension)",
            paper="000: Verification and Generation of Safe Straight Paths for a 4-DOF Spherical Manipulator",
            joints=JOINTS, kinds=KINDS, lower=LOWER, upper=UPPER, qd_max=QD_MAX,
            fk=fk, measures=measures, singular_sets=singular_sets,
        )


ROBOT = SphericalArm()
