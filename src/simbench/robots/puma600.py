"""PUMA 600 (paper 002): Craig's modified DH kinematics, analytic IK in 8 configurations, singularity measures.

Geometry (paper 002, eq. 1, verified as Craig's modified DH: docs/papers/002-puma600.md, Errata): a2 = 0.432, a3 = 0.02,
d3 = 0.149, d4 = 0.432 m, with

    i:        1    2     3     4     5     6
    alpha_{i-1}: 0  -90    0   -90    90   -90 deg
    a_{i-1}:  0    0    a2    a3     0     0
    d_i:      0    0    d3    d4     0     0

The world frame is frame 0 (where axes 1 and 2 meet); Corke's PUMA 560 angles are q - [180, 180, 0, 0, 0, 0] deg.
The wrist centre is the origin of frames 4-6; the tool (a welding torch) is TOOL in frame 6.

Configurations (Paul and Zhang's three binary choices): arm righty if r = c1 Px + s1 Py < 0, lefty if r > 0;
elbow up if sign(H) sign(r) > 0, H = a3 s3 + d4 c3; wrist noflip if q5 >= 0, flip if q5 < 0.
"""

from __future__ import annotations

import numpy as np

from simbench.robots import REVOLUTE, SingularSet, Tolerance
from simbench.robots.serial import SerialArm

A2, A3, D3, D4 = 0.432, 0.02, 0.149, 0.432
D6 = 0.056  # wrist centre to tool flange along z6 (PUMA 560 flange)
TOOL = np.array([0.0, 0.0, D6 + 0.15])  # torch tip: a 0.15 m straight torch on the flange

_ALPHA = np.deg2rad([0.0, -90.0, 0.0, -90.0, 90.0, -90.0])
_A = np.array([0.0, 0.0, A2, A3, 0.0, 0.0])
_D = np.array([0.0, 0.0, D3, D4, 0.0, 0.0])

JOINTS = ("q1", "q2", "q3", "q4", "q5", "q6")
KINDS = (REVOLUTE,) * 6
# Corke's PUMA 560 limits (+-160, [-45, 225], [-225, 45], [-110, 170], +-100, +-266 deg) moved to these angles.
LOWER = np.deg2rad([20.0, -225.0, -225.0, -110.0, -100.0, -266.0])
UPPER = np.deg2rad([340.0, 45.0, 45.0, 170.0, 100.0, 266.0])
# Joint speeds of the order the PUMA 560's drives reach (about 250 deg/s at the arm, 300 deg/s at the wrist).
QD_MAX = np.deg2rad([250.0, 250.0, 250.0, 300.0, 300.0, 300.0])
HOME = np.deg2rad([180.0, -135.0, -180.0, 0.0, 45.0, 0.0])  # Corke's nominal table-top pose qn

STRETCH = np.arctan2(-D4, A3)  # q3 of the stretched arm: sin(q3 - STRETCH) = H / sqrt(a3^2 + d4^2)

ARM = {"righty": -1.0, "lefty": 1.0}
ELBOW = {"up": 1.0, "down": -1.0}
WRIST = {"noflip": 1.0, "flip": -1.0}


def _rot_z(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    one, zero = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1),
                     np.stack([zero, zero, one], -1)], -2)


_RX = _rot_z(_ALPHA)[:, [2, 0, 1]][:, :, [2, 0, 1]]  # Rx(alpha_{i-1}): Rz's entries with the axes turned z -> x


