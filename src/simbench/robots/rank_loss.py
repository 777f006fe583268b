"""What an arm loses where its Jacobian loses rank, from the SVD of the unit-consistent Jacobian
Ju = [Jp / L; Jr] = U S V^T (L the reach: robots.model_arm) at its least singular value sigma_min:

    lost_twist    the unit tool twist [vx, vy, vz, wx, wy, wz] (m/s, rad/s) the arm cannot make: U's column of
                  sigma_min, a twist [v / L; w], its position part multiplied back by L, then renormalised;
    null_motion   the unit joint motion that moves the tool by sigma_min alone: V's column of sigma_min.

Their sign is fixed so that the null motion's largest component is positive. For arms of six joints or more (the
last three the wrist, the first the shoulder), the event is named by where the null motion's weight (its squared
components) lies, never by the joints' names:

    wrist     CONCENTRATED or more in the last three joints: the wrist's axes line up;
    shoulder  CONCENTRATED or more in the first and the last three, at least 1 - CONCENTRATED in the first: a turn
              of the first joint that the wrist undoes (the tool on the first joint's axis);
    elbow     the lost twist a translation (CONCENTRATED or more in its position part), under 1 - CONCENTRATED of
              the null motion in the first joint: the arm stretched or folded.

The event's closest instant (`closest_sample`): a rank loss is a linear dependence among the columns of Ju that the
null motion moves (weight SUPPORT or more, at the span's least sigma_min); the instant is where those columns alone
are nearest dependence, free of how the other joints couple into the lost twist (the PUMA's wrist: its columns 4
and 6 depend on q5 alone). Where the null motion moves every joint it is the whole Ju's minimum.
"""

from __future__ import annotations

import numpy as np

from simbench.api import Array

CONCENTRATED = 0.9  # share of a unit vector's weight (squared components) that counts as "in" a set of joints
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
    name = _named(twist, sign * null)
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


def _named(twist: Array, null: Array) -> str | None:
    """wrist, shoulder or elbow by the module docstring's rule, or None."""
    if len(null) < 6:
        return None
    weight = null**2
    if weight[-3:].sum() >= CONCENTRATED:
        return "wrist"
    if weight[0] + weight[-3:].sum() >= CONCENTRATED and weight[0] >= 1 - CONCENTRATED:
        return "shoulder"
    if (twist[:3] ** 2).sum() >= CONCENTRATED and weight[0] < 1 - CONCENTRATED:
        return "elbow"
    return None
