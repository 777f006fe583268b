"""A planar 3R arm: three revolute joints with parallel vertical axes, its analytic kinematics and singular set.

The tool's pose in the plane of motion is (x, y, phi):

    x   = L1 cos q1 + L2 cos(q1 + q2) + L3 cos(q1 + q2 + q3)
    y   = L1 sin q1 + L2 sin(q1 + q2) + L3 sin(q1 + q2 + q3)
    phi = q1 + q2 + q3

and the tool point is (x, y, Z) with Z the plane's height in the MJCF (models/planar3r.xml). The Jacobian of
(x, y, phi) is square, and its determinant is L1 L2 sin q2 whatever q1 and q3 (the standard planar 3R result,
e.g. Siciliano et al., Robotics: Modelling, Planning and Control, sec. 3.3, or Craig, Introduction to Robotics,
ch. 5): the arm is singular exactly where the elbow is stretched (q2 = 0) or folded (q2 = +-pi), and nowhere else.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from simbench.api import REVOLUTE, Robot, SingularSet, Tolerance

L1, L2, L3 = 0.4, 0.3, 0.2  # link lengths (m), as in the MJCF
Z = 0.38  # height of the tool's plane of motion (m): joint 1 at 0.30, links stacked 0.04 apart
JOINTS = ("q1", "q2", "q3")
LOWER = np.deg2rad([-180.0, -170.0, -170.0])
UPPER = np.deg2rad([180.0, 170.0, 170.0])
# About half a turn per second at the shoulder and a turn per second at the elbow and wrist: what small servos
# of this size give (no source; used only to flag references no drive could follow).
QD_MAX = np.array([np.pi, 2 * np.pi, 2 * np.pi])
SCENE = Path(__file__).parent / "models" / "scene.xml"


def _rows(q: np.ndarray) -> np.ndarray:
    """q as (N, 3) floats: a single configuration (3,) becomes one row."""
    q = np.atleast_2d(np.asarray(q, float))
    if q.shape[-1] != 3:
        raise ValueError(f"expected joint values (N, 3), got shape {q.shape}")
    return q


def pose(q: np.ndarray) -> np.ndarray:
    """The tool's planar pose (x, y, phi) (N, 3) at joint values q (N, 3); phi = q1 + q2 + q3, not wrapped."""
    q = _rows(q)
    a1, a12, a123 = q[:, 0], q[:, 0] + q[:, 1], q.sum(axis=1)
    return np.stack([L1 * np.cos(a1) + L2 * np.cos(a12) + L3 * np.cos(a123),
                     L1 * np.sin(a1) + L2 * np.sin(a12) + L3 * np.sin(a123), a123], axis=-1)


def fk(q: np.ndarray) -> np.ndarray:
    """The tool point (N, 3) in metres, world frame, at joint values q (N, 3)."""
    p = pose(q)
    return np.stack([p[:, 0], p[:, 1], np.full(len(p), Z)], axis=-1)


def jacobian(q: np.ndarray) -> np.ndarray:
    """d(x, y, phi)/dq (N, 3, 3): column j is joint j's effect on the tool's pose."""
    q = _rows(q)
    a1, a12, a123 = q[:, 0], q[:, 0] + q[:, 1], q.sum(axis=1)
    s1, s12, s123 = L1 * np.sin(a1), L2 * np.sin(a12), L3 * np.sin(a123)
    c1, c12, c123 = L1 * np.cos(a1), L2 * np.cos(a12), L3 * np.cos(a123)
    one = np.ones(len(q))
    return np.stack([
        np.stack([-(s1 + s12 + s123), -(s12 + s123), -s123], axis=-1),
        np.stack([c1 + c12 + c123, c12 + c123, c123], axis=-1),
        np.stack([one, one, one], axis=-1),
    ], axis=1)


def det_j(q: np.ndarray) -> np.ndarray:
    """det J = L1 L2 sin q2 (N,): zero exactly on the singular set (standard planar 3R result)."""
    return L1 * L2 * np.sin(_rows(q)[:, 1])


def elbow_gaps(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How far (rad) q2 is from the stretched elbow (q2 = 0) and from the folded one (q2 = +-pi), (N,) each."""
    q2 = np.angle(np.exp(1j * _rows(q)[:, 1]))  # wrapped to (-pi, pi]
    return np.abs(q2), np.pi - np.abs(q2)


class Planar3R(Robot):
    """The planar 3R arm of this package's scene: three hinges along z, a tool site at the tip of link 3."""

    def __init__(self):
        super().__init__(
            name="planar3r",
            description="planar 3R arm in a horizontal plane (L = 0.4, 0.3, 0.2 m); example of an outside package",
            scene=SCENE,
            joints=JOINTS,
            kinds=(REVOLUTE,) * 3,
            lower=LOWER,
            upper=UPPER,
            qd_max=QD_MAX,
            tool_site="tool",
            tool_sensor="tool_pos",
        )

    def fk(self, q: np.ndarray) -> np.ndarray:
        """The tool point (N, 3) at joint values q (N, 3)."""
        return fk(q)

    def pose(self, q: np.ndarray) -> np.ndarray:
        """The tool's planar pose (x, y, phi) (N, 3): what a planner in the plane controls."""
        return pose(q)

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """d(x, y, phi)/dq (N, 3, 3)."""
        return jacobian(q)

    def measures(self, rec) -> dict[str, np.ndarray]:
        """det_J = L1 L2 sin q2 along the run (m^2): its sign is the elbow's branch, zero the singular set."""
        return {"det_J": det_j(rec.q)}

    def singular_sets(self, rec, tol: Tolerance) -> list[SingularSet]:
        """The elbow stretched (q2 = 0) and folded (q2 = +-pi) along the run; gaps in rad, distance |gap| / tol."""
        stretched, folded = elbow_gaps(rec.q)
        return [
            SingularSet("stretched", "elbow stretched", "q2 = 0 (boundary of the reach, |p_wrist| = L1 + L2)",
                        stretched / tol.angle, {"q2": stretched}),
            SingularSet("folded", "elbow folded", "q2 = +-180 deg (|p_wrist| = L1 - L2; outside q2's range)",
                        folded / tol.angle, {"q2": folded}),
        ]


ROBOT = Planar3R()
