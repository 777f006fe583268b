"""Agile Eye (paper 003): the 3-RRR spherical parallel manipulator with orthogonal axes that orients a camera.

Frame (NOTES.md section 4; the world frame is this base frame): base axes u1 = z, u2 = x, u3 = y; intermediate
axes w1 = [-s1, c1, 0], w2 = [0, -s2, c2], w3 = [c3, 0, -s3] (s_i = sin theta_i); platform axes v_i = the
columns of the platform orientation R; every leg closes by w_i . v_i = 0 (eq. 3 with the 90 deg link arcs).

  IK   theta1 = atan2(r21, r11), theta2 = atan2(r32, r22), theta3 = atan2(r13, r33), each leg also at +pi:
       8 working modes (bit i of the mode adds pi to leg i).
  FK   closed form: v1 = cos(a) u1 + sin(a) (w1 x u1) lies on the plane normal to w1; v2 is along w2 x v1 and
       v3 = v1 x v2, so v3 . w3 = 0 becomes (v1.w2)(v1.w3) = w2.w3, one trigonometric equation in 2a with two
       roots. Each root gives R and its three sign flips R diag(1,-1,-1), R diag(-1,1,-1), R diag(-1,-1,1):
       8 solutions, two families of the 4 assembly modes NOTES.md lists. The working mode does not change them
       (theta_i + pi turns w_i into -w_i).
  Jacobians  A omega = B theta_dot with A rows (w_i x v_i)^T and B = diag(u_i . (w_i x v_i)) (eqs. 4-7).
       det A and det B both vanish exactly where some v_i = +-u_i: six curves on which the Agile Eye's type 1
       and type 2 singularities coincide. KCI = 1 / cond(A^-1 B), 1 at the home pose, 0 on the curves.

The camera looks along LINE_OF_SIGHT, the platform's (1, 1, 1) / sqrt(3); the robot's tool point is the aim
point AIM metres along it.
"""

from __future__ import annotations

import numpy as np

from simbench.api import Summary
from simbench.robots import REVOLUTE, Robot, SingularSet, Tolerance, scene
from simbench.rotations import axis_rotation, canonical, quat_to_matrix, rotation_angle

U = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # rows: u1, u2, u3
LINE_OF_SIGHT = np.ones(3) / np.sqrt(3.0)
AIM = 0.4  # m: the aim point on the line of sight (the robot's tool point)
_FLIPS = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)

JOINTS = ("theta1", "theta2", "theta3")
PASSIVE = ("phi1", "phi2", "phi3", "psi1")  # distal hinges about w_i; the platform hinge about v1 (leg 1)
KINDS = (REVOLUTE,) * 3
LOWER = np.full(3, -np.inf)  # the base joints turn freely; the workspace is bounded by the singular curves
UPPER = np.full(3, np.inf)
QD_MAX = np.full(3, np.deg2rad(1000.0))  # the prototype's "over 1000 deg/s" (paper 003, unconfirmed)


def intermediate_axes(theta: np.ndarray) -> np.ndarray:
    """w_i (N, 3, 3), one per row, for base angles theta (N, 3)."""
    theta = np.atleast_2d(theta)
    s, c = np.sin(theta), np.cos(theta)
    zero = np.zeros(len(theta))
    return np.stack([np.stack([-s[:, 0], c[:, 0], zero], -1),
                     np.stack([zero, -s[:, 1], c[:, 1]], -1),
                     np.stack([c[:, 2], zero, -s[:, 2]], -1)], axis=1)


def ik(rot: np.ndarray, mode: np.ndarray | int = 0) -> np.ndarray:
    """Base angles (N, 3) in (-pi, pi] for platform orientations (N, 3, 3) in working mode 0..7 (per sample)."""
    r = np.reshape(rot, (-1, 3, 3))
    theta = np.stack([np.arctan2(r[:, 1, 0], r[:, 0, 0]), np.arctan2(r[:, 2, 1], r[:, 1, 1]),
                      np.arctan2(r[:, 0, 2], r[:, 2, 2])], axis=-1)
    bits = (np.asarray(mode)[..., None] >> np.arange(3)) & 1
    return np.angle(np.exp(1j * (theta + np.pi * bits)))


