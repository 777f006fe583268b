"""cartesian_path's `ruckig` method: pinv's joint path kept, its timing a jerk-limited motion of the path parameter.

The joint path is the cubic spline q(s) through pinv's samples (scipy's not-a-knot CubicSpline: the spline
path_retiming.retime builds with toppra.SplineInterpolator). Its timing s(t) is Ruckig's (Berscheid and Kroeger,
"Jerk-limited Real-time Trajectory Generation with Arbitrary Target States", RSS 2021; the `ruckig` library, whose
community build plans state to state, no intermediate waypoints) on the one coordinate s, driven online at the
control step under bounds on sd, |sdd| and |sddd| that keep every joint within MARGIN of its limits. By the chain
rule along q(s),

    qd   = q' sd
    qdd  = q' sdd + q'' sd^2
    qddd = q' sddd + 3 q'' sd sdd + q''' sd^3

so the bounds on s at a spline interval come from its largest |q'|, |q''| and |q'''| (exact: q' is quadratic, q''
linear, q''' constant on an interval). The ceiling on sd leaves the path's bends at most a share of each limit
(CURVATURE_SHARE of the acceleration, CROSS_SHARE and CUBIC_SHARE of the jerk); sdd and sddd get what is left.
As retime's, the timing is no faster than the asked law: sd at most the law's mean speed on each interval, and
the final stop no shorter than the law's time left.

A bound must hold before the motion gets there. sd follows a braking curve (under the ceilings and the law, the
fastest sd that can still slow down for every one ahead at BRAKING_SHARE of the acceleration bound, and make a
jerk-limited stop at s = 1 in 1/AHEAD of the path left) with Ruckig's velocity interface, each cycle to the curve's
least over the stretch ahead that a swing of sdd to its braking covers (Ruckig's position interface, given a lower
bound than the speed, brakes hard and undershoots it); |sdd|'s bound is the least over the stretch its ramp to zero
covers, |sddd|'s the next steps' (it can change at once). Near the end, Ruckig's position interface plans the stop at
s = 1 under the least bounds left; the first such plan that stays under the ceilings is the rest of the motion.
"""

from __future__ import annotations

import numpy as np

from simbench.api.trajectory import control_grid
from simbench.core.errors import RunError
from simbench.planners.path_retiming import MARGIN, MAX_SLOWDOWN, refuse_longer

JERK_TIME = 0.1  # s: jerk limits where the task gives none, each joint's acceleration limit reached in this time
# (as path_retiming's ACCEL_TIME for the acceleration: dozens of control steps, an industrial arm's order)
CURVATURE_SHARE = 0.5  # share of a joint's acceleration limit the path's bend q'' sd^2 may take
CROSS_SHARE = 0.25  # share of a joint's jerk limit 3 q'' sd sdd may take
CUBIC_SHARE = 0.25  # share of a joint's jerk limit q''' sd^3 may take
BRAKING_SHARE = 0.5  # share of the acceleration bound the braking curve asks (the rest: room for the jerk ramps)
AHEAD = 1.5  # the bounds look this many ramp (or stop) distances ahead
EPS = 1e-12  # Ruckig's rounding in s and sd
S_CAP = 100.0  # |sdd|, |sddd| at most this many times the asked law's peak (its peak sdd / duration where it has
# no jerk): the bounds where no joint moves


def default_jerk_limits(qdd_max: np.ndarray) -> np.ndarray:
    """Jerk limits where the task gives none: each joint's acceleration limit reached in JERK_TIME."""
    return np.asarray(qdd_max, float) / JERK_TIME


