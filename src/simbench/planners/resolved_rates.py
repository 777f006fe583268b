"""cartesian_path's resolved rates, a control sample at a time (the planner's module docstring states the rule and its
references): the rates within the joint ranges, a redundant arm's null-space motion, the closed loop's error,
sns's bounds, and dls_adaptive's crossing of a passage below EPSILON by pinv.
"""

from __future__ import annotations

import numpy as np

from simbench.planners.path_methods import (EPSILON, GRADIENT_GAIN, Resolver, Rule, damped_rates,
                                            manipulability_gradient, null_projector, pinv_rates, sns_rates)
from simbench.robots.rank_loss import unit_jacobian

CLIK_SHARE = 0.5  # share of the tool's error removed each control sample (K = CLIK_SHARE / dt)
KNOT_STEP = 0.01  # s: integrate's default step between knots, where the arm is clear of its singular set and limits
CLEAR_SIGMA = EPSILON  # a knot step is taken where sigma_min is at least this ...
CLEAR_SPEED = 0.5  # ... and every joint's rate at most this share of its speed limit
NULL_GAIN = 1.0  # 1/s: a redundant arm's return to its start posture, in the null space
_UNDER = 1 - 1e-9  # rates scaled to just under the speed limits, which the plan check reads strictly
POSITION_ROWS = 3  # a free task's rows of Ju and of the twist: the point's


def _clamped_rates(ju: np.ndarray, twist: np.ndarray, now: np.ndarray, preference: np.ndarray | None, robot,
                   dt: float, rule: Rule = damped_rates) -> tuple[np.ndarray, float, float, np.ndarray]:
    """One sample's rates by the rule, plus the null-space motion `preference` (_preference), with every joint kept
    inside its range (cartesian_path's docstring): the rates, the whole arm's sigma_min (of Ju's rows, those the
    task uses) and lambda^2, and which joints are held (dof,)."""
    rates, sigma, lam2, basis = rule(ju, twist)  # no joint held yet: Ju and the twist whole
    out = _plus_null(rates, basis, preference)
    after = now + dt * out
    passing = (after > robot.upper) | (after < robot.lower)
    if not np.count_nonzero(passing):  # the usual case (a tenth of ndarray.any's time: this runs every sample)
        return out, sigma, lam2, passing  # none held
    held, fixed = np.zeros(len(now), bool), np.zeros(len(now))
    while np.count_nonzero(passing):
        fixed[passing] = (np.clip(after[passing], robot.lower[passing], robot.upper[passing]) - now[passing]) / dt
        held |= passing
        if np.count_nonzero(held) == len(now):
            return fixed, sigma, lam2, held
        free = ~held
        rates, _, _, basis = rule(ju[:, free], twist - ju[:, held] @ fixed[held])
        out = fixed.copy()
        out[free] = _plus_null(rates, basis, None if preference is None else preference[free])
        after = now + dt * out
        passing = ~held & ((after > robot.upper) | (after < robot.lower))
    return out, sigma, lam2, held


def _plus_null(rates: np.ndarray, basis: np.ndarray, preference: np.ndarray | None) -> np.ndarray:
    """The rule's rates plus the null-space motion (I - Ju+ Ju) preference. None: an arm with no joint to spare,
    whose projector is not made (rates + 0.0 gives the same floats as adding the projection of zero, +0.0, did:
    a zero rate's sign included)."""
    if preference is None:
        return rates + 0.0
    return rates + null_projector(basis) @ preference


def _inside(robot, q: np.ndarray) -> np.ndarray:
    """q within the joint ranges: np.clip's result at half its cost (a step of the integration's every sample)."""
    return np.minimum(np.maximum(q, robot.lower), robot.upper)


def _preference(robot, q0: np.ndarray, now: np.ndarray, rows: int, resolver: Resolver) -> np.ndarray | None:
    """A redundant arm's null-space motion (dof,): up manipulability's gradient (the gradient method) or back to
    its start posture; None on an arm with no more joints than the task's rows."""
    if robot.dof <= rows:
        return None
    if resolver.gradient:
        return GRADIENT_GAIN * manipulability_gradient(robot, now, rows)
    return NULL_GAIN * (q0 - now)