def link_frames(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Origins (N, 6, 3) and rotations (N, 6, 3, 3) of frames 1..6 in frame 0 (modified DH)."""
    q = np.atleast_2d(q)
    n = q.shape[0]
    rot = np.broadcast_to(np.eye(3), (n, 3, 3))
    pos = np.zeros((n, 3))
    origins, rotations = [], []
    for i in range(6):
        pos = pos + rot[:, :, 0] * _A[i]
        rot = rot @ _RX[i] @ _rot_z(q[:, i])
        pos = pos + rot[:, :, 2] * _D[i]
        origins.append(pos)
        rotations.append(rot)
    return np.stack(origins, 1), np.stack(rotations, 1)


def wrist_center(q: np.ndarray) -> np.ndarray:
    """Wrist centre (N, 3): paper 002's eq. 1, the sign of Py's d3 term fixed (docs/papers/002-puma600.md, Errata)."""
    c1, s1, c2, s2, c3, s3 = _trig(q, 0, 1, 2)
    g = A3 * c3 - D4 * s3 + A2
    h = A3 * s3 + D4 * c3
    r = c2 * g - s2 * h
    return np.stack([c1 * r - D3 * s1, s1 * r + D3 * c1, -s2 * g - c2 * h], axis=-1)


def tool_pose(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tool point (N, 3) and tool orientation R_06 (N, 3, 3)."""
    origins, rotations = link_frames(q)
    r06 = rotations[:, 5]
    return origins[:, 5] + r06 @ TOOL, r06


def fk(q: np.ndarray) -> np.ndarray:
    """Tool point (N, 3)."""
    return tool_pose(q)[0]


def jacobian(q: np.ndarray) -> np.ndarray:
    """Geometric Jacobian (N, 6, 6) of the tool: rows 0-2 linear velocity, rows 3-5 angular velocity."""
    origins, rotations = link_frames(q)
    tool = origins[:, 5] + rotations[:, 5] @ TOOL
    axes = rotations[:, :, :, 2]
    linear = np.cross(axes, tool[:, None, :] - origins)
    return np.concatenate([linear.transpose(0, 2, 1), axes.transpose(0, 2, 1)], axis=1)


def configuration(q: np.ndarray) -> np.ndarray:
    """Configuration flags (N, 3): arm (-1 righty, +1 lefty), elbow (+1 up, -1 down), wrist (+1 noflip)."""
    q = np.atleast_2d(q)
    p = wrist_center(q)
    r = np.cos(q[:, 0]) * p[:, 0] + np.sin(q[:, 0]) * p[:, 1]
    h = A3 * np.sin(q[:, 2]) + D4 * np.cos(q[:, 2])
    sign = lambda x: np.where(x >= 0, 1.0, -1.0)  # noqa: E731
    return np.stack([sign(r), sign(h) * sign(r), sign(q[:, 4])], axis=-1)


def arm_angles(p: np.ndarray, arm: np.ndarray, elbow: np.ndarray) -> np.ndarray:
    """(q1, q2, q3) (N, 3) putting the wrist centre at p (N, 3) in the given configuration; NaN if unreachable.
    Craig's closed form (Introduction to Robotics, section 4.7), independent of paper 002's method."""
    p = np.atleast_2d(p)
    n = len(p)
    arm, elbow = np.broadcast_to(arm, (n,)), np.broadcast_to(elbow, (n,))
    px, py, pz = p.T
    with np.errstate(invalid="ignore"):
        r = arm * np.sqrt(px**2 + py**2 - D3**2)
        k = (px**2 + py**2 + pz**2 - A2**2 - A3**2 - D3**2 - D4**2) / (2 * A2)
        root = np.sqrt(A3**2 + D4**2 - k**2)
    q1 = np.arctan2(py, px) - np.arctan2(D3, r)
    candidates = [np.arctan2(A3, D4) - np.arctan2(k, sign * root) for sign in (1.0, -1.0)]
    h_first = A3 * np.sin(candidates[0]) + D4 * np.cos(candidates[0])
    q3 = np.where(np.sign(h_first) == elbow * arm, *candidates)
    c1, s1, c3, s3 = np.cos(q1), np.sin(q1), np.cos(q3), np.sin(q3)
    reach = c1 * px + s1 * py
    q23 = np.arctan2((-A3 - A2 * c3) * pz - reach * (D4 - A2 * s3), (A2 * s3 - D4) * pz + (A3 + A2 * c3) * reach)
    q2 = np.angle(np.exp(1j * (q23 - q3)))
    return np.stack([q1, q2, q3], axis=-1)


def arm_rotation(q1: np.ndarray, q23: np.ndarray) -> np.ndarray:
    """R_03 (N, 3, 3) = Rz(q1) Rx(-90 deg) Rz(q2 + q3): frame 3 depends on q1 and q2 + q3 alone."""
    c1, s1, c23, s23 = np.cos(q1), np.sin(q1), np.cos(q23), np.sin(q23)
    zero = np.zeros_like(q1)
    return np.stack([np.stack([c1 * c23, -c1 * s23, -s1], -1),
                     np.stack([s1 * c23, -s1 * s23, c1], -1),
                     np.stack([-s23, -c23, zero], -1)], -2)


def wrist_angles(q123: np.ndarray, r06: np.ndarray, wrist: np.ndarray) -> np.ndarray:
    """(q4, q5, q6) (N, 3) giving R_06 (N, 3, 3) after the arm's (q1, q2, q3): Rx(90 deg) R_36 = Rz(q4) Ry(-q5)
    Rz(q6). At q5 = 0 only q4 + q6 is defined; q4 is then 0."""
    r03 = arm_rotation(q123[:, 0], q123[:, 1] + q123[:, 2])
    r36 = np.einsum("nji,njk->nik", r03, r06)
    m = np.stack([r36[:, 0], -r36[:, 2], r36[:, 1]], axis=1)  # Rx(90 deg) R_36
    wrist = np.broadcast_to(wrist, (len(q123),))
    lateral = np.hypot(m[:, 0, 2], m[:, 1, 2])
    q5 = wrist * np.arctan2(lateral, m[:, 2, 2])
    sign = -wrist  # sin(-q5) has the sign of -wrist
    degenerate = lateral < 1e-12
    q4 = np.where(degenerate, 0.0, np.arctan2(sign * m[:, 1, 2], sign * m[:, 0, 2]))
    q6 = np.where(degenerate, np.arctan2(m[:, 1, 0], m[:, 0, 0]),
                  np.arctan2(sign * m[:, 2, 1], -sign * m[:, 2, 0]))
    return np.stack([q4, q5, q6], axis=-1)


def ik(position: np.ndarray, rotation: np.ndarray, config: np.ndarray) -> np.ndarray:
    """Analytic IK (Craig section 4.7): joints (N, 6) putting the tool at position (N, 3) with orientation
    rotation (N, 3, 3) in configuration config (N, 3) or (3,); NaN rows where the pose is out of reach."""
    position = np.atleast_2d(position)
    rotation = np.reshape(rotation, (-1, 3, 3))
    config = np.broadcast_to(config, (len(position), 3))
    p = position - rotation @ TOOL
    q123 = arm_angles(p, config[:, 0], config[:, 1])
    return np.concatenate([q123, wrist_angles(q123, rotation, config[:, 2])], axis=1)


def _trig(q: np.ndarray, *joints: int) -> list[np.ndarray]:
    """cos and sin (N,) of each joint `joints` of q (N, 6) in turn: c_a, s_a, c_b, s_b, ..."""
    q = np.atleast_2d(q)
    return [f(q[:, i]) for i in joints for f in (np.cos, np.sin)]


def _elbow_and_shoulder(c2: np.ndarray, s2: np.ndarray, c3: np.ndarray, s3: np.ndarray) -> tuple:
    """The elbow's H = a3 s3 + d4 c3 and the shoulder's r = c2 (a2 + a3 c3 - d4 s3) - s2 H (c1 Px + s1 Py, eq. 1),
    (N,) each, from the cosines and sines of q2 and q3; 0 where the elbow or shoulder is singular."""
    h = A3 * s3 + D4 * c3
    return h, c2 * (A2 + A3 * c3 - D4 * s3) - s2 * h


def shoulder_gap(q: np.ndarray) -> np.ndarray:
    """|r| (m): the wrist centre's distance from the shoulder-singular plane (r = c1 Px + s1 Py = 0)."""
    return np.abs(_elbow_and_shoulder(*_trig(q, 1, 2))[1])


def elbow_gap(q: np.ndarray) -> np.ndarray:
    """Angle (rad) from the stretched or folded arm, |asin(H / sqrt(a3^2 + d4^2))|."""
    q = np.atleast_2d(q)
    return np.abs(np.arcsin(np.clip(np.sin(q[:, 2] - STRETCH), -1.0, 1.0)))


def wrist_gap(q: np.ndarray) -> np.ndarray:
    """|q5| folded into [0, pi/2]: the angle from the wrist singularity (axes 4 and 6 aligned)."""
    q = np.atleast_2d(q)
    return np.abs(np.arcsin(np.sin(q[:, 4])))


_LENGTH = A2 + D4  # scales the Jacobian's linear rows so that its condition number has no units


def _frame3_columns(q: np.ndarray, c3: np.ndarray, s3: np.ndarray, c4: np.ndarray, s4: np.ndarray,
                    c5: np.ndarray, s5: np.ndarray) -> list[tuple]:
    """The columns of the tool Jacobian in frame 3's coordinates, linear rows divided by a2 + d4, in closed form
    (the same singular values as `jacobian`'s), from q (N, 6) and the cosines and sines of q3, q4 and q5: column i
    is (z_i x (t - o_i) / (a2 + d4), z_i), six entries each, arrays or the constants 0.0 and 1.0."""
    c23, s23 = np.cos(q[:, 1] + q[:, 2]), np.sin(q[:, 1] + q[:, 2])
    tool = TOOL[2] / _LENGTH
    x6, y6, z6 = -c4 * s5, c5, s4 * s5
    tx, ty, tz = A3 / _LENGTH + tool * x6, D4 / _LENGTH + tool * y6, tool * z6  # t
    ux, uy, uz = tx + A2 / _LENGTH * c3, ty - A2 / _LENGTH * s3, tz + D3 / _LENGTH  # t - o1
    return [(-c23 * uz, s23 * uz, c23 * ux - s23 * uy, -s23, -c23, 0.0),
            (-uy, ux, 0.0, 0.0, 0.0, 1.0), (-ty, tx, 0.0, 0.0, 0.0, 1.0),
            (tool * z6, 0.0, -tool * x6, 0.0, 1.0, 0.0),
            (-tool * c4 * c5, -tool * s5, tool * s4 * c5, s4, 0.0, c4),
            (0.0, 0.0, 0.0, x6, y6, z6)]


def frame3_jacobian(q: np.ndarray) -> np.ndarray:
    """The tool Jacobian (N, 6, 6) in frame 3's coordinates with its linear rows divided by a2 + d4."""
    q = np.atleast_2d(q)
    return _matrices(_frame3_columns(q, *_trig(q, 2, 3, 4)))


def _matrices(columns: list[tuple]) -> np.ndarray:
    """The matrices (N, 6, 6) of `_frame3_columns`' columns."""
    columns = [np.stack(np.broadcast_arrays(*column), -1) for column in columns]
    return np.stack(np.broadcast_arrays(*columns), -1)


def manipulability(q: np.ndarray) -> np.ndarray:
    """|det J| of the tool Jacobian with its linear rows divided by a2 + d4: a2 |H r s5| / (a2 + d4)^3 (J is block
    triangular about the wrist centre)."""
    c2, s2, c3, s3, _, s5 = _trig(q, 1, 2, 4)
    return _manipulability(*_elbow_and_shoulder(c2, s2, c3, s3), s5)


def _manipulability(h: np.ndarray, r: np.ndarray, s5: np.ndarray) -> np.ndarray:
    return A2 * np.abs(h * r * s5) / _LENGTH**3


def condition(q: np.ndarray) -> np.ndarray:
    """Condition number of the tool Jacobian with its linear rows divided by a2 + d4."""
    return _condition(frame3_jacobian(q))


def _condition(jac: np.ndarray) -> np.ndarray:
    sv = np.linalg.svd(jac, compute_uv=False)
    return sv[:, 0] / np.maximum(sv[:, -1], 1e-300)


def measures(q: np.ndarray) -> dict[str, np.ndarray]:
    """Manipulability, condition number and the three singularity gaps, each joint's cos and sin taken once (they
    cost as much as the rest), the same numbers the measures' own functions take."""
    q = np.atleast_2d(q)
    c2, s2, c3, s3, c4, s4, c5, s5 = _trig(q, 1, 2, 3, 4)
    h, r = _elbow_and_shoulder(c2, s2, c3, s3)
    return {"manipulability": _manipulability(h, r, s5),
            "condition": _condition(_matrices(_frame3_columns(q, c3, s3, c4, s4, c5, s5))),
            "shoulder_gap": np.abs(r), "elbow_gap": elbow_gap(q), "wrist_gap": np.abs(np.arcsin(s5))}


def singular_sets(q: np.ndarray, tol: Tolerance) -> list[SingularSet]:
    """Shoulder (r = 0), elbow (arm stretched or folded) and wrist (q5 = 0) singularities."""
    return sets_of_measures({"shoulder_gap": shoulder_gap(q), "elbow_gap": elbow_gap(q), "wrist_gap": wrist_gap(q)},
                            tol)


def sets_of_measures(found: dict[str, np.ndarray], tol: Tolerance) -> list[SingularSet]:
    """`singular_sets` from the gaps `measures` found (the same numbers, not computed again)."""
    shoulder, elbow, wrist = found["shoulder_gap"], found["elbow_gap"], found["wrist_gap"]
    return [
        SingularSet("shoulder", "PUMA", "wrist centre on the shoulder-singular plane (r = c1 Px + s1 Py = 0)",
                    shoulder / tol.length, {"r": shoulder}),
        SingularSet("elbow", "PUMA", "arm stretched or folded (a3 s3 + d4 c3 = 0)", elbow / tol.angle,
                    {"q3": elbow}),
        SingularSet("wrist", "PUMA", "axes 4 and 6 aligned (q5 = 0)", wrist / tol.angle, {"q5": wrist}),
    ]


class Puma600(SerialArm):
    def __init__(self):
        super().__init__(
            name="puma600",
            description="PUMA 600 6-DOF arm with a welding torch (decoupled, spherical wrist)",
            paper="002: joint time histories for line and circle paths of a decoupled arm",
            joints=JOINTS, kinds=KINDS, lower=LOWER, upper=UPPER, qd_max=QD_MAX,
            fk=fk, measures=measures, singular_sets=singular_sets, sets_of_measures=sets_of_measures,
        )


ROBOT = Puma600()