def fk_all(theta: np.ndarray) -> np.ndarray:
    """All 8 platform orientations (N, 8, 3, 3) for base angles (N, 3): two families, each with its sign flips.

    NaN where the two roots do not exist (never for the Agile Eye's orthogonal axes) or are degenerate.
    """
    w = intermediate_axes(theta)
    a = np.broadcast_to(U[0], w[:, 0].shape)
    b = np.cross(w[:, 0], a)
    a2, b2 = np.einsum("ij,ij->i", a, w[:, 1]), np.einsum("ij,ij->i", b, w[:, 1])
    a3, b3 = np.einsum("ij,ij->i", a, w[:, 2]), np.einsum("ij,ij->i", b, w[:, 2])
    k = np.einsum("ij,ij->i", w[:, 1], w[:, 2])
    p, q, m = (a2 * a3 - b2 * b3) / 2, (a2 * b3 + a3 * b2) / 2, k - (a2 * a3 + b2 * b3) / 2
    spread = np.arccos(np.clip(m / np.hypot(p, q), -1.0, 1.0))
    out = []
    for root in (1.0, -1.0):
        angle = (np.arctan2(q, p) + root * spread) / 2
        v1 = np.cos(angle)[:, None] * a + np.sin(angle)[:, None] * b
        v2 = np.cross(w[:, 1], v1)
        with np.errstate(invalid="ignore", divide="ignore"):  # NaN where v1 is along w2: a degenerate root
            v2 /= np.linalg.norm(v2, axis=1, keepdims=True)
        base = np.stack([v1, v2, np.cross(v1, v2)], axis=-1)
        out += [base * flip for flip in _FLIPS]
    return np.stack(out, axis=1)


def _finite(score: np.ndarray) -> np.ndarray:
    """Similarity scores with those of NaN solutions (a degenerate root: fk_all's v2 = w2 x v1 of zero length)
    at -inf, so that argmax never picks them (it would pick the first NaN)."""
    return np.where(np.isnan(score), -np.inf, score)


