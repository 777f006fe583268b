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
                  any other passage by pinv (ours; its docstring says why);
    sns           Saturation in the Null Space (Flacco, De Luca and Khatib, ICRA 2012, Alg. 1; IEEE Trans. Robot.
                  31(3), 2015): each joint's rate bounded within the sample by its speed limit and by its range,
                  (limit - q) / dt; while pinv's rates pass a bound, the most critical joint (the one that bounds
                  the task's scale most) is saturated at its bound and the task solved again by the others
                  (qd = qd_N + (Ju W)+ (x - Ju qd_N), W the free joints); where the free joints cannot make the
                  task (Ju W of lower rank than Ju), the task is scaled by the largest s <= 1 any saturation set
                  found keeps within every bound: qd = qd_N + (Ju W)+ (s x - Ju qd_N), so that Ju qd = s x, the
                  twist scaled, not turned. On an arm with no joints to spare it is task scaling alone;
    gradient      pinv plus the null-space gradient of manipulability (Liegeois, IEEE Trans. Syst. Man Cybern.
                  7(12), 1977): qd = Ju+ x + K_W (I - Ju+ Ju) grad w, w = sqrt(det(Ju Ju^T)) (Yoshikawa, Int. J.
                  Robot. Res. 4(2), 1985) of the task's rows of Ju, its gradient by central differences of MuJoCo's
                  Jacobian, K_W = GRADIENT_GAIN; a redundant arm's only (cartesian_path refuses it elsewhere);
    priority      task priority, the tool's point first (J1, x1: Ju's and x's position rows), its orientation
                  second (J2, x2): qd = J1# x1 + (J2 N1)# (x2 - J2 J1# x1), N1 = I - J1+ J1 (Nakamura, Hanafusa
                  and Yoshikawa, Int. J. Robot. Res. 6(2), 1987; Chiaverini, IEEE Trans. Robot. Autom. 13(3),
                  1997, eq. 8), both inverses dls_adaptive's damped one (the singularity-robust inverse, ibid.):
                  J1# exact wherever J1's least singular value is at least EPSILON, so that the point is kept and
                  the orientation alone given up near a wrist singularity. A free task (the point's rows alone)
                  is its first task alone. Chiaverini's own proposal, eq. 34, qd = J1# x1 + N1 J2# x2, leaves out
                  J2 J1# x1: it would not make the orientation's twist even far from every singularity.

Each rule (a Rule) returns the rates, Ju's least singular value, the lambda^2 it used (priority: the larger of its
two) and `basis`, the rows of V^T that span Ju's row space: the null-space projector I - Ju+ Ju, in which a
redundant arm returns to its start posture (gradient: climbs w), is null_projector(basis), made only where an arm
has joints to spare. sns is solved with its bounds (sns_rates). cartesian_path scales the damped rules' rates (dls,
dls_adaptive, priority) down under the speed limits (`Resolver`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

import numpy as np

from simbench.robots.rank_loss import unit_jacobian

EPSILON = 0.05  # sigma_min of Ju (about 3 deg from a rank loss) below which the adaptive damping grows
LAMBDA_MAX = 0.05  # the adaptive damping at sigma_min = 0: joint rates at most 1 / (2 LAMBDA_MAX) = 10 per unit twist
DAMPING = 0.05  # dls's fixed lambda where the task gives none: LAMBDA_MAX, everywhere
RCOND = 1e-12  # pinv: singular values below this share of the largest count as zero
GRADIENT_GAIN = 10.0  # rad^2/s: gradient's K_W, the null-space rate per unit of w's gradient (w per rad)
GRADIENT_STEP = 1e-6  # rad (or m): the central differences' step of w's gradient
METHODS = ("dls_adaptive", "pinv", "dls", "time_scaling", "mink", "sns", "gradient", "priority", "ruckig")

Rule = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, float, float, np.ndarray]]


@cache
def _gesdd():
    """LAPACK's dgesdd, SciPy imported on the first plan (not by validation or `simbench list`)."""
    from scipy.linalg.lapack import dgesdd

    return dgesdd