def retime_jerk(s_grid: np.ndarray, q_grid: np.ndarray, law, qd_max: np.ndarray, qdd_max: np.ndarray,
                jerk_max: np.ndarray, dt: float, hold: float) -> tuple[np.ndarray, ...]:
    """Ruckig's jerk-limited timing of the joint path q_grid (M, dof) at s_grid (M,), as retime's: the control times
    t, s(t) (N,), the spline's q(s(t)) and dq/dt (N, dof), and the planned duration (at rest from then on).
    RunError where Ruckig finds no timing or it is longer than MAX_SLOWDOWN times the asked law."""
    import ruckig  # imported here: validation and `simbench list` do not pay for it
    from scipy.interpolate import CubicSpline

    spline = CubicSpline(s_grid, q_grid)
    fine = np.linspace(0.0, law.duration, 20 * len(s_grid) + 1)
    s_law, _, sdd_law, sddd_law = law(fine, order=3)
    caps = (np.interp(s_grid, s_law, fine),  # when the law passes each knot
            S_CAP * max(float(np.abs(sdd_law).max()), 1.0 / law.duration**2),
            S_CAP * max(float(np.abs(sddd_law).max()), float(np.abs(sdd_law).max()) / law.duration))
    limits = _PathLimits(spline, MARGIN * np.asarray(qd_max, float), MARGIN * np.asarray(qdd_max, float),
                         MARGIN * np.asarray(jerk_max, float), caps)
    with np.errstate(divide="ignore"):  # at most the braking curve's speed: at least its time
        refuse_longer(float(np.sum(np.diff(s_grid) / limits.speed)), law.duration, "ruckig")
    otg = ruckig.Ruckig(1, dt)
    follow, out = ruckig.InputParameter(1), ruckig.OutputParameter(1)
    follow.control_interface = ruckig.ControlInterface.Velocity
    follow.current_position, follow.current_velocity, follow.current_acceleration = [0.0], [0.0], [0.0]
    follow.target_acceleration = [0.0]
    states = [(0.0, 0.0, 0.0)]
    accel, jerk = caps[1], caps[2]
    for _ in range(int(MAX_SLOWDOWN * law.duration / dt) + 1):
        s, v, a = follow.current_position[0], follow.current_velocity[0], follow.current_acceleration[0]
        if s >= 1.0:
            raise RunError(f"ruckig: no jerk-limited stop at the path's end within the joints' limits (sd = {v:.3g} "
                           "there)")
        speed, accel, jerk = limits.bounds(s, v, a, accel, jerk, dt)
        if s + AHEAD * _stop_distance(v, a, accel, jerk) >= 1.0:
            stopping = _stop(ruckig, limits, s, v, a, max(speed, v), law.duration - limits.law_time(s), dt)
            if stopping is not None:
                states += [tuple(row) for row in stopping[0]]
                duration = (len(states) - len(stopping[0]) - 1) * dt + stopping[1]
                break
        follow.target_velocity, follow.max_acceleration, follow.max_jerk = [speed], [accel], [jerk]
        if otg.update(follow, out) not in (ruckig.Result.Working, ruckig.Result.Finished):
            raise RunError(f"ruckig: no jerk-limited timing of the joint path (at s = {s:.4f})")
        out.pass_to_input(follow)
        states.append((follow.current_position[0], follow.current_velocity[0], follow.current_acceleration[0]))
    else:
        duration = len(states) * dt
    refuse_longer(duration, law.duration, "ruckig")
    timed = np.array(states)
    if np.diff(timed[:, 0]).min() < -EPS or timed[:, 0].max() > 1.0 + EPS:
        raise RunError(f"ruckig: the jerk-limited timing of the joint path turns back (s up to "
                       f"{timed[:, 0].max():.9f})")
    t = control_grid(duration, hold, dt)
    at = np.minimum(np.arange(len(t)), len(timed) - 1)
    s, sd = np.clip(timed[at, 0], 0.0, 1.0), timed[at, 1]
    s[t >= duration], sd[t >= duration] = 1.0, 0.0
    return t, s, spline(s), spline(s, 1) * sd[:, None], duration


