"""The per-sample rate rules of cartesian_path's `task.method`, on the unit-consistent Jacobian Ju = [Jp / L; Jr]
(L the arm's reach) and the commanded twist x (the path's twist plus the closed loop's correction, cartesian_path):

    pinv          qd = Ju+ x, Ju+ = V S^-1 U^T over the non-zero singular values (the Moore-Penrose
                  pseudo-inverse: resolved motion rate control, Whitney, IEEE Trans. Man-Machine Syst. 10(2), 1969):
                  the tool stays on the path at whatever joint speed that takes, never scaled down;
    dls           qd = Ju^T (Ju Ju^T + lambda^2 I)^-1 x, lambda fixed (`task.damping`, dimensionless: a metre at the
                  end of the reach counts as a radian, so that in J = [Jp; Jr] the damping term is
                  lambda^2 diag(L^2, L^2, L^2, 1, 1, 1)) (damped least squares: Wampler, IEEE Trans. Syst. Man
                  Cybern. 16(1), 1986; Nakamura and Hanafusa, J. Dyn. Sys. Meas. Control 108, 1986, eq. 15);
    dls_adaptive  the same with lambda^2 = LAMBDA_MAX^2 (1 - (sigma_min / EPSILON)^2) below EPSILON, else 0
                  (Chiaverini, Siciliano and Egeland, IEEE Trans. Control Syst. Technol. 2(2), 1994, sec. III),
                  on a passage below EPSILON where pinv's rates would pass a speed limit: cartesian_path crosses
                  any other passage by pinv (ours; its docstring says why).

Each returns the rates, Ju's least singular value, the lambda^2 it used and the null-space projector I - Ju+ Ju
(a redundant arm's posture term). cartesian_path scales the damped rules' rates down under the speed limits.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

EPSILON = 0.05  # sigma_min of Ju (about 3 deg from a rank loss) below which the adaptive damping grows
LAMBDA_MAX = 0.05  # the adaptive damping at sigma_min = 0: joint rates at most 1 / (2 LAMBDA_MAX) = 10 per unit twist
DAMPING = 0.05  # dls's fixed lambda where the task gives none: LAMBDA_MAX, everywhere
RCOND = 1e-12  # pinv: singular values below this share of the largest count as zero
METHODS = ("dls_adaptive", "pinv", "dls", "time_scaling", "mink")
SCALED = ("dls_adaptive", "dls")  # the rules whose rates cartesian_path scales down under the speed limits

Rule = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, float, float, np.ndarray]]


def _damped(ju: np.ndarray, twist: np.ndarray, lam2_of: Callable[[float], float]):
    """Ju^T (Ju Ju^T + lambda^2 I)^-1 twist by the SVD (V S (S^2 + lambda^2)^-1 U^T), lambda^2 = lam2_of(sigma_min);
    sigma_min, lambda^2 and I - Ju+ Ju."""
    u, sv, vt = np.linalg.svd(ju, full_matrices=False)
    sigma = float(sv[-1])
    lam2 = lam2_of(sigma)
    rates = vt.T @ (sv / (sv**2 + lam2) * (u.T @ twist))
    return rates, sigma, lam2, np.eye(ju.shape[1]) - vt.T @ vt


def damped_rates(ju: np.ndarray, twist: np.ndarray) -> tuple[np.ndarray, float, float, np.ndarray]:
    """dls_adaptive: the variable damping (cartesian_path applies it where pinv would pass a speed limit)."""
    return _damped(ju, twist, lambda sigma: LAMBDA_MAX**2 * (1 - (sigma / EPSILON) ** 2) if sigma < EPSILON else 0.0)


def pinv_rates(ju: np.ndarray, twist: np.ndarray) -> tuple[np.ndarray, float, float, np.ndarray]:
    """pinv: Ju+ twist, sigma_min, 0 and I - Ju+ Ju."""
    u, sv, vt = np.linalg.svd(ju, full_matrices=False)
    keep = sv > RCOND * sv[0]
    inverse = np.divide(1.0, sv, out=np.zeros_like(sv), where=keep)
    rates = vt.T @ (inverse * (u.T @ twist))
    return rates, float(sv[-1]), 0.0, np.eye(ju.shape[1]) - vt[keep].T @ vt[keep]


def rule_of(method: str, damping: float | None) -> Rule:
    """The rate rule of a resolved-rate method (time_scaling's joint path is pinv's)."""
    if method == "dls_adaptive":
        return damped_rates
    if method == "dls":  # lambda fixed
        lam2 = float(DAMPING if damping is None else damping) ** 2
        return lambda ju, twist: _damped(ju, twist, lambda sigma: lam2)
    return pinv_rates