def fk_nearest(theta: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """The FK solution (N, 3, 3) nearest each reference orientation (N, 3, 3) or (3, 3)."""
    sols = fk_all(theta)
    ref = np.broadcast_to(reference, (len(sols), 3, 3))
    index = np.argmax(_finite(np.einsum("nkij,nij->nk", sols, ref)), axis=1)  # largest trace(ref^T R): nearest
    return sols[np.arange(len(sols)), index]


def fk_track(theta: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Platform orientations along a joint path (N, 3, 3), each the FK solution nearest the one before,
    beginning nearest `start`: the assembly mode followed continuously."""
    sols = fk_all(theta)
    # similarity[k, i, j]: how near solution i at sample k is to solution j at sample k + 1 (trace of R_i^T R_j)
    similarity = _finite(np.einsum("kiab,kjab->kij", sols[:-1], sols[1:]))
    index = np.empty(len(sols), int)
    index[0] = np.argmax(_finite(np.einsum("kab,ab->k", sols[0], start)))
    for k in range(len(sols) - 1):
        index[k + 1] = np.argmax(similarity[k, index[k]])
    return sols[np.arange(len(sols)), index]


def fk(theta: np.ndarray) -> np.ndarray:
    """The aim point (N, 3) of the FK solution nearest the home orientation."""
    return fk_nearest(theta, np.eye(3)) @ LINE_OF_SIGHT * AIM


def jacobians(theta: np.ndarray, rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A (N, 3, 3) with rows (w_i x v_i) and B = diag(u_i . (w_i x v_i)) (N, 3, 3): A omega = B theta_dot."""
    w = intermediate_axes(theta)
    v = np.reshape(rot, (-1, 3, 3)).transpose(0, 2, 1)  # rows v_i
    a = np.cross(w, v)
    b = np.einsum("ij,nij->ni", U, a)
    return a, b[:, :, None] * np.eye(3)


def kci(theta: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """Kinematic conditioning index 1 / cond(A^-1 B) (N,): 1 isotropic, 0 singular."""
    return kci_of(*jacobians(theta, rot))


def kci_of(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The KCI of Jacobians A and B already at hand (N, 3, 3 each)."""
    sa = np.linalg.svd(a, compute_uv=False)
    ok = sa[:, -1] > 1e-12 * sa[:, 0]
    j = np.linalg.solve(np.where(ok[:, None, None], a, np.eye(3)), b)
    sj = np.linalg.svd(j, compute_uv=False)
    return np.where(ok, sj[:, -1] / np.maximum(sj[:, 0], 1e-300), 0.0)


def axis_gaps(rot: np.ndarray) -> np.ndarray:
    """Angle (N, 3) between each platform axis v_i and its base axis u_i, folded to [0, pi/2]: zero on the
    singular curves v_i = +-u_i."""
    v = np.reshape(rot, (-1, 3, 3)).transpose(0, 2, 1)
    return np.arccos(np.clip(np.abs(np.einsum("ij,nij->ni", U, v)), 0.0, 1.0))


def assemble(theta: np.ndarray, rot: np.ndarray | None = None) -> dict[str, float]:
    """Passive joint angles closing every leg for base angles theta (3,) and platform orientation rot (the FK
    solution nearest home if not given), in the MJCF's convention: each body's frame is the world frame at the
    home pose (theta = 0, R = I), the distal hinge i turns about w_i(0) and the platform hinge about v1(0) = x."""
    theta = np.asarray(theta, float)
    rot = fk_nearest(theta[None], np.eye(3))[0] if rot is None else rot
    home_axes = intermediate_axes(np.zeros(3))[0]
    out = {}
    distal_1 = None
    for i in range(3):
        proximal = axis_rotation(U[i][None], theta[i:i + 1])[0]
        w0 = home_axes[i]
        target = proximal.T @ rot[:, i]
        e = np.eye(3)[i]
        phi = np.arctan2(np.cross(e, target) @ w0, e @ target)
        out[PASSIVE[i]] = float(phi)
        if i == 0:
            distal_1 = proximal @ axis_rotation(w0[None], np.array([phi]))[0]
    m = distal_1.T @ rot
    out[PASSIVE[3]] = float(np.arctan2(m[2, 1], m[1, 1]))
    return out


def _platform(rec) -> np.ndarray:
    return quat_to_matrix(rec.sensors["platform_quat"])


def measures(rec) -> dict[str, np.ndarray]:
    """KCI, the angle to the nearest singular curve, det A and the loop-closure error along a recording."""
    rot = _platform(rec)
    a, b = jacobians(rec.q, rot)
    closure = np.maximum(np.linalg.norm(rec.sensors["tip2"] - rec.sensors["mount2"], axis=1),
                         np.linalg.norm(rec.sensors["tip3"] - rec.sensors["mount3"], axis=1))
    return {"kci": kci_of(a, b), "singular_gap": axis_gaps(rot).min(axis=1), "det_a": np.linalg.det(a),
            "closure_error": closure}


def singular_sets(rec, tol: Tolerance) -> list[SingularSet]:
    """The six curves v_i = +-u_i, where det A = 0 (type 2) and, on the Agile Eye, det B = 0 too (type 1)."""
    gaps = axis_gaps(_platform(rec))
    return [SingularSet("type2", "type 2 (det A = 0; on the Agile Eye also type 1, det B = 0)",
                        "a platform axis along its base axis (v_i = +-u_i)", gaps.min(axis=1) / tol.angle,
                        {f"v{i + 1}": gaps[:, i] for i in range(3)})]


def summary(traj, rec, series: dict) -> tuple[dict, list[dict], dict]:
    """Report entries (closure error, KCI, orientation error), assembly-mode changes as events, and the
    platform orientation series."""
    rot = _platform(rec)
    report = {"closure_error_max": float(series["closure_error"].max()),
              "kci": {"mean": float(series["kci"].mean()), "min": float(series["kci"].min())}}
    extra = {"platform_quat": canonical(rec.sensors["platform_quat"]), "base_angles": rec.q.copy()}
    if "platform_quat_ref" in traj.series:
        error = rotation_angle(quat_to_matrix(traj.series["platform_quat_ref"]), rot)
        extra["orientation_error"] = error
        report["orientation_error_max"] = float(error.max())
    sign = np.sign(series["det_a"])
    flips = np.flatnonzero(sign[1:] * sign[:-1] < 0)
    events = [{"t_start": float(rec.t[k]), "t_end": float(rec.t[k + 1]), "kind": "assembly_mode_change",
               "detail": {"det_a": [float(series["det_a"][k]), float(series["det_a"][k + 1])]}} for k in flips]
    report["assembly_mode_changes"] = len(events)
    return report, events, extra


class AgileEye(Robot):
    """simbench.api.Robot of the Agile Eye (paper 003), a closed chain: its passive joints assembled, its report
    entries."""

    def __init__(self):
        super().__init__(
            name="agile_eye",
            description="Agile Eye: 3-RRR spherical parallel camera orienter (closed chain)",
            paper="003: Trajectory Optimization of Spherical Parallel Robots using Artificial Neural Network",
            joints=JOINTS,
            kinds=KINDS,
            lower=LOWER,
            upper=UPPER,
            qd_max=QD_MAX,
            tool_site="aim",
            tool_sensor="aim_pos",
            orientation_error="orientation_error",
            breaking=("assembly_mode_change",),
            sensors=("platform_quat", "tip2", "mount2", "tip3", "mount3"),
            scene=scene("agile_eye"),
        )

    def fk(self, q: np.ndarray) -> np.ndarray:
        return fk(q)

    def measures(self, rec) -> dict[str, np.ndarray]:
        return measures(rec)

    def singular_sets(self, rec, tol: Tolerance) -> list[SingularSet]:
        return singular_sets(rec, tol)

    def assemble(self, q: np.ndarray) -> dict[str, float]:
        return assemble(q)

    def summary(self, traj, rec, series: dict) -> Summary:
        return Summary(*summary(traj, rec, series))


ROBOT = AgileEye()
