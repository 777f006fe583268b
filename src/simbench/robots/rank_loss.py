"""What an arm loses where its Jacobian loses rank, from the SVD of the unit-consistent Jacobian
Ju = [Jp / L; Jr] = U S V^T (L the reach: robots.model_arm) at its least singular value sigma_min:

    lost_twist    the unit tool twist [vx, vy, vz, wx, wy, wz] (m/s, rad/s) the arm cannot make: U's column of
                  sigma_min, a twist [v / L; w], its position part multiplied back by L, then renormalised;
    null_motion   the unit joint motion that moves the tool by sigma_min alone: V's column of sigma_min.

Their sign is fixed so that the null motion's largest component is positive.

The event is named by the joints' axes, never by their names: a revolute joint's column of J = [Jp; Jr] at the
tool point p is [u x (p - a); u], u its axis through a, so the columns hold every axis line. (Where the null
motion's weight lies does not name it: on the UR5's wrist set it spreads over joints 2, 3, 4 and 6.) For arms of
six revolute joints or more, the last three the wrist and the first the shoulder, with the wrist points w_e (on
axis n-2, nearest axis n-1) and w_s (on axis n-1, nearest axis n; both a spherical wrist's centre), three angles
say how far the joints must turn to reach each set:

    wrist     the wrist's axes parallel to one plane, det[u_n-2, u_n-1, u_n] = 0: the wrist cannot turn the tool
              about its normal (the PUMA's axes 4 and 6 in line; the UR's 4 and 6 parallel, so with 2 and 3).
              Only joint n-1 changes det (the others turn the three axes together, or none), at the rate
              det[u_n-2, u_n-1, u_n-1 x u_n]; the angle atan2(|det|, |rate|) is q5 folded into [0, 90] deg;
    elbow     w_e in the plane of axes 2 and 3 (parallel), the arm stretched or folded: turns of joints 2 and 3
              then make a turn about a parallel axis through w_e, which the wrist undoes (the UR's joint 4 is
              that axis). The angle at axis 3 between the planes through it and axis 2 and through it and w_e,
              folded, is q3's turn to the set where axes 2 and 3 are parallel;
    shoulder  w_s on the plane through axis 1 parallel to axis 2: joints 2 to n-2 move w_s normal to axis 2 (they
              are parallel to it or pass through w_s, as on the PUMA and the UR), the last two not at all, and
              joint 1 within the plane, so w_s's translation along axis 2 is lost. The angle atan2(|x|, |g|), x
              w_s's distance from the plane and g its rates across it under joints 2 to n-2, is their turn to
              the plane, to first order.

The event is named by the least angle where it is under NEAR; elsewhere, and on other arms, it has none. An arm
whose wrist does not decouple has other singular sets near these: the Jaco's stretched rank loss, 11.5 deg from
the elbow set, is named elbow.

The event's closest instant (`closest_sample`): a rank loss is a linear dependence among the columns of Ju that the
null motion moves (weight SUPPORT or more, at the span's least sigma_min); the instant is where those columns alone
are nearest dependence, free of how the other joints couple into the lost twist (the PUMA's wrist: its columns 4
and 6 depend on q5 alone). Where the null motion moves every joint it is the whole Ju's minimum.
"""

from __future__ import annotations

import numpy as np

from simbench.api import Array

NEAR = np.deg2rad(20.0)  # rad: the turn of the joints within which a singular set names the event
SUPPORT = 0.05  # weight of a joint in the null motion that makes its column one of those the rank loss binds


def unit_jacobian(jac: Array, reach: float) -> Array:
    """Ju = [Jp / L; Jr] of Jacobians J = [Jp; Jr] (..., 6, dof)."""
    unit = np.array(jac, float)
    unit[..., :3, :] /= reach
    return unit


def rank_loss_detail(jac: Array, reach: float) -> dict:
    """sigma_min, lost_twist, null_motion and, where the module's rule names it, `named`, of one J (6, dof)."""
    u, sv, vt = np.linalg.svd(unit_jacobian(jac, reach), full_matrices=False)
    k = len(sv) - 1
    null = vt[k]
    sign = 1.0 if null[np.argmax(np.abs(null))] >= 0 else -1.0
    twist = sign * np.concatenate([u[:3, k] * reach, u[3:, k]])
    twist /= np.linalg.norm(twist)
    out = {"sigma_min": float(sv[k]), "lost_twist": twist.tolist(), "null_motion": (sign * null).tolist()}
    name = _named(np.asarray(jac, float), reach)
    if name is not None:
        out["named"] = name
    return out


