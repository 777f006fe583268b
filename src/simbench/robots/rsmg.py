"""RSMG (paper 001): a rotor turned about its centre O by four arms whose electromagnets grip it.

Arm i (all axes through O): an actuated base joint theta_i about u_i, an upper link of arc ALPHA to a passive
joint gamma_i about w_i, a lower link of arc BETA to the electromagnet (EM), whose axis v_i points at O, on a
free hinge about v_i. Constraints (eqs. 10-11): w_i . u_i = cos ALPHA, v_i . w_i = cos BETA.

  Frames: each arm has a frame F_i with z = u_i and x = X_REF[i]; at theta_i = 0, w_i lies in the F_i x-z plane,
  w_i = cos(ALPHA) u_i + sin(ALPHA) (cos theta_i x_i + sin theta_i y_i) (eq. 12). gamma_i is the angle at w_i
  between the planes (w_i, u_i) and (w_i, v_i): 0 with the lower link folded back towards u_i, 180 deg with it
  stretched out, both coplanar (type B, eq. 42).
  IK (eqs. 12-23): g = v^T [x y u]_Fi, g1 cos theta + g2 sin theta = (cos BETA - g3 cos ALPHA) / sin ALPHA = g4,
  theta = asin(g4 / rho) - delta or pi - asin(g4 / rho) - delta, delta = atan2(g1, g2), rho = |(g1, g2)|.
  (Eq. 21 prints asin(g4): the division by rho, implied by eqs. 19-20, is lost.) The two roots are mirror images;
  the one with gamma in (0, 180 deg) is kept.
  DK (eqs. 24-32): v_i from theta_i and gamma_i, then R = L K^T (K K^T)^-1 with K the gripped contact points in
  the rotor frame and L the same in the base frame.
  Singularities (eqs. 33-42): A omega + B theta_dot = 0, A rows (w_i x v_i)^T, B = diag((w_i x u_i) . v_i).
  Type A: rank A < 3 over the gripping arms, tested by the 3 x 3 minors (det A1, det A2 of eqs. 37-39); type B:
  det B = 0, some gamma_i at 0 or 180 deg.

Design (the surviving text does not give it; models/rsmg/README.md justifies each choice): four arms on the axes
of a regular tetrahedron, one from below; ALPHA = BETA = 70 deg; three candidate contact points per arm, 120 deg
apart on the rotor's great circle normal to that arm's axis at the home pose.
"""

from __future__ import annotations

import numpy as np

from simbench.api import Summary
from simbench.robots import REVOLUTE, Robot, SingularSet, Tolerance, scene
from simbench.rotations import quat_to_matrix, rotation_angle

ALPHA = np.deg2rad(70.0)
BETA = np.deg2rad(70.0)
RADIUS = 0.05  # m: the rotor
ARMS = 4
CANDIDATES = 3
GAMMA_BAND = np.deg2rad([10.0, 170.0])  # eq. 45
DET_A_MIN = 0.01  # eq. 46


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _tetrahedron() -> np.ndarray:
    """Arm axes u_i: one straight down, three at 109.47 deg from it, 120 deg apart in azimuth."""
    up = 1.0 / 3.0
    side = np.sqrt(1.0 - up**2)
    azimuth = np.deg2rad([0.0, 120.0, 240.0])
    return np.vstack([[0.0, 0.0, -1.0], np.stack([side * np.cos(azimuth), side * np.sin(azimuth),
                                                  np.full(3, up)], axis=-1)])


U = _tetrahedron()
X_REF = _unit(np.vstack([[1.0, 0.0, 0.0]] + [[0.0, 0.0, 1.0] - u[2] * u for u in U[1:]]))
Y_REF = np.cross(U, X_REF)
# Candidate contact points (rotor frame): arm i's three, 120 deg apart on the great circle normal to u_i.
_PHASE = 2 * np.pi / 3 * np.arange(CANDIDATES)
POINTS = np.stack([np.cos(_PHASE)[:, None] * X_REF[i] + np.sin(_PHASE)[:, None] * Y_REF[i] for i in range(ARMS)])
JOINTS = tuple(f"theta{i + 1}" for i in range(ARMS)) + tuple(f"gamma{i + 1}" for i in range(ARMS))
KINDS = (REVOLUTE,) * (2 * ARMS)
LOWER = np.full(2 * ARMS, -np.inf)
UPPER = np.full(2 * ARMS, np.inf)
QD_MAX = np.full(2 * ARMS, 4 * np.pi)  # 2 turns/s: a small direct-drive motor's speed, the base joints' and gammas'