def _bounded_rates(ju: np.ndarray, twist: np.ndarray, now: np.ndarray, preference: np.ndarray | None, robot,
                   dt: float) -> tuple[np.ndarray, float, float, np.ndarray, float]:
    """sns's rates: each joint's within its speed limit (just under it, as the scaled rules') and within its
    range at the sample's end. Returns the rates, sigma_min, 0, the joints saturated at a range's end (held) and
    the task's scale."""
    to_lower, to_upper = (robot.lower - now) / dt, (robot.upper - now) / dt
    fast = _UNDER * robot.qd_max
    rates, sigma, scale, saturated = sns_rates(ju, twist, np.zeros(robot.dof) if preference is None else preference,
                                               np.maximum(-fast, to_lower), np.minimum(fast, to_upper))
    held = saturated & (((rates == to_lower) & (to_lower > -fast)) | ((rates == to_upper) & (to_upper < fast)))
    return rates, sigma, 0.0, held, scale


def _sample(robot, q0: np.ndarray, now: np.ndarray, point: np.ndarray, rotation: np.ndarray, twist: np.ndarray,
            dt: float, resolver: Resolver) -> tuple[np.ndarray, float, float, np.ndarray, float]:
    """One control sample at the joints `now` (cartesian_path's qd_k): the path's twist plus K times the tool's error
    from (point, rotation), by the resolver's rule within the ranges (_clamped_rates; sns: _bounded_rates), on the
    twist's rows of Ju. Returns the rates, sigma_min, lambda^2, the joints held and the task's scale (sns's; else
    1)."""
    rows = len(twist)
    error, ju = _error_and_jacobian(robot, now, point, rotation, rows)
    command, preference = twist + CLIK_SHARE / dt * error, _preference(robot, q0, now, rows, resolver)
    if resolver.bounded:
        return _bounded_rates(ju, command, now, preference, robot, dt)
    return *_clamped_rates(ju, command, now, preference, robot, dt, resolver.rule), 1.0


def _error_and_jacobian(robot, now: np.ndarray, point: np.ndarray, rotation: np.ndarray,
                        rows: int) -> tuple[np.ndarray, np.ndarray]:
    """The unit-consistent error (rows,) of the tool at the joints `now` from (point, rotation) (task_error's) and
    the task's rows of Ju there, from one kinematics pass."""
    at, turned, jac = pose_jacobian_at(robot, now)
    error = np.empty(rows)
    error[:POSITION_ROWS] = (point - at) / robot.reach
    if rows > POSITION_ROWS:
        error[POSITION_ROWS:] = orientation_error(rotation, turned)
    return error, unit_jacobian(jac, robot.reach)[:rows]