def closest_sample(ju: Array) -> int:
    """The sample of a near span's Jacobians ju (n, 6, dof) closest to its rank loss (the module's docstring)."""
    least = int(np.argmin(np.linalg.svd(ju, compute_uv=False)[:, -1]))
    _, sv, vt = np.linalg.svd(ju[least], full_matrices=False)
    bound = np.flatnonzero(vt[len(sv) - 1] ** 2 >= SUPPORT)
    if len(bound) == ju.shape[-1]:
        return least
    return int(np.argmin(np.linalg.svd(ju[:, :, bound], compute_uv=False)[:, -1]))


def _angles(jac: Array, reach: float) -> dict[str, float] | None:
    """The turn (rad) to the wrist, elbow and shoulder sets at one J (6, dof) by the module's rule; None for an arm
    of under six joints or with a prismatic one among the first three and last three."""
    dof = jac.shape[1]
    axes, velocity = jac[3:].T, jac[:3].T
    if dof < 6 or np.any(np.abs(np.linalg.norm(axes[[0, 1, 2, -3, -2, -1]], axis=1) - 1.0) > 1e-6):
        return None
    points = np.cross(axes, velocity)  # each axis' point nearest the tool point, from it
    lines = list(zip(points, axes))
    w_e, w_s = _nearest(lines[-3], lines[-2]), _nearest(lines[-2], lines[-1])
    tol = 1e-9 * reach
    return {"wrist": _wrist(axes), "elbow": _elbow(lines, w_e, tol),
            "shoulder": _shoulder(lines, velocity, w_s, tol)}


def _named(jac: Array, reach: float) -> str | None:
    """wrist, elbow or shoulder, the least of _angles where it is under NEAR, or None."""
    angles = _angles(jac, reach)
    if angles is None:
        return None
    name = min(angles, key=angles.get)
    return name if angles[name] < NEAR else None


def _nearest(a: tuple[Array, Array], b: tuple[Array, Array]) -> Array:
    """The point of line a = (point, direction) nearest line b (some point of it where they are parallel)."""
    (pa, ua), (pb, ub) = a, b
    s = np.linalg.lstsq(np.column_stack([ua, -ub]), pb - pa, rcond=None)[0][0]
    return pa + s * ua


def _folded(a: Array, b: Array, tol: float) -> float:
    """The angle (rad) between the lines along a and b, in [0, pi/2]; pi/2 where either vector is under tol."""
    if min(np.linalg.norm(a), np.linalg.norm(b)) < tol:
        return np.pi / 2
    return float(np.arctan2(np.linalg.norm(np.cross(a, b)), abs(a @ b)))


def _wrist(axes: Array) -> float:
    """atan2(|det W|, |d det W / d q_n-1|), W the last three axes (the module's docstring)."""
    u4, u5, u6 = axes[-3:]
    return float(np.arctan2(abs(np.linalg.det([u4, u5, u6])), abs(np.linalg.det([u4, u5, np.cross(u5, u6)]))))


def _elbow(lines: list, w_e: Array, tol: float) -> float:
    """The folded angle at axis 3 between the planes through it and axis 2 and through it and w_e."""
    (p2, u2), (p3, u3) = lines[1], lines[2]
    elbow = _nearest(lines[2], lines[1])
    return _folded(np.cross(u2, elbow - p2), np.cross(u3, w_e - p3), tol)


def _shoulder(lines: list, velocity: Array, w_s: Array, tol: float) -> float:
    """atan2(|x|, |g|): x w_s's distance from the plane through axis 1 parallel to axis 2, g its rates across it
    under joints 2 to n-2."""
    (p1, u1), (_, u2) = lines[0], lines[1]
    normal = np.cross(u1, u2)
    if np.linalg.norm(normal) < 1e-9:
        return np.pi / 2
    normal /= np.linalg.norm(normal)
    rates = [(v + np.cross(u, w_s)) @ normal for (_, u), v in zip(lines[1:-2], velocity[1:-2])]
    return float(np.arctan2(abs(normal @ (w_s - p1)), max(np.linalg.norm(rates), tol)))
