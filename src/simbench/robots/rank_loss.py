"""What an arm loses where its Jacobian loses rank, read from the singular value decomposition of the
unit-consistent Jacobian Ju = [Jp / L; Jr] = U S V^T (L the arm's reach: robots.model_arm), at its least singular
value sigma_min (the min(6, dof)-th):

    lost_twist    the unit tool twist [vx, vy, vz, wx, wy, wz] (m/s, rad/s) the arm cannot make there: U's column
                  of sigma_min is a twist [v / L; w], so its position part is multiplied back by L, then the whole
                  renormalised;
    null_motion   the unit joint motion (rad or m per unit) that moves the tool by sigma_min alone, nothing at
                  sigma_min = 0: V's column of sigma_min.

The pair's sign is arbitrary (U and V flip together): it is fixed so that the null motion's largest component
is positive.

Where the vectors show it, the event is named by where the null motion's weight (its components squared, summing
to 1) lies, for arms of six joints or more (the last three taken as the wrist, the first as the shoulder),
never by the joints' names:

    wrist     CONCENTRATED of the weight or more in the last three joints: the arm stands still, the wrist's
              axes line up;
    shoulder  CONCENTRATED or more in the first and the last three joints, at least 1 - CONCENTRATED in the
              first: a turn of the first joint that the wrist undoes (the tool on the first joint's axis);
    elbow     the lost twist a translation (CONCENTRATED of its weight or more in its position part) and under
              1 - CONCENTRATED of the null motion in the first joint: the arm stretched or folded, unable to move
              the tool along its reach.

Anything else has no name: the vectors say it all.

The event's closest instant (`closest_sample`): a rank loss is a linear dependence among some of Ju's columns,
those the null motion moves (weight SUPPORT or more, at the span's least sigma_min). The instant is where those
columns alone are nearest dependence, the least singular value of Ju restricted to them: free of how the other
joints couple into the lost twist, which shifts the whole Ju's minimum when they move fast near the loss (the
PUMA's wrist: its columns 4 and 6 depend on q5 alone, so their minimum is |q5|'s). Where the null motion moves
every joint it is the whole Ju's minimum.
"""

from __future__ import annotations

import numpy as np

from simbench.api import Array

CONCENTRATED = 0.9  # share of a unit vector's weight (squared components) that counts as "in" a set of joints
SUPPORT = 0.05  # weight of a joint in the null motion that makes its column one of those the rank loss binds


def unit_jacobian(jac: Array, reach: float) -> Array:
    """Ju = [Jp / L; Jr] of Jacobians J = [Jp; Jr] (..., 6, dof): a metre at the end of the reach counts as a
    radian."""
    unit = np.array(jac, float)
    unit[..., :3, :] /= reach
    return unit


def rank_loss_detail(jac: Array, reach: float) -> dict:
    """sigma_min, lost_twist, null_motion and (where the rule of the module's docstring names it) `named`, of one
    Jacobian J (6, dof) of an arm of reach L."""
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
    """The sample of a near span's unit-consistent Jacobians ju (n, 6, dof) closest to its rank loss (the module's
    docstring): the least singular value of the columns that the null motion at the span's least sigma_min moves."""
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