def pose_jacobian_at(robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """pose_jacobian's at one joint vector q (dof,): (3,), (3, 3), (6, dof); the robot's own where it has one
    (robots.model_arm.ModelArm.pose_jacobian_at)."""
    if hasattr(robot, "pose_jacobian_at"):
        return robot.pose_jacobian_at(q)
    at, turned, jac = pose_jacobian(robot, q[None])
    return at[0], turned[0], jac[0]


def task_error(robot, points: np.ndarray, rotations: np.ndarray, q: np.ndarray, rows: int) -> np.ndarray:
    """The unit-consistent error (N, rows) of the tool at q (N, dof) from points, rotations (cartesian_path's e_k): the
    point's / L, then, on a task of 6 rows, the orientation's (eq. 3.85)."""
    at, turned = tool_pose(robot, q)
    position = (points - at) / robot.reach
    if rows == POSITION_ROWS:
        return position
    return np.hstack([position, orientation_error(rotations, turned)])


def tool_pose(robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The tool point (N, 3) and its rotation (N, 3, 3) at q (N, dof): from one kinematics pass where the robot offers
    one (robots.model_arm.ModelArm.pose), else from its fk and tool_rotation."""
    if hasattr(robot, "pose"):
        return robot.pose(q)
    return robot.fk(q), robot.tool_rotation(q)


def pose_jacobian(robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tool point (N, 3), its rotation (N, 3, 3) and J (N, 6, dof) at q (N, dof): from one kinematics pass where
    the robot offers one (robots.model_arm.ModelArm.pose_jacobian), else from its fk, tool_rotation and jacobian."""
    if hasattr(robot, "pose_jacobian"):
        return robot.pose_jacobian(q)
    return robot.fk(q), robot.tool_rotation(q), robot.jacobian(q)


def sigma_min(robot, q: np.ndarray, rows: int) -> np.ndarray:
    """The least singular value (N,) of the task's rows of Ju at q (N, dof)."""
    return np.linalg.svd(unit_jacobian(robot.jacobian(q), robot.reach)[:, :rows], compute_uv=False)[:, -1]


def _crossing(robot, q0: np.ndarray, now: np.ndarray, points: np.ndarray, rotations: np.ndarray,
              twists: np.ndarray, dt: float) -> tuple[tuple[np.ndarray, ...], np.ndarray] | None:
    """pinv's samples from the joints `now` while sigma_min stays below EPSILON (a passage, to the path's end at
    most): their q, qd, sigma_min and held joints, and the joints after; None where pinv's rates pass a speed
    limit in it (cartesian_path's docstring: dls_adaptive's damping is for such a passage only)."""
    rows, pinv, fast = [], Resolver(), _UNDER * robot.qd_max
    for point, rotation, twist in zip(points, rotations, twists):
        rates, sigma, _, held, _ = _sample(robot, q0, now, point, rotation, twist, dt, pinv)
        if sigma >= EPSILON:
            break
        if np.count_nonzero(np.abs(rates) > fast):  # (ndarray.any's answer at a tenth of its time)
            return None
        rows.append((now, rates, sigma, held))
        now = _inside(robot, now + dt * rates)
    return tuple(np.array(column) for column in zip(*rows)), now


def orientation_error(r_goal: np.ndarray, r: np.ndarray) -> np.ndarray:
    """1/2 (n x n_d + s x s_d + a x a_d) (..., 3) of rotations (..., 3, 3) (Siciliano et al. 2009, eq. 3.85):
    sin(angle) times the axis of the rotation from r to r_goal, world frame. Computed as the same sum's closed form,
    vee of the skew part of r_goal r^T (three cross products cost more at every control sample)."""
    if np.ndim(r_goal) == 2 == np.ndim(r):  # one pair, a control sample's: the same product, indexed directly
        one = (r_goal @ r.T).ravel()
        return 0.5 * (one[_LOWER] - one[_UPPER])
    turn = (r_goal @ np.swapaxes(r, -1, -2)).reshape(*np.shape(r_goal)[:-2], 9)
    return 0.5 * (turn.take(_LOWER, axis=-1) - turn.take(_UPPER, axis=-1))


# orientation_error's vee in a flattened 3 x 3: (2, 1), (0, 2), (1, 0) less (1, 2), (2, 0), (0, 1)
_LOWER, _UPPER = np.array([7, 2, 3]), np.array([5, 6, 1])


def integrate(robot, q0: np.ndarray, points: np.ndarray, rotations: np.ndarray, twists: np.ndarray,
              dt: float, resolver: Resolver, knot_step: float = KNOT_STEP) -> tuple[np.ndarray, ...]:
    """q, qd (N, dof), sigma_min, lambda^2 and the speed scale (N,) of cartesian_path's integration from q0 by the
    method's resolver (path_methods), scaled down under the speed limits where it says (sns: its task's scale);
    and the held joints (N, dof). dls_adaptive (`damped_rates`) crosses a passage below EPSILON by pinv where pinv
    keeps the speed limits through it (_crossing), and damps it otherwise.

    Where the arm is clear of its singular set and its limits (_clear), it moves a knot step of `knot_step` at a time
    (_knot: the joints put on the path's pose, then its rates held over the step) and the samples between are the
    cubic Hermite curve of the knots' joints and rates (_between); elsewhere a control sample at a time. Per sample,
    the same rule: the knots cost a control sample each, the samples between an array operation."""
    n = len(points)
    q, qd, sigma, lam2 = np.empty((n, robot.dof)), np.empty((n, robot.dof)), np.empty(n), np.zeros(n)
    scale, held = np.ones(n), np.zeros((n, robot.dof), bool)
    every = max(1, round(knot_step / dt))  # control samples a knot step spans
    knots: list[int] = []
    now, k, damping, clear = q0.copy(), 0, False, False
    fast = _UNDER * robot.qd_max  # the scaled rules' bound
    while k < n:
        if clear and every > 1 and k + every < n:
            on, rates, sigma[k], spent = _knot(robot, q0, now, points[k], rotations[k], twists[k], resolver)
            if not spent and _clear(robot, on, rates, sigma[k], every * dt):
                q[k], qd[k] = on, rates
                knots.append(k)
                now = on + every * dt * rates
                k += every
                continue
            now = on  # on the path: the samples go on from there, one at a time
        rates, sigma[k], lam2[k], held[k], scale[k] = _sample(robot, q0, now, points[k], rotations[k], twists[k], dt,
                                                              resolver)
        damping = damping and sigma[k] < EPSILON  # a damped passage lasts while sigma_min stays below EPSILON
        if resolver.rule is damped_rates and sigma[k] < EPSILON and not damping:
            crossed = _crossing(robot, q0, now, points[k:], rotations[k:], twists[k:], dt)
            if crossed is not None:
                rows, now = crossed
                end = k + len(rows[0])
                q[k:end], qd[k:end], sigma[k:end], held[k:end] = rows
                lam2[k:end] = 0.0
                k = end
                clear = False
                continue
            damping = True
        if resolver.scaled and np.count_nonzero(np.abs(rates) > fast):  # (else the scale is 1: fast / |rate| >= 1)
            scale[k] = min(1.0, float((fast / np.maximum(np.abs(rates), 1e-300)).min()))
            rates = rates * scale[k]
        q[k], qd[k] = now, rates  # sns's rates come scaled
        clear = (lam2[k] == 0.0 and scale[k] == 1.0 and not np.count_nonzero(held[k])
                 and _clear(robot, now, rates, sigma[k], every * dt))
        now = _inside(robot, now + dt * qd[k])  # a held joint on its limit, not an ulp past
        k += 1
    _between(robot, q, qd, sigma, np.array(knots, int), every, dt)
    return q, qd, sigma, lam2, scale, held


def _knot(robot, q0: np.ndarray, now: np.ndarray, point: np.ndarray, rotation: np.ndarray, twist: np.ndarray,
          resolver: Resolver) -> tuple[np.ndarray, np.ndarray, float, bool]:
    """A knot at the joints `now`: the joints put on the path's pose (a Newton step, q + Ju+ e, as
    path_retiming.exact_ik's), the rule's rates for the path's twist there (the error spent: no closed-loop term),
    sigma_min, and whether the rule damps there (a knot step is then not taken)."""
    rows = len(twist)
    error, ju = _error_and_jacobian(robot, now, point, rotation, rows)
    step, sigma, _, _ = pinv_rates(ju, error)
    rates, _, lam2, basis = resolver.rule(ju, twist)
    return now + step, _plus_null(rates, basis, _preference(robot, q0, now, rows, resolver)), sigma, lam2 > 0.0


def _clear(robot, q: np.ndarray, rates: np.ndarray, sigma: float, step: float) -> bool:
    """Whether the arm at q, moving at `rates`, is clear enough of its singular set (sigma_min at least CLEAR_SIGMA)
    and of its limits (rates within CLEAR_SPEED of the speed limits, twice a knot step's motion inside the ranges)
    for a knot step of `step` seconds."""
    if sigma < CLEAR_SIGMA:
        return False
    speed = np.abs(rates)
    reach = 2.0 * step * speed
    # count_nonzero: a tenth of ndarray.all's time (this runs at every control sample)
    return not (np.count_nonzero(speed > CLEAR_SPEED * robot.qd_max) or np.count_nonzero(q - reach <= robot.lower)
                or np.count_nonzero(q + reach >= robot.upper))


def _between(robot, q: np.ndarray, qd: np.ndarray, sigma: np.ndarray, knots: np.ndarray, every: int,
             dt: float) -> None:
    """Fill the samples inside each knot step (k, k + every), in place: q and qd on the cubic Hermite curve through
    the knots' joints and rates (its basis written out, every step in one array operation), within the ranges;
    sigma_min linear between the knots'."""
    if not len(knots):
        return
    step = every * dt
    u = (np.arange(1, every) / every)[None, :, None]  # (1, every - 1, 1): the share of the step
    q_a, q_b = q[knots][:, None], q[knots + every][:, None]
    m_a, m_b = step * qd[knots][:, None], step * qd[knots + every][:, None]
    inside = (knots[:, None] + np.arange(1, every)[None]).ravel()
    q[inside] = np.clip(((2 * u**3 - 3 * u**2 + 1) * q_a + (u**3 - 2 * u**2 + u) * m_a + (-2 * u**3 + 3 * u**2) * q_b
                         + (u**3 - u**2) * m_b).reshape(-1, q.shape[1]), robot.lower, robot.upper)
    qd[inside] = (((6 * u**2 - 6 * u) * q_a + (3 * u**2 - 4 * u + 1) * m_a + (-6 * u**2 + 6 * u) * q_b
                   + (3 * u**2 - 2 * u) * m_b) / step).reshape(-1, q.shape[1])
    sigma[inside] = (sigma[knots][:, None] * (1 - u[..., 0]) + sigma[knots + every][:, None] * u[..., 0]).ravel()
