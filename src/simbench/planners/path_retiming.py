"""cartesian_path's `time_scaling`: the path kept exactly, its timing stretched where the joints' speed and
acceleration limits need it.

  1. The joint path q(s): pinv's closed-loop resolved rates (path_methods) on a uniform grid of s (one step per
     control sample), each sample then solved exactly for the path's pose (`exact_ik`; for its point alone where
     the task's orientation is free: the position rows of Ju and of the error).
  2. The timing s(t): time-optimal path parameterisation by reachability analysis (TOPP-RA: Pham and Pham, IEEE
     Trans. Robot. 34(3), 2018; the `toppra` library) of the cubic spline through q(s), under
     |qd_j| <= MARGIN qd_max_j and |qdd_j| <= MARGIN qdd_max_j, and no faster along the path than the asked time
     law: s is a further coordinate whose speed limit at s is the law's ds/dt there. It starts and ends at rest.
  3. The plan: the joints solved exactly at each s(t_k) (exact_ik from the spline's q), their rates the spline's.

`slowdown` = planned duration / asked. MARGIN leaves room for the exact solution's departure from the spline; what
TOPP-RA's grid does not see stretches the whole timing uniformly: the spline's rates between gridpoints (probed
densely), and its rates' finite differences at the plan's own samples (near a singularity, at a corner between
segments), which fall as the square of the stretch. Where the exact joints still ask a joint for more than its
acceleration limit (their second differences: a kink the spline rounds off), the plan reports `acceleration_limit`.
"""

from __future__ import annotations

import numpy as np

from simbench.api import REVOLUTE, Violation
from simbench.api.trajectory import control_grid
from simbench.core.errors import RunError
from simbench.planners.path_methods import RCOND
from simbench.robots.rank_loss import unit_jacobian

ACCEL_TIME = 0.1  # s: acceleration limits where the task gives none, each joint's speed limit reached in this time
MARGIN = 0.98  # share of the speed and acceleration limits TOPP-RA plans for
GRIDPOINTS = 1000  # TOPP-RA's gridpoints at most: s at uniform times of the asked law (dense where it is slow)
PROBE = 8  # times between two gridpoints at which the timing's joint rates are checked
STRETCHES = 8  # tries at the stretch that brings the sampled accelerations back under their limits
MAX_SLOWDOWN = 100.0  # a longer timing is refused (its samples would be the run's memory)
IK_TOL = 1e-12  # exact_ik's tolerance on the unit-consistent pose error
IK_ITERATIONS = 30
IK_ACCEPT = 1e-9  # a sample's exact solution is taken where its pose error ends below this, else the start kept
IK_STEP = 0.1  # rad (or m): the most a Newton step, and the whole solution, may move a joint


def exact_ik(robot, q: np.ndarray, points: np.ndarray, rotations: np.ndarray,
             error_of) -> tuple[np.ndarray, np.ndarray]:
    """Joints (N, dof) at which the tool's pose is points, rotations: Newton's q <- q + Ju+ e from q, e =
    error_of(points, rotations, q) (N, rows), Ju's first `rows` rows (6: the pose; 3: the point alone, a free
    task's), steps of at most IK_STEP, inside the joint ranges; a sample is solved for until its error is within
    IK_TOL or it leaves IK_STEP of its start. A sample that does not converge to IK_ACCEPT within IK_STEP of its start
    (another branch, near a singularity) keeps it. Returns the joints and the last |e| (N,)."""
    start = np.array(q, float)
    q = start.copy()
    going = np.arange(len(q))  # the samples still solved for
    for _ in range(IK_ITERATIONS):
        error = error_of(points[going], rotations[going], q[going])
        on = (np.linalg.norm(error, axis=1) > IK_TOL) & (np.abs(q[going] - start[going]).max(axis=1) <= IK_STEP)
        going, error = going[on], error[on]
        if not len(going):
            break
        ju = unit_jacobian(robot.jacobian(q[going]), robot.reach)[:, :error.shape[1]]
        step = np.einsum("nij,nj->ni", np.linalg.pinv(ju, rcond=RCOND), error)  # pinv_rates' Ju+ e, all at once
        longest = np.abs(step).max(axis=1, keepdims=True)
        q[going] = np.clip(q[going] + step * np.minimum(1.0, IK_STEP / np.maximum(longest, 1e-300)), robot.lower,
                           robot.upper)
    size = np.linalg.norm(error_of(points, rotations, q), axis=1)
    kept = (size > IK_ACCEPT) | (np.abs(q - start).max(axis=1) > IK_STEP)
    if np.count_nonzero(kept):  # the error where the start is kept, the others' as found
        q[kept] = start[kept]
        size[kept] = np.linalg.norm(error_of(points[kept], rotations[kept], q[kept]), axis=1)
    return q, size