def _stop(ruckig, limits, s: float, v: float, a: float, speed: float, least: float, dt: float) -> tuple | None:
    """Ruckig's stop at s = 1 from (s, v, a) under sd <= speed and the least bounds on |sdd|, |sddd| left, taking at
    least `least` s: its (s, sd, sdd) at the next control steps to rest (K, 3) and its duration, or None where it
    leaves the joints' ceiling on sd."""
    stop, plan = ruckig.InputParameter(1), ruckig.Trajectory(1)
    stop.minimum_duration = max(least, 0.0)
    stop.current_position, stop.current_velocity, stop.current_acceleration = [s], [v], [a]
    stop.target_position, stop.target_velocity, stop.target_acceleration = [1.0], [0.0], [0.0]
    stop.max_velocity = [speed]
    stop.max_acceleration, stop.max_jerk = [[bound] for bound in limits.to_end(s)]
    if ruckig.Ruckig(1).calculate(stop, plan) != ruckig.Result.Working:
        return None
    times = np.arange(1, int(np.ceil(plan.duration / dt)) + 1) * dt
    ahead = np.array([[row[0] for row in plan.at_time(time)] for time in times])
    return (ahead, plan.duration) if limits.within(ahead[:, 0], ahead[:, 1]) else None


class _PathLimits:
    """Per spline interval, from the largest |q'|, |q''|, |q'''| of each joint: the ceiling on sd, the bounds on
    |sdd| (where sd is at most the ceiling) and on |sddd| (where |sdd| is also at most its bound), and the braking
    curve."""

    def __init__(self, spline, qd_max: np.ndarray, qdd_max: np.ndarray, jerk_max: np.ndarray, caps: tuple):
        self.knots = spline.x
        c = spline.c  # (4, intervals, dof): c0 x^3 + c1 x^2 + c2 x + c3, x from the interval's start
        h = np.diff(self.knots)[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):  # q' is largest at an end or at its vertex
            vertex = np.clip(np.nan_to_num(-c[1] / (3 * c[0]), nan=0.0, posinf=0.0, neginf=0.0), 0.0, h)
        d1 = np.abs([3 * c[0] * x**2 + 2 * c[1] * x + c[2] for x in (0.0, h, vertex)]).max(axis=0)
        d2 = np.maximum(np.abs(2 * c[1]), np.abs(6 * c[0] * h + 2 * c[1]))
        d3 = np.abs(6 * c[0])
        self.law_times, s_accel, s_jerk = caps
        law_speed = h[:, 0] / np.diff(self.law_times)  # the law's mean speed on each interval
        with np.errstate(divide="ignore", invalid="ignore"):
            v = np.minimum.reduce([qd_max / d1, np.sqrt(CURVATURE_SHARE * qdd_max / d2),
                                   np.cbrt(CUBIC_SHARE * jerk_max / d3)]).min(axis=1, keepdims=True)
            accel = np.minimum((qdd_max - d2 * v**2) / d1, CROSS_SHARE * jerk_max / (3 * d2 * v))
            accel = np.minimum(np.nan_to_num(accel, nan=np.inf).min(axis=1), s_accel)
            jerk = (jerk_max - 3 * d2 * v * accel[:, None] - d3 * v**3) / d1
            jerk = np.minimum(np.nan_to_num(jerk, nan=np.inf).min(axis=1), s_jerk)
        self.ceiling, self.accel, self.jerk = v[:, 0], accel, jerk
        self.accel_left = np.minimum.accumulate(accel[::-1])[::-1]  # the least from each interval to the end
        self.jerk_left = np.minimum.accumulate(jerk[::-1])[::-1]
        stop = _stop_speed((1.0 - self.knots[:-1]) / AHEAD, self.accel_left, self.jerk_left)
        self.speed = np.minimum.reduce([self.ceiling, law_speed, stop])  # the braking curve at each interval's start
        for i in range(len(h) - 2, -1, -1):  # sd^2 falls by 2 sdd ds
            self.speed[i] = min(self.speed[i], np.sqrt(self.speed[i + 1]**2 + 2.0 * BRAKING_SHARE * accel[i] * h[i, 0]))
        self.decel = np.append(np.maximum(-np.diff(self.speed**2) / (2.0 * h[:-1, 0]), 0.0), 0.0)  # what it asks

    def _at(self, s) -> np.ndarray:
        """The intervals the path parameters s lie in."""
        return np.minimum(np.searchsorted(self.knots, s, side="right") - 1, len(self.speed) - 1)

    def _ahead(self, s: float, distance: float) -> slice:
        """The intervals from s's to the one `distance` further on."""
        first, last = self._at([s, s + distance])
        return slice(first, last + 1)

    def bounds(self, s: float, v: float, a: float, accel: float, jerk: float, dt: float) -> tuple[float, ...]:
        """Bounds on sd, |sdd|, |sddd| for Ruckig's next cycle from the state (s, v, a) and the last bounds on |sdd|
        and |sddd|: the braking curve's least over the stretch a swing of sdd to the most braking it asks within a
        stop covers (or the stop, where shorter), |sdd|'s over the stretch its ramp to zero covers, |sddd|'s over
        the next steps."""
        v = max(v, 0.0)
        step = 2.0 * v * dt
        stop = _stop_time(v, a, accel, jerk)
        asked = float(self.decel[self._ahead(s, AHEAD * v * stop + step)].max())  # the most braking within a stop
        lag = AHEAD * v * min((abs(a) + asked) / jerk, stop) + step
        return (float(self.speed[self._ahead(s, lag)].min()),
                float(self.accel[self._ahead(s, AHEAD * v * abs(a) / jerk + step)].min()),
                float(self.jerk[self._ahead(s, step)].min()))

    def law_time(self, s: float) -> float:
        """When the asked law passes s."""
        return float(np.interp(s, self.knots, self.law_times))

    def to_end(self, s: float) -> tuple[float, float]:
        """The least bounds on |sdd| and |sddd| from s to the end."""
        at = self._at(s)
        return float(self.accel_left[at]), float(self.jerk_left[at])

    def within(self, s: np.ndarray, sd: np.ndarray) -> bool:
        """Whether the samples (s, sd) stay on the path, moving forward, under the joints' ceiling on sd."""
        return bool(s.max() <= 1.0 + EPS and sd.min() >= -EPS and (sd <= self.ceiling[self._at(s)] + EPS).all())


