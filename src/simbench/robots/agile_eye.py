"""Agile Eye (paper 003): the 3-RRR spherical parallel manipulator with orthogonal axes that orients a camera.

Frame (docs/papers/003-agile-eye.md; the world frame is this base frame): base axes u1 = z, u2 = x, u3 = y; intermediate
axes w1 = [-s1, c1, 0], w2 = [0, -s2, c2], w3 = [c3, 0, -s3] (s_i = sin theta_i); platform axes v_i = the
columns of the platform orientation R; every leg closes by w_i . v_i = 0 (eq. 3 with the 90 deg link arcs).

  IK   theta1 = atan2(r21, r11), theta2 = atan2(r32, r22), theta3 = atan2(r13, r33), each leg also at +pi:
       8 working modes (bit i of the mode adds pi to leg i).
  FK   closed form: v1 = cos(a) u1 + sin(a) (w1 x u1) lies on the plane normal to w1; v2 is along w2 x v1 and
       v3 = v1 x v2, so v3 . w3 = 0 becomes (v1.w2)(v1.w3) = w2.w3, one trigonometric equation in 2a with two
       roots. Each root gives R and its three sign flips R diag(1,-1,-1), R diag(-1,1,-1), R diag(-1,-1,1):
       8 solutions, two families of the 4 assembly modes (docs/papers/003-agile-eye.md). The working mode does
       not change them (theta_i + pi turns w_i into -w_i).
  Jacobians  A omega = B theta_dot with A rows (w_i x v_i)^T and B = diag(u_i . (w_i x v_i)) (eqs. 4-7).
       det A and det B both vanish exactly where some v_i = +-u_i: six curves on which the Agile Eye's type 1
       and type 2 singularities coincide. KCI = 1 / cond(A^-1 B), 1 at the home pose, 0 on the curves.

The camera looks along LINE_OF_SIGHT, the platform's (1, 1, 1) / sqrt(3); the robot's tool point is the aim
point AIM metres along it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from simbench import api
from simbench.api import Summary
from simbench.core.windowed import BlockSum
from simbench.maths.rotations import axis_rotation, canonical, quat_to_matrix, rotation_angle
from simbench.maths.vectors import cross, triple
from simbench.robots import REVOLUTE, Robot, SingularSet, Tolerance, scene

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
    w = np.zeros((len(theta), 3, 3))
    w[:, 0, 0], w[:, 0, 1] = -s[:, 0], c[:, 0]
    w[:, 1, 1], w[:, 1, 2] = -s[:, 1], c[:, 1]
    w[:, 2, 0], w[:, 2, 2] = c[:, 2], -s[:, 2]
    return w


def ik(rot: np.ndarray, mode: np.ndarray | int = 0) -> np.ndarray:
    """Base angles (N, 3) in (-pi, pi] for platform orientations (N, 3, 3) in working mode 0..7 (per sample)."""
    r = np.reshape(rot, (-1, 3, 3))
    theta = np.stack([np.arctan2(r[:, 1, 0], r[:, 0, 0]), np.arctan2(r[:, 2, 1], r[:, 1, 1]),
                      np.arctan2(r[:, 0, 2], r[:, 2, 2])], axis=-1)
    bits = (np.asarray(mode)[..., None] >> np.arange(3)) & 1
    return np.angle(np.exp(1j * (theta + np.pi * bits)))


def fk_all(theta: np.ndarray) -> np.ndarray:
    """All 8 platform orientations (N, 8, 3, 3) for base angles (N, 3): two families (the two roots), each with its
    sign flips. NaN where the two roots do not exist (never for the Agile Eye's orthogonal axes) or are degenerate.
    """
    w = intermediate_axes(theta)
    a = np.broadcast_to(U[0], w[:, 0].shape)
    b = cross(w[:, 0], a)
    a2, b2 = np.einsum("ij,ij->i", a, w[:, 1]), np.einsum("ij,ij->i", b, w[:, 1])
    a3, b3 = np.einsum("ij,ij->i", a, w[:, 2]), np.einsum("ij,ij->i", b, w[:, 2])
    k = np.einsum("ij,ij->i", w[:, 1], w[:, 2])
    p, q, m = (a2 * a3 - b2 * b3) / 2, (a2 * b3 + a3 * b2) / 2, k - (a2 * a3 + b2 * b3) / 2
    spread = np.arccos(np.clip(m / np.hypot(p, q), -1.0, 1.0))
    angle = (np.arctan2(q, p)[:, None] + np.array([1.0, -1.0]) * spread[:, None]) / 2  # (N, 2 roots)
    v1 = np.cos(angle)[..., None] * a[:, None] + np.sin(angle)[..., None] * b[:, None]
    v2 = cross(w[:, None, 1], v1)
    with np.errstate(invalid="ignore", divide="ignore"):  # NaN where v1 is along w2: a degenerate root
        v2 /= np.linalg.norm(v2, axis=2, keepdims=True)
    base = np.stack([v1, v2, cross(v1, v2)], axis=-1)  # (N, 2, 3, 3)
    return (base[:, :, None] * _FLIPS[:, None, :]).reshape(len(base), 8, 3, 3)


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
    """Platform orientations along a joint path (N, 3, 3), each the FK solution nearest the one before (largest
    trace of R_i^T R_j), beginning nearest `start`: the assembly mode followed continuously. Taken a stretch at a
    time on which the followed solution stays the same one of the 8 (a Python step per change, not per sample)."""
    sols = fk_all(theta)
    count = len(sols)
    flat = sols.reshape(count, 8, 9)
    index = np.empty(count, int)
    index[0] = np.argmax(_finite(np.einsum("kab,ab->k", sols[0], start)))
    k, stretch = 0, 16
    while k < count - 1:
        end = min(count - 1, k + stretch)
        current = index[k]
        nearest = np.argmax(_finite(np.einsum("ka,kja->kj", flat[k:end, current], flat[k + 1:end + 1])), axis=1)
        moves = np.flatnonzero(nearest != current)
        stop = moves[0] if moves.size else end - k  # samples k + 1 .. k + stop keep the current solution
        index[k + 1:k + 1 + stop] = current
        if moves.size:
            index[k + 1 + stop] = nearest[stop]
            k, stretch = k + 1 + stop, 16
        else:
            k, stretch = end, 2 * stretch
    return sols[np.arange(count), index]


def fk(theta: np.ndarray) -> np.ndarray:
    """The aim point (N, 3) of the FK solution nearest the home orientation."""
    return fk_nearest(theta, np.eye(3)) @ LINE_OF_SIGHT * AIM


def jacobians(theta: np.ndarray, rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A (N, 3, 3) with rows (w_i x v_i) and B = diag(u_i . (w_i x v_i)) (N, 3, 3): A omega = B theta_dot."""
    _, _, a, b = _scaled_rows(theta, rot)
    return a, b[:, :, None] * np.eye(3)


def kci(theta: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """Kinematic conditioning index 1 / cond(A^-1 B) (N,): 1 isotropic, 0 singular."""
    return kci_terms(theta, rot).kci


def axis_gaps(rot: np.ndarray) -> np.ndarray:
    """Angle (N, 3) between each platform axis v_i and its base axis u_i, folded to [0, pi/2]: zero on the
    singular curves v_i = +-u_i."""
    return axis_gap_partials(rot)[0]


def _scaled_rows(theta: np.ndarray, rot: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """w_i (N, 3, 3), v_i, a_i = w_i x v_i (the rows of A) and b_i = u_i . a_i (B's diagonal), rows per leg."""
    w = intermediate_axes(theta)
    v = np.reshape(rot, (-1, 3, 3)).transpose(0, 2, 1)
    a = cross(w, v)
    return w, v, a, np.einsum("ij,nij->ni", U, a)


class KciTerms(NamedTuple):
    """The KCI and the terms on the way (kci_terms), which kci_partials reuses: per leg (rows) w_i, v_i,
    a_i = w_i x v_i and b_i = u_i . a_i (1 where the KCI is not defined), where it is (`ok`) and K = B^-1 A
    (rows a_i / b_i)."""

    w: np.ndarray
    v: np.ndarray
    a: np.ndarray
    b: np.ndarray
    ok: np.ndarray
    k: np.ndarray
    kci: np.ndarray


def kci_terms(theta: np.ndarray, rot: np.ndarray) -> KciTerms:
    """kci (N,) with its terms: 1 / cond(A^-1 B) = sigma_min / sigma_max of K = B^-1 A, whose rows are a_i / b_i.
    The singular values of K itself, not the eigenvalues of K K^T, so that the KCI is exact to the rounding of
    sigma_max also near the singular curves. 0 where some b_i vanishes (within 1e-12 of A's scale: not `ok`), B
    and so A^-1 B being singular."""
    w, v, a, b = _scaled_rows(theta, rot)
    ok = np.abs(b).min(axis=1) > 1e-12 * np.abs(a).max(axis=(1, 2))
    b = np.where(ok[:, None], b, 1.0)
    k = a / b[:, :, None]
    s = np.linalg.svd(k, compute_uv=False)
    return KciTerms(w, v, a, b, ok, k, np.where(ok, s[:, -1] / np.maximum(s[:, 0], 1e-300), 0.0))


def platform_rates(theta: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """The platform's angular velocity (base frame) per unit rate of each base joint (N, 3, 3), column j for
    theta_dot = e_j: A^-1 B (eqs. 4-7), the derivative of the exact FK. NaN where A is singular."""
    _, _, a, b = _scaled_rows(theta, rot)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.linalg.solve(a, b[:, :, None] * np.eye(3))


def kci_partials(theta: np.ndarray, rot: np.ndarray,
                 terms: KciTerms | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The KCI (N,), its partial derivatives in the base angles with the platform held (N, 3), and in the
    platform's rotation (N, 3): d kci = d_theta . dtheta + d_omega . omega for a small turn omega (base frame) of
    the platform. Along a path whose platform turns at `rates` (column j the angular velocity per unit rate of
    theta_j: platform_rates for the exact FK), the gradient is d_theta + rates^T d_omega. Reverse mode, with
    K = B^-1 A (rows k_i = a_i / b_i) = sum_m sigma_m x_m y_m^T: d sigma_m / d K = x_m y_m^T; k_i = a_i / (u_i . a_i);
    a_i = w_i x v_i with dv_i = omega x v_i and dw_i = u_i x w_i dtheta_i (the cross products then expanded into
    dot products). The partials are 0 where some b_i is near 0 (not `ok`). `terms`: kci_terms(theta, rot) if at
    hand."""
    w, v, _, b, ok, k, value = kci_terms(theta, rot) if terms is None else terms
    x, s, y = np.linalg.svd(k)  # s descending: sigma_max first
    # d kci = kci (d sigma_min / sigma_min - d sigma_max / sigma_max)
    d_k = value[:, None, None] * (x[:, :, 2, None] * y[:, None, 2] / np.maximum(s[:, 2, None, None], 1e-300)
                                  - x[:, :, 0, None] * y[:, None, 0] / np.maximum(s[:, 0, None, None], 1e-300))
    d_a = (d_k - np.einsum("nia,nia->ni", d_k, k)[:, :, None] * U) / b[:, :, None]  # d kci / d a_i
    v_w = np.einsum("nia,nia->ni", v, w)  # 0 for the exact FK, not quite for a learnt one
    # sum_i v_i x (d_a_i x w_i) = sum_i d_a_i (v_i . w_i) - w_i (v_i . d_a_i)
    d_omega = np.einsum("nia,ni->na", d_a, v_w) - np.einsum("nia,ni->na", w, np.einsum("nia,nia->ni", v, d_a))
    # (v_i x d_a_i) . (u_i x w_i) = (v_i . u_i)(d_a_i . w_i) - (v_i . w_i)(d_a_i . u_i)
    d_theta = (np.einsum("ia,nia->ni", U, v) * np.einsum("nia,nia->ni", d_a, w)
               - v_w * np.einsum("ia,nia->ni", U, d_a))
    live = (ok & (value > 0))[:, None]
    return value, np.where(live, d_theta, 0.0), np.where(live, d_omega, 0.0)


def axis_gap_partials(rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """axis_gaps (N, 3) and their derivatives in the platform's rotation (N, 3 axes, 3): gap_i = arccos|u_i .
    v_i| and dv_i = omega x v_i, so d gap_i = -sign(u_i . v_i) (v_i x u_i) . omega / sqrt(1 - (u_i . v_i)^2)."""
    v = np.reshape(rot, (-1, 3, 3)).transpose(0, 2, 1)
    dot = np.einsum("ij,nij->ni", U, v)
    gaps = np.arccos(np.clip(np.abs(dot), 0.0, 1.0))
    slope = -np.sign(dot) / np.sqrt(np.maximum(1.0 - dot**2, 1e-300))
    return gaps, slope[:, :, None] * cross(v, U)


def assemble(theta: np.ndarray, rot: np.ndarray | None = None) -> dict[str, float]:
    """Passive joint angles closing every leg for base angles theta (3,) and platform orientation rot (the FK
    solution nearest home if not given), in the MJCF's convention: each body's frame is the world frame at the
    home pose (theta = 0, R = I), the distal hinge i turns about w_i(0) and the platform hinge about v1(0) = x."""
    theta = np.asarray(theta, float)
    rot = fk_nearest(theta[None], np.eye(3))[0] if rot is None else rot
    home_axes = intermediate_axes(np.zeros(3))[0]
    out = {}
    for i in range(3):
        target = axis_rotation(U[i][None], theta[i:i + 1])[0].T @ rot[:, i]
        e = np.eye(3)[i]
        out[PASSIVE[i]] = float(np.arctan2(np.cross(e, target) @ home_axes[i], e @ target))
    distal_1 = axis_rotation(U[:1], theta[:1])[0] @ axis_rotation(home_axes[:1], np.array([out[PASSIVE[0]]]))[0]
    m = distal_1.T @ rot
    out[PASSIVE[3]] = float(np.arctan2(m[2, 1], m[1, 1]))
    return out


def _platform(rec) -> np.ndarray:
    return quat_to_matrix(rec.sensors["platform_quat"])


class Summariser(api.Summariser):
    """`summary` a window of samples at a time (in order): the KCI's sum (`windowed.BlockSum`: the same however
    the run is cut), the largest errors, and det A's last sample (an assembly-mode change between two windows)
    carried from window to window."""

    def __init__(self, traj):
        self.t, self.lo = traj.t, 0
        self.planned = "platform_quat_ref" in traj.series
        self.closure, self.orientation = -np.inf, -np.inf
        self.kci_sum, self.kci_min = BlockSum(), np.inf
        self.det_a: np.ndarray = np.zeros(0)  # det A at the sample before the window
        self.events: list[api.Event] = []

    def add(self, traj, rec, series: dict) -> dict:
        kci, det_a = series["kci"], series["det_a"]
        self.closure = max(self.closure, float(series["closure_error"].max()))
        self.kci_sum.add(kci)
        self.kci_min = min(self.kci_min, float(kci.min()))
        extra = {"platform_quat": canonical(rec.sensors["platform_quat"]), "base_angles": rec.q.copy()}
        if self.planned:
            error = rotation_angle(quat_to_matrix(traj.series["platform_quat_ref"]), _platform(rec))
            extra["orientation_error"] = error
            self.orientation = max(self.orientation, float(error.max()))
        det = np.concatenate([self.det_a, det_a])
        sign = np.sign(det)
        first = self.lo - len(self.det_a)  # the sample of det's first
        self.events += [api.Event(float(self.t[first + k]), float(self.t[first + k + 1]), "assembly_mode_change",
                                  {"det_a": [float(det[k]), float(det[k + 1])]})
                        for k in np.flatnonzero(sign[1:] * sign[:-1] < 0)]
        self.det_a, self.lo = det_a[-1:].copy(), self.lo + rec.t.size
        return extra

    def finish(self) -> tuple[dict, list[api.Event]]:
        report = {"closure_error_max": self.closure, "kci": {"mean": self.kci_sum.value() / self.lo,
                                                             "min": self.kci_min}}
        if self.planned:
            report["orientation_error_max"] = self.orientation
        report["assembly_mode_changes"] = len(self.events)
        return report, self.events


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
        """KCI, the angle to the nearest singular curve, det A (the triple product of its rows) and the
        loop-closure error along a recording."""
        rot = _platform(rec)
        terms = kci_terms(rec.q, rot)
        a = terms.a
        closure = np.maximum(np.linalg.norm(rec.sensors["tip2"] - rec.sensors["mount2"], axis=1),
                             np.linalg.norm(rec.sensors["tip3"] - rec.sensors["mount3"], axis=1))
        return {"kci": terms.kci, "singular_gap": axis_gaps(rot).min(axis=1),
                "det_a": triple(a[:, 0], a[:, 1], a[:, 2]), "closure_error": closure}

    def singular_sets(self, rec, tol: Tolerance) -> list[SingularSet]:
        """The six curves v_i = +-u_i, where det A = 0 (type 2) and, on the Agile Eye, det B = 0 too (type 1)."""
        gaps = axis_gaps(_platform(rec))
        return [SingularSet("type2", "type 2 (det A = 0; on the Agile Eye also type 1, det B = 0)",
                            "a platform axis along its base axis (v_i = +-u_i)", gaps.min(axis=1) / tol.angle,
                            {f"v{i + 1}": gaps[:, i] for i in range(3)})]

    def assemble(self, q: np.ndarray) -> dict[str, float]:
        return assemble(q)

    def summary(self, traj, rec, series: dict) -> Summary:
        """Report entries (closure error, KCI, orientation error), assembly-mode changes as events, and the
        platform orientation series: the Summariser's of the whole run as one window."""
        return Summariser(traj).whole(traj, rec, series)

    def summariser(self, traj) -> Summariser:
        return Summariser(traj)


ROBOT = AgileEye()