def retime(s_grid: np.ndarray, q_grid: np.ndarray, law, qd_max: np.ndarray, qdd_max: np.ndarray, dt: float,
           hold: float) -> tuple[np.ndarray, ...]:
    """TOPP-RA's timing of the joint path q_grid (M, dof) at s_grid (M,): the control times t, s(t) (N,), the
    spline's q(s(t)) and dq/dt (N, dof), and the planned duration. RunError where no timing exists."""
    import toppra  # imported here: validation and `simbench list` do not pay for it
    import toppra.algorithm
    import toppra.constraint

    dof = q_grid.shape[1]
    path = toppra.SplineInterpolator(s_grid, np.hstack([q_grid, s_grid[:, None]]))
    fine = np.linspace(0.0, law.duration, 20 * len(s_grid) + 1)
    s_law, sd_law, sdd_law = law(fine, order=2)
    sd_law[[0, -1]] = 0.0

    def speed_limits(s: float) -> np.ndarray:
        rate = float(np.interp(s, s_law, sd_law))
        return np.vstack([np.column_stack([-MARGIN * qd_max, MARGIN * qd_max]), [-rate, rate]])

    s_accel = 100.0 * max(float(np.abs(sdd_law).max()), 1.0 / law.duration**2)
    accel = np.vstack([np.column_stack([-MARGIN * qdd_max, MARGIN * qdd_max]), [-s_accel, s_accel]])
    constraints = [toppra.constraint.JointVelocityConstraintVarying(speed_limits),
                   toppra.constraint.JointAccelerationConstraint(accel)]
    gridpoints = np.unique(law(np.linspace(0.0, law.duration, min(GRIDPOINTS, len(s_grid))), order=0)[0])
    solver = toppra.algorithm.TOPPRA(constraints, path, gridpoints=gridpoints, parametrizer="ParametrizeConstAccel")
    timed = solver.compute_trajectory(0.0, 0.0)
    if timed is None:
        raise RunError("time_scaling: TOPP-RA found no timing of the joint path within the joints' speed and "
                       "acceleration limits")
    refuse_longer(float(timed.duration), law.duration, "time_scaling")
    excess = _excess(timed, dof, qd_max, max(PROBE * len(gridpoints), 2 * int(timed.duration / dt)))
    stretch = excess / MARGIN if excess > 1.0 else 1.0  # back to MARGIN of the limit where the grid let it pass
    for _ in range(STRETCHES):  # the same for the accelerations at the plan's samples, which rise as they densen
        share = _sampled_acceleration(timed, dof, qdd_max, stretch, dt)
        if share <= 1.0:
            break
        stretch *= np.sqrt(share / MARGIN)
    duration = float(timed.duration) * stretch
    refuse_longer(duration, law.duration, "time_scaling")
    t = control_grid(duration, hold, dt)
    inside = np.minimum(t, duration) / stretch
    y, yd = timed(inside), timed(inside, 1) / stretch
    s = np.clip(y[:, -1], 0.0, 1.0)
    s[t >= duration] = 1.0
    rates = yd[:, :dof]
    rates[t >= duration] = 0.0
    return t, s, path(s)[:, :dof], rates, duration


