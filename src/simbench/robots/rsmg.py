"""RSMG (paper 001): a rotor turned about its centre O by four arms whose electromagnets grip it.

Arm i (all axes through O): an actuated base joint theta_i about u_i, an upper link of arc ALPHA to a passive
joint gamma_i about w_i, a lower link of arc BETA to the electromagnet (EM), whose axis v_i points at O, on a
free hinge about v_i. Constraints (eqs. 10-11): w_i . u_i = cos ALPHA, v_i . w_i = cos BETA.

  w_i = cos(ALPHA) u_i + sin(ALPHA) (cos theta_i x_i + sin theta_i y_i) (eq. 12), x_i = X_REF[i]; gamma_i is the
  angle at w_i between the planes (w_i, u_i) and (w_i, v_i): 0 folded back towards u_i, 180 deg stretched out.
  IK (eqs. 12-23): theta = asin(g4 / rho) - delta or its mirror; eq. 21 prints asin(g4), the division by rho
  (implied by eqs. 19-20) lost. The root with gamma in (0, 180 deg) is kept.
  DK (eqs. 24-32): R = L K^T (K K^T)^-1, K the gripped points in the rotor frame, L in the base frame.
  Singularities (eqs. 33-42): A omega + B theta_dot = 0, A rows (w_i x v_i)^T, B = diag((w_i x u_i) . v_i); type A:
  rank A < 3 over the gripping arms (eqs. 37-39); type B: some gamma_i at 0 or 180 deg.

The design (rsmg_geometry; models/rsmg/README.md justifies it) is not in the surviving text; what a run's outputs
show of the RSMG is rsmg_outputs'.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from simbench.api import Summary
from simbench.maths.vectors import cross, triple
from simbench.robots import Robot, SingularSet, Tolerance, rsmg_outputs, scene
from simbench.robots.rsmg_geometry import (ALPHA, ARMS, BETA, CANDIDATES, CHUNK, DET_A_MIN, GAMMA_BAND,  # noqa: F401
                                          JOINTS, KINDS, LOWER, POINTS, QD_MAX, RADIUS, UPPER, U, X_REF, Y_REF,
                                          gripping)

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def upper_axis(arm: int, theta: np.ndarray) -> np.ndarray:
    """w_i (N, 3) for base angles theta (N,) of arm `arm` (eq. 12), component by component (faster than (N, 1) by
    (3,) in the IK's inner loops)."""
    theta = np.asarray(theta, float)
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.cos(ALPHA) * U[arm, j] + np.sin(ALPHA) * (c * X_REF[arm, j] + s * Y_REF[arm, j])
                     for j in range(3)], axis=-1)


def folded(arm: int, w: np.ndarray) -> np.ndarray:
    """The EM axis with gamma = 0: w turned by BETA back towards u_i, in their plane."""
    toward_u = [(U[arm, j] - np.cos(ALPHA) * w[..., j]) / np.sin(ALPHA) for j in range(3)]
    return np.stack([np.cos(BETA) * w[..., j] + np.sin(BETA) * toward_u[j] for j in range(3)], axis=-1)