def upper_axis(arm: int, theta: np.ndarray) -> np.ndarray:
    """w_i (N, 3) for base angles theta (N,) of arm `arm` (eq. 12)."""
    theta = np.asarray(theta, float)[..., None]
    return np.cos(ALPHA) * U[arm] + np.sin(ALPHA) * (np.cos(theta) * X_REF[arm] + np.sin(theta) * Y_REF[arm])


def folded(arm: int, w: np.ndarray) -> np.ndarray:
    """The EM axis with gamma = 0: w turned by BETA back towards u_i, in their plane."""
    toward_u = (U[arm] - np.cos(ALPHA) * w) / np.sin(ALPHA)
    return np.cos(BETA) * w + np.sin(BETA) * toward_u


def _rotate(axis: np.ndarray, angle: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """Rodrigues: vector (N, 3) turned about unit axis (N, 3) by angle (N,)."""
    c, s = np.cos(angle)[..., None], np.sin(angle)[..., None]
    dot = np.einsum("...i,...i->...", axis, vector)[..., None]
    return vector * c + np.cross(axis, vector) * s + axis * dot * (1 - c)


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
    return np.arctan2(np.einsum("...i,...i->...", np.cross(v0, v), w), np.einsum("...i,...i->...", v0, v) - along)


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
    gammas = [gamma_of(arm, th, v) for th in roots]
    first = gammas[0] > 0
    theta = np.angle(np.exp(1j * np.where(first, roots[0], roots[1])))
    gamma = np.where(first, gammas[0], gammas[1])
    return theta, gamma


def dk(arms: list[int], theta: np.ndarray, gamma: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Rotor orientation (3, 3) from the gripping arms' base angles and gammas and the contact points they hold
    (k, 3, rotor frame): R = L K^T (K K^T)^-1 (eq. 32), K and L with the points as columns."""
    v = np.stack([em_axis(i, t, g) for i, t, g in zip(arms, theta, gamma)])
    k, l_ = points.T, v.T
    return l_ @ k.T @ np.linalg.inv(k @ k.T)


def jacobian_rows(arm: int, theta: np.ndarray, gamma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row of A, (w_i x v_i) (N, 3), and diagonal entry of B, (w_i x u_i) . v_i (N,) (eqs. 34-35)."""
    w = upper_axis(arm, theta)
    v = em_axis(arm, theta, gamma)
    a = np.cross(w, v)
    return a, np.einsum("...i,...i->...", np.cross(w, U[arm]), v)


def type_a_measure(rows: np.ndarray, engaged: np.ndarray) -> np.ndarray:
    """The largest |3 x 3 minor| of A over the gripping arms (N,): zero exactly where rank A < 3 (eqs. 36-39).

    rows (N, 4, 3): A's rows for every arm; engaged (N, 4) bool. With four arms gripping this is
    max(|det A1|, |det A2|, ...), the paper's test; with three, the one determinant.
    """
    best = np.zeros(len(rows))
    for drop in range(ARMS):
        keep = [i for i in range(ARMS) if i != drop]
        det = np.abs(np.linalg.det(rows[:, keep]))
        usable = engaged[:, keep].all(axis=1)
        best = np.where(usable, np.maximum(best, det), best)
    return best


def _engaged(rec) -> np.ndarray:
    return np.stack([rec.eq_active[f"grip{i + 1}"] for i in range(ARMS)], axis=1).astype(bool)


def _rows(rec) -> np.ndarray:
    theta, gamma = rec.q[:, :ARMS], rec.q[:, ARMS:]
    return np.stack([jacobian_rows(i, theta[:, i], gamma[:, i])[0] for i in range(ARMS)], axis=1)


def _type_b_gap(gamma: np.ndarray, engaged: np.ndarray) -> np.ndarray:
    """Smallest angle of a gripping arm's gamma from 0 or 180 deg (N,); pi/2 where none grips."""
    gap = np.minimum(np.abs(gamma), np.abs(np.pi - np.abs(gamma)))
    return np.where(engaged, gap, np.pi / 2).min(axis=1)


def measures(rec) -> dict[str, np.ndarray]:
    """The type A measure (largest 3 x 3 minor of A over the gripping arms) and the type B gap."""
    engaged = _engaged(rec)
    return {"type_a": type_a_measure(_rows(rec), engaged), "type_b_gap": _type_b_gap(rec.q[:, ARMS:], engaged)}


def singular_sets(rec, tol: Tolerance) -> list[SingularSet]:
    """Type A: |det A1| and |det A2| (every 3 x 3 minor over the gripping arms) under 0.01 (eq. 46). Type B: a
    gripping arm's gamma within 10 deg of 0 or 180 deg (eq. 45). The paper's own thresholds, not `tol`."""
    engaged = _engaged(rec)
    type_a = type_a_measure(_rows(rec), engaged)
    type_b = _type_b_gap(rec.q[:, ARMS:], engaged)
    return [SingularSet("typeA", "type A (interior, rank A < 3)", "|det A1|, |det A2| < 0.01", type_a / DET_A_MIN,
                        {"det": type_a}),
            SingularSet("typeB", "type B (boundary, det B = 0)", "a gripping arm's gamma within 10 deg of 0 or 180",
                        type_b / GAMMA_BAND[0], {"gamma": type_b})]


def summary(traj, rec, series: dict) -> tuple[dict, list[dict], dict]:
    """Rotor tracking, gripping counts and gammas, and the switch events with how far each grip snapped."""
    engaged = _engaged(rec)
    gamma = rec.q[:, ARMS:]
    rot = quat_to_matrix(rec.sensors["rotor_quat"])
    error = rotation_angle(quat_to_matrix(traj.series["rotor_quat_ref"]), rot)
    held = gamma[engaged]
    closure = _closure_error(rec, rot, engaged)
    report = {
        "rotor_error_max": float(error.max()),
        "closure_error_max": float(closure.max()),
        "fewest_gripping": int(engaged.sum(axis=1).min()),
        "gripping_gamma": {"min": float(held.min()), "max": float(held.max())},
        "switch_events": _switch_events(traj, rec, rot),
    }
    extra = {"gamma": gamma.copy(), "engaged": engaged, "rotor_quat": rec.sensors["rotor_quat"].copy(),
             "rotor_error": error, "closure_error": closure}
    return report, [], extra


def _closure_error(rec, rot: np.ndarray, engaged: np.ndarray) -> np.ndarray:
    """How far each gripping EM's tip has moved on the rotor since it gripped (the weld's violation: the loop
    through the arm and the rotor failing to close), the largest over the arms (N,), in m."""
    closure = np.zeros(rec.t.size)
    for arm in range(ARMS):
        on_rotor = np.einsum("nji,nj->ni", rot, rec.sensors[f"em{arm + 1}_tip"])  # R^T tip, in the rotor's frame
        grip = engaged[:, arm] & ~np.concatenate([[False], engaged[:-1, arm]])  # the rows where it grips
        since = np.maximum.accumulate(np.where(grip, np.arange(rec.t.size), 0))
        drift = np.linalg.norm(on_rotor - on_rotor[since], axis=1)
        closure = np.maximum(closure, np.where(engaged[:, arm], drift, 0.0))
    return closure


def _switch_events(traj, rec, rot: np.ndarray) -> list[dict]:
    """One event a re-grip: release to grip, the arm, the points; the grip's snap (the EM tip's jump in the step
    after the weld goes on, beyond what its motion before carried it: the second difference of its position); and
    the grip's offset (how far the EM tip is from the planned contact point when it grips, which the weld then
    keeps). `rot`: the recorded rotor orientations."""
    events = []
    releases = {}
    for sw in traj.switches:
        arm = sw.detail["arm"]
        if not sw.active:
            releases[arm] = sw
            continue
        if arm not in releases:
            continue  # the initial grips
        k = int(np.clip(np.searchsorted(rec.t, sw.t - 1e-9), 1, len(rec.t) - 2))
        tip = rec.sensors[f"em{arm}_tip"]
        jump = float(np.linalg.norm(tip[k + 1] - 2 * tip[k] + tip[k - 1]))
        point = rot[k] @ POINTS[arm - 1, "abc".index(sw.detail["to_point"])] * RADIUS
        events.append({"t_start": releases[arm].t, "t_end": sw.t, "kind": "switch",
                       "detail": {"arm": arm, "from_point": sw.detail["from_point"], "to_point": sw.detail["to_point"],
                                  "contact_jump": jump, "grip_offset": float(np.linalg.norm(tip[k] - point))}})
    return events


def paint(model, rec, row: int) -> None:
    """Colour each EM by its state in this frame: green while it grips, grey while it is free."""
    for i in range(ARMS):
        on = rec.eq_active[f"grip{i + 1}"][row]
        model.geom(f"em{i + 1}").rgba = [0.2, 0.85, 0.3, 1.0] if on else [0.55, 0.55, 0.58, 1.0]


def plots(traj, rec, result, folder) -> list[str]:
    """gamma of every arm against time with its switches (paper 001's Fig. 11 is arm 1's)."""
    import matplotlib.pyplot as plt

    engaged = _engaged(rec)
    fig, axes = plt.subplots(ARMS, 1, figsize=(8, 7), sharex=True)
    for i, ax in enumerate(axes):
        g = np.rad2deg(rec.q[:, ARMS + i])
        ax.plot(rec.t, np.where(engaged[:, i], g, np.nan), color="tab:green", lw=1.2, label="gripping")
        ax.plot(rec.t, np.where(engaged[:, i], np.nan, g), color="tab:gray", lw=1.0, label="swinging")
        for bound in np.rad2deg(GAMMA_BAND):
            ax.axhline(bound, color="k", ls=":", lw=0.8)
        for e in result.extra["switch_events"]:
            if e["detail"]["arm"] == i + 1:
                ax.axvline(e["t_end"], color="tab:red", lw=0.8)
        ax.set_ylabel(f"gamma{i + 1} (deg)")
        ax.set_ylim(-5, 185)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[0].set_title("gamma of each arm (red: re-grips; dotted: the 10-170 deg band)")
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(folder / "gamma.png", dpi=110)
    plt.close(fig)
    return ["gamma.png"]


class RSMG(Robot):
    """simbench.api.Robot of the RSMG, whose rotor pose depends on the gripped points: no fk of the joints alone (paper 001)."""

    def __init__(self):
        super().__init__(
            name="rsmg",
            description="RSMG: a rotor turned by four electromagnet arms that re-grip it (switched welds)",
            paper="001: Novel 3-DOF Reconfigurable Spherical Motion Generator with Unlimited Workspace",
            joints=JOINTS,
            kinds=KINDS,
            lower=LOWER,
            upper=UPPER,
            qd_max=QD_MAX,
            tool_site="marker",
            tool_sensor="marker_pos",
            orientation_error="rotor_error",
            breaking=("typeA", "typeB"),
            sensors=("rotor_quat", "em1_tip", "em2_tip", "em3_tip", "em4_tip"),
            scene=scene("rsmg"),
        )

    def measures(self, rec) -> dict[str, np.ndarray]:
        return measures(rec)

    def singular_sets(self, rec, tol: Tolerance) -> list[SingularSet]:
        return singular_sets(rec, tol)

    def summary(self, traj, rec, series: dict) -> Summary:
        return Summary(*summary(traj, rec, series))

    def paint(self, model, rec, row: int) -> None:
        paint(model, rec, row)

    def plots(self, traj, rec, analysis, folder) -> list[str]:
        return plots(traj, rec, analysis, folder)


ROBOT = RSMG()