def refuse_longer(duration: float, asked: float, method: str) -> None:
    """RunError naming `method` where a timing of `duration` s passes MAX_SLOWDOWN times the asked one."""
    if duration > MAX_SLOWDOWN * asked:
        raise RunError(f"{method}: the joints' limits stretch the motion to {duration:.4g} s, more than "
                       f"{MAX_SLOWDOWN:g} times the asked {asked:g} s")


def _excess(timed, dof: int, qd_max: np.ndarray, count: int) -> float:
    """The largest |qd_j| / qd_max_j of TOPP-RA's timing at `count` uniform times. TOPP-RA keeps the limits at its
    gridpoints only: between them the spline may ask more (near a singularity, where q(s) bends sharply), and the
    timing is then stretched uniformly."""
    times = np.linspace(0.0, float(timed.duration), count + 1)
    return max(float(np.max(np.abs(timed(chunk, 1)[:, :dof]) / qd_max)) for chunk in np.array_split(
        times, max(1, len(times) // 65536)))


def _sampled_acceleration(timed, dof: int, qdd_max: np.ndarray, stretch: float, dt: float) -> float:
    """The largest |qd_j(t_k+1) - qd_j(t_k)| / dt / qdd_max_j of TOPP-RA's timing stretched by `stretch`, at the
    plan's samples t_k = k dt up to rest: what the plan's rates ask. Each averages the continuous acceleration over
    a sample, whose narrow peaks (where q(s) bends sharply) would overstate it."""
    duration = float(timed.duration) * stretch
    t = np.append(np.arange(int(np.ceil(duration / dt))) * dt, duration)
    rates = timed(t / stretch, 1)[:, :dof] / stretch
    rates[-1] = 0.0
    return float(np.max(np.abs(np.diff(rates, axis=0)) / dt / qdd_max))


def acceleration_violations(robot, t: np.ndarray, q: np.ndarray, qd: np.ndarray,
                            qdd_max: np.ndarray) -> tuple[np.ndarray, tuple[Violation, ...]]:
    """The plan's accelerations at its samples over each joint's limit, (N, dof): the larger of its rates' finite
    differences and its joints' second differences (the exact solution's kinks). Returns them and one
    `acceleration_limit` violation per joint past its limit (the MARGIN's slack spent): its worst, and from when."""
    dt = t[1] - t[0]  # the control grid's uniform step
    share = np.zeros_like(q)
    share[1:] = np.abs(np.diff(qd, axis=0)) / dt / qdd_max
    bends = np.abs(np.diff(q, 2, axis=0)) / dt**2 / qdd_max
    share[1:-1] = np.maximum(share[1:-1], bends)
    out = []
    for j in np.flatnonzero(share.max(axis=0) > 1.0):
        first, worst = int(np.argmax(share[:, j] > 1.0)), int(np.argmax(share[:, j]))
        ratio, limit = float(share[worst, j]), float(qdd_max[j])
        unit, scale = ("deg/s^2", np.rad2deg(1.0)) if robot.kinds[j] == REVOLUTE else ("mm/s^2", 1e3)
        out.append(Violation("acceleration_limit", f"the plan asks {robot.joints[j]} for {ratio * limit * scale:.1f} "
                             f"{unit} at t = {t[worst]:.3f} s, {ratio:.2f} times its acceleration limit "
                             f"{limit * scale:.1f} {unit}, from t = {t[first]:.3f} s: the exact joints bend sharper "
                             "there than the timing allows (a corner, a singularity)", float(t[first]), 0,
                             {"joint": robot.joints[j], "ratio": ratio, "limit": limit, "t_worst": float(t[worst]),
                              "source": "planner"}))
    return share, tuple(out)