def thin_svd(ju: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """U, S, V^T of one small matrix (the thin SVD), by LAPACK's dgesdd called directly: NumPy's svd wraps the same
    routine in a batched ufunc whose call costs more than a 6 x 6 decomposition, and the rules call it at every
    control sample. NumPy's where dgesdd does not converge (it raises LinAlgError)."""
    u, sv, vt, info = _gesdd()(ju, full_matrices=0)
    if info != 0:
        return np.linalg.svd(ju, full_matrices=False)
    return u, sv, vt


def null_projector(basis: np.ndarray) -> np.ndarray:
    """I - Ju+ Ju (dof, dof) from a rule's `basis` (rank, dof), the rows of V^T that span Ju's row space."""
    return np.eye(basis.shape[1]) - basis.T @ basis


def _damped(ju: np.ndarray, twist: np.ndarray, lam2_of: Callable[[float], float], rank_only: bool = False):
    """Ju^T (Ju Ju^T + lambda^2 I)^-1 twist by the SVD (V S (S^2 + lambda^2)^-1 U^T), lambda^2 = lam2_of(sigma_min);
    sigma_min, lambda^2 and the basis of Ju's row space (null_projector's). Where `rank_only`, the singular values
    under RCOND of the largest, or of 1 (rows a planar arm can never move, a task's rows beyond the joints left to
    it), count as zero, and sigma_min is the least of the others (0, undamped, where none is left)."""
    u, sv, vt = thin_svd(ju)
    if rank_only:
        keep = sv > RCOND * max(float(sv[0]), 1.0)
        u, sv, vt = u[:, keep], sv[keep], vt[keep]
    sigma = float(sv[-1]) if len(sv) else 0.0
    lam2 = lam2_of(sigma) if len(sv) else 0.0
    rates = vt.T @ (sv / (sv**2 + lam2) * (u.T @ twist))
    return rates, sigma, lam2, vt


def _adaptive(sigma: float) -> float:
    """dls_adaptive's lambda^2 at the least singular value sigma."""
    return LAMBDA_MAX**2 * (1 - (sigma / EPSILON) ** 2) if sigma < EPSILON else 0.0


def damped_rates(ju: np.ndarray, twist: np.ndarray) -> tuple[np.ndarray, float, float, np.ndarray]:
    """dls_adaptive: the variable damping (cartesian_path applies it where pinv would pass a speed limit)."""
    return _damped(ju, twist, _adaptive)


def _pseudo_inverse(ju: np.ndarray) -> tuple[Callable[[np.ndarray], np.ndarray], float, np.ndarray, int]:
    """x -> Ju+ x, Ju+ = V S^-1 U^T over the singular values above RCOND of the largest; Ju's least singular value,
    the basis of its row space (null_projector's) and its rank."""
    u, sv, vt = thin_svd(ju)
    if sv[-1] > RCOND * sv[0]:  # full rank, the usual case: every singular value kept (the masks' cost spared)
        inverse, rank, kept = 1.0 / sv, len(sv), vt
    else:
        keep = sv > RCOND * sv[0]
        inverse, rank, kept = np.divide(1.0, sv, out=np.zeros_like(sv), where=keep), int(keep.sum()), vt[keep]
    return (lambda x: vt.T @ (inverse * (u.T @ x))), float(sv[-1]), kept, rank


def pinv_rates(ju: np.ndarray, twist: np.ndarray) -> tuple[np.ndarray, float, float, np.ndarray]:
    """pinv: Ju+ twist, sigma_min, 0 and the basis of Ju's row space."""
    inverse, sigma, basis, _ = _pseudo_inverse(ju)
    return inverse(twist), sigma, 0.0, basis


def priority_rates(ju: np.ndarray, twist: np.ndarray) -> tuple[np.ndarray, float, float, np.ndarray]:
    """priority (Chiaverini 1997, eq. 8, both inverses damped as dls_adaptive's, on the singular values each task's
    Jacobian can have: a planar arm's point has two, the orientation left to a five-joint arm two): the point's rows
    first, the orientation's in what they leave free; the first task alone where Ju has the point's rows alone.
    Returns the rates, the whole Ju's sigma_min, the larger lambda^2 of the two inverses and the basis of Ju's row
    space."""
    first, sigma, lam2, b1 = _damped(ju[:3], twist[:3], _adaptive, rank_only=True)
    if len(ju) == 3:
        return first, sigma, lam2, b1
    second, _, lam2_second, _ = _damped(ju[3:] @ null_projector(b1), twist[3:] - ju[3:] @ first, _adaptive,
                                        rank_only=True)
    _, sigma, basis, _ = _pseudo_inverse(ju)
    return first + second, sigma, max(lam2, lam2_second), basis


def sns_rates(ju: np.ndarray, twist: np.ndarray, preference: np.ndarray, low: np.ndarray,
              high: np.ndarray) -> tuple[np.ndarray, float, float, np.ndarray]:
    """sns (Flacco et al. 2012, Alg. 1): the rates within [low, high] (low <= 0 <= high) for the twist scaled by the
    largest s <= 1 found, plus a redundant arm's `preference` (its null-space motion, cartesian_path's) in the free
    joints' null space, scaled with the twist. Returns the rates, Ju's sigma_min, s and the saturated joints."""
    dof = len(low)
    saturated, fixed = np.zeros(dof, bool), np.zeros(dof)
    inverse, sigma, basis, full = _pseudo_inverse(ju)
    best = (0.0, np.zeros(dof), np.zeros(dof), saturated.copy())  # s* = 0, none saturated: qd = 0
    while True:
        free = ~saturated
        task, kept = np.zeros(dof), fixed.copy()  # qd = s task + kept
        task[free] = inverse(twist) + null_projector(basis) @ preference[free]
        kept[free] = -inverse(ju[:, saturated] @ fixed[saturated])
        rates = task + kept
        passing = (rates < low) | (rates > high)
        if not passing.any():
            return rates, sigma, 1.0, saturated
        scale, critical = _task_scale(task, kept, low, high, passing)
        if scale > best[0]:
            best = (scale, task, kept, saturated.copy())
        saturated[critical] = True
        fixed[critical] = high[critical] if rates[critical] > high[critical] else low[critical]
        if saturated.all():
            break
        inverse, _, basis, rank = _pseudo_inverse(ju[:, ~saturated])
        if rank < full:  # the free joints cannot make the task
            break
    scale, task, kept, saturated = best
    return scale * task + kept, sigma, scale, saturated


def _task_scale(task: np.ndarray, kept: np.ndarray, low: np.ndarray, high: np.ndarray,
                passing: np.ndarray) -> tuple[float, int]:
    """The largest s in [0, 1] with low <= s task + kept <= high (0 where there is none), and the most critical
    joint: of those `passing` a bound at s = 1, the one whose bounds cap s lowest (Flacco et al. 2012's task
    scaling factor)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        to_low, to_high = (low - kept) / task, (high - kept) / task
    moving = task != 0
    inside = (kept >= low) & (kept <= high)
    upper = np.where(moving, np.maximum(to_low, to_high), np.inf)
    lower = np.where(moving, np.minimum(to_low, to_high), np.where(inside, -np.inf, np.inf))
    top, bottom = min(float(upper.min()), 1.0), float(lower.max())
    candidates = np.flatnonzero(passing)
    return (0.0 if bottom > top or top < 0.0 else top), int(candidates[np.argmin(upper[candidates])])


def manipulability(ju: np.ndarray) -> np.ndarray:
    """w = sqrt(det(Ju Ju^T)) (...) of Jacobians (..., rows, dof), the product of their singular values (Yoshikawa
    1985)."""
    return np.linalg.svd(ju, compute_uv=False).prod(axis=-1)


def manipulability_gradient(robot, q: np.ndarray, rows: int) -> np.ndarray:
    """grad w (dof,) at joints q (dof,) of the task's first `rows` rows of Ju, by central differences of the
    robot's (MuJoCo's) Jacobian, step GRADIENT_STEP."""
    steps = GRADIENT_STEP * np.eye(len(q))
    w = manipulability(unit_jacobian(robot.jacobian(np.vstack([q + steps, q - steps])), robot.reach)[:, :rows])
    return (w[:len(q)] - w[len(q):]) / (2 * GRADIENT_STEP)


@dataclass(frozen=True)
class Resolver:
    """How cartesian_path resolves a sample's rates for a method: its rule, whether the rates are scaled down
    together under the speed limits, whether a redundant arm climbs w's gradient in the null space (else it returns
    to its start posture) and whether the rates are solved within their bounds (sns)."""

    rule: Rule = pinv_rates
    scaled: bool = False
    gradient: bool = False
    bounded: bool = False


def resolver_of(method: str, damping: float | None) -> Resolver:
    """The resolver of a resolved-rate method (time_scaling's joint path is pinv's)."""
    if method == "dls":  # lambda fixed
        lam2 = float(DAMPING if damping is None else damping) ** 2
        return Resolver(lambda ju, twist: _damped(ju, twist, lambda sigma: lam2), scaled=True)
    return {"dls_adaptive": Resolver(damped_rates, scaled=True), "priority": Resolver(priority_rates, scaled=True),
            "gradient": Resolver(gradient=True), "sns": Resolver(bounded=True)}.get(method, Resolver())