def _stop_time(v: float, a: float, accel: float, jerk: float) -> float:
    """An upper bound on the time sd takes from (v, a) to rest under |sdd| <= accel, |sddd| <= jerk: sdd to zero,
    then the jerk-limited stop from the speed reached."""
    top = max(v, 0.0) + max(a, 0.0)**2 / (2.0 * jerk)
    return abs(a) / jerk + (2.0 * np.sqrt(top / jerk) if top < accel**2 / jerk else top / accel + accel / jerk)


def _stop_distance(v: float, a: float, accel: float, jerk: float) -> float:
    """An upper bound on how far s runs in that time."""
    return (max(v, 0.0) + max(a, 0.0)**2 / (2.0 * jerk)) * _stop_time(v, a, accel, jerk)


def _stop_speed(distance: np.ndarray, accel: np.ndarray, jerk: np.ndarray) -> np.ndarray:
    """The fastest sd that stops within `distance` from sdd = 0 under |sdd| <= accel, |sddd| <= jerk: the inverse of
    v sqrt(v / jerk) (sdd up and down, below accel) or v^2 / (2 accel) + v accel / (2 jerk) (reaching it)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        short = np.cbrt(distance**2 * jerk)
        long = np.sqrt(accel**4 / (4.0 * jerk**2) + 2.0 * accel * distance) - accel**2 / (2.0 * jerk)
    return np.where(short < accel**2 / jerk, short, long)
