"""The plan on the control grid from the schedule: every arm's theta and gamma (holds and quintic swings), the
electromagnets' switches, which arms grip, and the rotor's references and orientations, found BLOCK samples at a
time."""

from __future__ import annotations

import numpy as np

from simbench.api.trajectory import Switch, gradient_rows
from simbench.maths.rotations import matrix_to_quat
from simbench.planners.round_robin.schedule import ScheduleGrid
from simbench.planners.round_robin.search import FIT, Hold
from simbench.planners.round_robin.task import Motion
from simbench.planners.rsmg_contacts import FixedContacts, GeneralContacts, quintic
from simbench.robots import rsmg

# control samples whose orientations and rates are found at a time, in planning (rotor_references, joint_rates)
# and during the run (Orientations), so that their temporaries stay small
BLOCK = 8192
_MARKER = np.array([0.0, 0.0, 1.0])  # the rotor point whose path the report tracks (scaled to 1.2 x radius)


def _arm_path(t: np.ndarray, arm: int, holds: list[Hold], contacts: FixedContacts | GeneralContacts,
              grid: np.ndarray, n_approach: int, out_theta: np.ndarray, out_gamma: np.ndarray) -> None:
    """theta and gamma (N,) of one arm on the control grid t, into out_theta and out_gamma (NaN on entry): the IK
    of its held points (from n_approach steps before each grip), quintic swings between. A swing's end states are
    fitted on the schedule grid (FIT steps of each hold), whatever the control step."""
    mine = [h for h in holds if h.arm == arm]
    held = []  # per hold: grid times and its theta, gamma there
    for h in mine:
        start, stop = max(h.start - n_approach, 0), min(h.end, grid.size - 1)
        span = grid[start:stop + 1]
        # a hold never released lasts to the reference's end, which may pass the schedule's by up to half a control
        # step (control_grid rounds the samples' count): there it keeps its last value (np.interp's)
        inside = _span(t, span[0], np.inf) if h.end >= grid.size else _span(t, span[0], grid[h.end])
        theta, ga = contacts.path(arm, h.point, start, stop + 1)
        th = np.unwrap(theta)
        if held:  # keep theta on the turn nearest where the swing began
            th += 2 * np.pi * np.round((held[-1][1][-1] - th[0]) / (2 * np.pi))
        out_theta[inside] = np.interp(t[inside], span, th)
        out_gamma[inside] = np.interp(t[inside], span, ga)
        held.append((span, th, ga))
    for (a, (span_a, th_a, ga_a)), (b, (span_b, th_b, ga_b)) in zip(zip(mine, held), zip(mine[1:], held[1:])):
        t0, t1 = grid[a.end], grid[b.start - n_approach]
        swing = _span(t, t0, t1)
        for series, before, after in ((out_theta, th_a, th_b), (out_gamma, ga_a, ga_b)):
            start = _state(span_a[-FIT - 1:], before[-FIT - 1:], t0)
            end = _state(span_b[:FIT + 1], after[:FIT + 1], t1)
            coef = quintic(t1 - t0, np.concatenate([start, end]))
            series[swing] = np.polynomial.polynomial.polyval(t[swing] - t0, coef)


def _span(t: np.ndarray, start: float, stop: float) -> slice:
    """The samples of increasing times t from `start` to before `stop`, as a slice found by bisection."""
    return slice(int(np.searchsorted(t, start)), int(np.searchsorted(t, stop)))


def _state(t: np.ndarray, y: np.ndarray, at: float) -> np.ndarray:
    """Value, rate and acceleration at time `at`, from a quadratic fitted to the samples."""
    c = np.polynomial.polynomial.polyfit(t - at, y, 2)
    return np.array([c[0], c[1], 2 * c[2]])


def joint_paths(t: np.ndarray, sched: ScheduleGrid) -> np.ndarray:
    """q_ref (N, 8) on the control grid: every arm's theta, then every arm's gamma (_arm_path, into its columns)."""
    q_ref = np.full((t.size, 2 * rsmg.ARMS), np.nan)
    for arm in range(rsmg.ARMS):
        _arm_path(t, arm, sched.holds, sched.contacts, sched.grid, sched.n_approach, q_ref[:, arm],
                  q_ref[:, rsmg.ARMS + arm])
    return q_ref