def _rotate(axis: np.ndarray, angle: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """Rodrigues: vector (N, 3) turned about unit axis (N, 3) by angle (N,)."""
    c, s = np.cos(angle), np.sin(angle)
    dot = np.einsum("...i,...i->...", axis, vector)
    normal = cross(axis, vector)
    return np.stack([vector[..., j] * c + normal[..., j] * s + axis[..., j] * dot * (1 - c) for j in range(3)],
                    axis=-1)


def em_axis(arm: int, theta: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """v_i (N, 3) for the arm's base angle and gamma (eqs. 24-27)."""
    w = upper_axis(arm, theta)
    return _rotate(w, np.asarray(gamma, float), folded(arm, w))


def gamma_of(arm: int, theta: np.ndarray, v: np.ndarray) -> np.ndarray:
    """gamma (N,) in (-pi, pi] putting the EM axis at v for base angle theta."""
    w = upper_axis(arm, theta)
    v0 = folded(arm, w)
    # Both lie on the cone of half-angle BETA about w: compare their parts normal to w.
    along = np.einsum("...i,...i->...", v0, w) * np.einsum("...i,...i->...", v, w)
    return np.arctan2(np.einsum("...i,...i->...", cross(v0, v), w), np.einsum("...i,...i->...", v0, v) - along)


def ik(arm: int, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(theta, gamma) (N,) reaching EM axes v (N, 3) with gamma in (0, pi) (eqs. 12-23); NaN where out of reach."""
    v = np.atleast_2d(v)
    g1, g2, g3 = v @ X_REF[arm], v @ Y_REF[arm], v @ U[arm]
    g4 = (np.cos(BETA) - g3 * np.cos(ALPHA)) / np.sin(ALPHA)  # eq. 18
    rho = np.hypot(g1, g2)
    delta = np.arctan2(g1, g2)  # eq. 23
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.arcsin(g4 / rho)
    roots = (s - delta, np.pi - s - delta)  # eqs. 21-22
    both = gamma_of(arm, np.concatenate(roots), np.concatenate([v, v]))  # both roots' in one pass: half the calls
    gammas = (both[:len(v)], both[len(v):])
    first = gammas[0] > 0
    theta = np.angle(np.exp(1j * np.where(first, roots[0], roots[1])))
    gamma = np.where(first, gammas[0], gammas[1])
    return theta, gamma


def dk(arms: list[int], theta: np.ndarray, gamma: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Rotor orientation (3, 3) from the gripping arms' angles and their contact points (k, 3, rotor frame): R =
    L K^T (K K^T)^-1 (eq. 32)."""
    v = np.stack([em_axis(i, t, g) for i, t, g in zip(arms, theta, gamma)])
    k, l_ = points.T, v.T
    return l_ @ k.T @ np.linalg.inv(k @ k.T)


def jacobian_rows(arm: int, theta: np.ndarray, gamma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row of A, (w_i x v_i) (N, 3), and diagonal entry of B, (w_i x u_i) . v_i (N,) (eqs. 34-35)."""
    w = upper_axis(arm, theta)
    v = em_axis(arm, theta, gamma)
    return cross(w, v), np.einsum("...i,...i->...", cross(w, U[arm]), v)


def a_row(arm: int, theta: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """Row of A alone, w_i x v_i (N, 3) (eq. 34), without B's entry."""
    return cross(upper_axis(arm, theta), em_axis(arm, theta, gamma))


def type_a_measure(rows: np.ndarray, engaged: np.ndarray) -> np.ndarray:
    """The largest |3 x 3 minor| of A over the gripping arms (N,): zero exactly where rank A < 3 (eqs. 36-39).
    rows (N, 4, 3): every arm's row of A; engaged (N, 4) bool."""
    best = np.zeros(len(rows))
    for drop in range(ARMS):
        i, j, k = (arm for arm in range(ARMS) if arm != drop)
        det = np.abs(triple(rows[:, i], rows[:, j], rows[:, k]))
        usable = engaged[:, [i, j, k]].all(axis=1)
        best = np.where(usable, np.maximum(best, det), best)
    return best


def _rows(q: np.ndarray) -> np.ndarray:
    """A's rows a_i = w_i x v_i (N, 4, 3) for every arm at once from joints q (N, 8), jacobian_rows' expanded:
    a_i = sin(BETA) [(c st + s cos(ALPHA) ct) x_i + (s cos(ALPHA) st - c ct) y_i - s sin(ALPHA) u_i],
    c, s = cos, sin gamma_i and ct, st = cos, sin theta_i."""
    theta, gamma = q[:, :ARMS], q[:, ARMS:]
    ct, st, c, s = np.cos(theta), np.sin(theta), np.cos(gamma), np.sin(gamma)
    s_cos = np.cos(ALPHA) * s
    along_x, along_y, along_u = c * st + s_cos * ct, s_cos * st - c * ct, -np.sin(ALPHA) * s
    return np.sin(BETA) * (along_x[..., None] * X_REF + along_y[..., None] * Y_REF + along_u[..., None] * U)


def _type_b_gap(gamma: np.ndarray, engaged: np.ndarray) -> np.ndarray:
    """Smallest angle of a gripping arm's gamma from 0 or 180 deg (N,); pi/2 where none grips."""
    gap = np.minimum(np.abs(gamma), np.abs(np.pi - np.abs(gamma)))
    return np.where(engaged, gap, np.pi / 2).min(axis=1)


def _type_a(q: np.ndarray, engaged: np.ndarray) -> np.ndarray:
    """type_a_measure of the recorded joints (N,), CHUNK samples at a time to bound the temporaries."""
    out = np.empty(len(q))
    for a in range(0, len(q), CHUNK):
        out[a:a + CHUNK] = type_a_measure(_rows(q[a:a + CHUNK]), engaged[a:a + CHUNK])
    return out


class RSMG(Robot):
    """The RSMG (paper 001): its rotor pose depends on the gripped points, so no fk of the joints alone."""

    def __init__(self):
        super().__init__(
            name="rsmg",
            description="RSMG: a rotor turned by four electromagnet arms that re-grip it (switched welds)",
            paper="001: Novel 3-DOF Reconfigurable Spherical Motion Generator with Unlimited Workspace",
            joints=JOINTS, kinds=KINDS, lower=LOWER, upper=UPPER, qd_max=QD_MAX,
            tool_site="marker", tool_sensor="marker_pos", orientation_error="rotor_error", breaking=("typeA", "typeB"),
            sensors=("rotor_quat", "em1_tip", "em2_tip", "em3_tip", "em4_tip"), scene=scene("rsmg"),
        )

    def measures(self, rec) -> dict[str, np.ndarray]:
        """The type A measure (largest 3 x 3 minor of A over the gripping arms) and the type B gap."""
        engaged = gripping(rec)
        return {"type_a": _type_a(rec.q, engaged), "type_b_gap": _type_b_gap(rec.q[:, ARMS:], engaged)}

    def singular_sets(self, rec, tol: Tolerance) -> list[SingularSet]:
        return self.singular_sets_from(rec, tol, self.measures(rec))

    def singular_sets_from(self, rec, tol: Tolerance, measures: dict[str, np.ndarray]) -> list[SingularSet]:
        """Type A: |det A1| and |det A2| (every 3 x 3 minor over the gripping arms) under 0.01 (eq. 46). Type B: a
        gripping arm's gamma within 10 deg of 0 or 180 deg (eq. 45). The paper's own thresholds, not `tol`."""
        type_a, type_b = measures["type_a"], measures["type_b_gap"]
        return [SingularSet("typeA", "type A (interior, rank A < 3)", "|det A1|, |det A2| < 0.01",
                            type_a / DET_A_MIN, {"det": type_a}),
                SingularSet("typeB", "type B (boundary, det B = 0)", "a gripping arm's gamma within 10 deg of 0 or "
                            "180", type_b / GAMMA_BAND[0], {"gamma": type_b})]

    def summary(self, traj, rec, series: dict) -> Summary:
        """Rotor tracking, gripping counts and gammas, and the switch events: the Summariser's over one window."""
        return rsmg_outputs.Summariser(traj).whole(traj, rec, series)

    def summariser(self, traj):
        return rsmg_outputs.Summariser(traj)

    def paint(self, model, rec, row: int) -> None:
        rsmg_outputs.paint(model, rec, row)

    def plots(self, traj, rec, analysis) -> dict[str, Figure]:
        return rsmg_outputs.plots(traj, rec, analysis)


ROBOT = RSMG()