def grip_switches(holds: list[Hold], grid: np.ndarray, contacts: FixedContacts | GeneralContacts) -> tuple[Switch, ...]:
    """The electromagnets' switches in time order: on at each grip (from the point the arm held before; `point`:
    the one it grips, a unit vector in the rotor's frame), off at each release."""
    switches = []
    for h in holds:
        previous = [p for p in holds if p.arm == h.arm and p.end <= h.start]
        label = contacts.label(h.arm, h.point)
        switches.append(Switch(t=float(grid[h.start]), equality=f"grip{h.arm + 1}", active=True,
                               servo_group=h.arm + 1, detail={
                                   "arm": h.arm + 1,
                                   "from_point": contacts.label(h.arm, previous[-1].point) if previous else None,
                                   "to_point": label, "point": contacts.point(h.arm, h.point).tolist()}))
        if h.end < grid.size:
            switches.append(Switch(t=float(grid[h.end]), equality=f"grip{h.arm + 1}", active=False,
                                   servo_group=h.arm + 1, detail={"arm": h.arm + 1, "from_point": label}))
    return tuple(sorted(switches, key=lambda w: w.t))


def engaged_arms(t: np.ndarray, holds: list[Hold], grid: np.ndarray) -> np.ndarray:
    """Which arms grip (N, 4) at each control sample."""
    engaged = np.zeros((t.size, rsmg.ARMS), bool)
    for h in holds:
        stop = grid[h.end] if h.end < grid.size else np.inf
        engaged[_span(t, grid[h.start], stop), h.arm] = True
    return engaged


def rotor_references(motion: Motion, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The marker's planned point (N, 3) and the rotor's planned orientation as quaternions (N, 4) at path
    parameters s, a BLOCK of samples at a time (each row's numbers those of the whole run's arrays)."""
    tool_ref, quat = np.empty((len(s), 3)), np.empty((len(s), 4))
    for i in range(0, len(s), BLOCK):
        rot = motion.orientation(s[i:i + BLOCK])
        tool_ref[i:i + BLOCK] = rot @ (_MARKER * 1.2 * rsmg.RADIUS)
        quat[i:i + BLOCK] = matrix_to_quat(rot)
    return tool_ref, quat


def joint_rates(q_ref: np.ndarray, dt: float) -> np.ndarray:
    """np.gradient(q_ref, dt, axis=0) BLOCK rows at a time (trajectory.gradient_rows, as trajectory.revise takes
    it): the same numbers without temporaries of several times q_ref. dt, not t: np.gradient rounds differently."""
    qd_ref = np.empty(q_ref.shape)
    for lo in range(0, len(q_ref), BLOCK):
        qd_ref[lo:lo + BLOCK] = gradient_rows(q_ref, lo, min(lo + BLOCK, len(q_ref)), dt)
    return qd_ref


class Orientations:
    """The rotor's commanded orientations R (N, 3, 3) at the plan's path parameters s, found from the motion a
    block of BLOCK rows at a time as the run's grips ask for them, not kept whole. The grips come in time order,
    so the blocks before the latest asked for are dropped (and found again should an earlier row be asked for)."""

    def __init__(self, motion: Motion, s: np.ndarray):
        self.motion, self.s = motion, s
        self.blocks: dict[int, np.ndarray] = {}

    def rows(self, a: int, b: int) -> np.ndarray:
        """R at rows a..b-1: the same numbers as motion.orientation(s)[a:b] (each row's own)."""
        first, last = a // BLOCK, max(b - 1, a) // BLOCK
        self.blocks = {i: block for i, block in self.blocks.items() if i >= first}
        for i in range(first, last + 1):
            if i not in self.blocks:
                self.blocks[i] = self.motion.orientation(self.s[i * BLOCK:(i + 1) * BLOCK])
        return np.concatenate([self.blocks[i][max(a - i * BLOCK, 0):b - i * BLOCK] for i in range(first, last + 1)])
