"""The grips scheduled on the schedule grid along the rotor's motion; `Stuck` where no schedule keeps the band and
|det A|."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from simbench.core.errors import RunError
from simbench.maths.timing import TimeLaw
from simbench.planners.round_robin.search import SEARCH, STEP, Hold, Scheduler
from simbench.planners.round_robin.task import Task, band
from simbench.planners.rsmg_contacts import FIRM_CAP, FIRM_SPEED, SPEED_SHARE, FixedContacts, GeneralContacts, Swing
from simbench.robots import rsmg


def gammas(rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """theta and gamma (4, 3, N) of every arm holding every candidate along orientations (N, 3, 3)."""
    theta = np.empty((rsmg.ARMS, rsmg.CANDIDATES, len(rot)))
    gamma = np.empty_like(theta)
    for i in range(rsmg.ARMS):
        for k in range(rsmg.CANDIDATES):
            theta[i, k], gamma[i, k] = rsmg.ik(i, rot @ rsmg.POINTS[i, k])
    return theta, gamma


def unkept_limits(task: Task, who: str = "no schedule") -> str:
    """What a refused schedule (or `who`) could not keep, for its RunError."""
    lo, hi = band(task)
    return (f"{who} keeps |det A| >= det_a_min = {task.det_a_min:g} (eq. 46{rising(task)}) and every gripping "
            f"gamma in ({np.rad2deg(lo):.0f}, {np.rad2deg(hi):.0f}) deg (eq. 45 less the margin)")


def rising(task: Task) -> str:
    """How general contacts raise the floor on |det A| with the rotor's speed (GeneralContacts.floor), in words."""
    if task.contacts == "fixed" or task.det_a_min >= FIRM_CAP:
        return ""
    return (f"; with general contacts rising in proportion to the rotor's speed beyond "
            f"{np.rad2deg(FIRM_SPEED):.0f} deg/s, up to {FIRM_CAP:g}")


def schedule(gamma: np.ndarray, rows: np.ndarray, task: Task, n_swing: int, n_approach: int = 0) -> list[Hold]:
    """Which point each arm holds when (section 4.1-4.3), from the paper's candidates' gammas (4, 3, N) and rows of
    A (4, 3, N, 3), by search.Scheduler; RunError where no round-robin choice keeps three arms gripping inside
    eq. 45's band with the type A measure (eqs. 36-39) >= task.det_a_min (eq. 46)."""
    return search_holds(FixedContacts(gamma, rows, band(task)), task, n_swing, n_approach)


class Stuck(RunError):
    """No schedule: where the search got furthest and why (arm -1: the four gripping arms' A, not a band)."""

    def __init__(self, message: str, step: int, arm: int):
        super().__init__(message)
        self.step, self.arm = step, arm


def search_holds(contacts: FixedContacts | GeneralContacts, task: Task, n_swing: int, n_approach: int) -> list[Hold]:
    """`schedule` on any contact points: the holds, or Stuck."""
    budget = SEARCH["fixed"] if isinstance(contacts, FixedContacts) else SEARCH["general"] + contacts.n // n_swing
    scheduler = Scheduler(contacts, contacts.floor(task.det_a_min), n_swing, n_approach, budget)
    limits = unkept_limits(task)
    holds, stuck, tries = scheduler.search_from(scheduler.starts(limits))
    if holds is None:
        step, why, arm = max(stuck) if stuck else (0, "no schedule", -1)
        raise Stuck(f"round robin: {why}; {limits}" + (" (search budget spent)" if tries >= budget else ""),
                    step, arm)
    return sorted(holds, key=lambda h: (h.arm, h.start))


class ScheduleGrid(NamedTuple):
    """The schedule on its grid (STEP apart): the contact points, the holds, the steps of a swing's approach."""

    grid: np.ndarray
    contacts: FixedContacts | GeneralContacts
    holds: list[Hold]
    n_approach: int


def candidate_rows(theta: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """Every arm's row of A (eqs. 34-35) on every candidate along the grid, (4, 3, N, 3)."""
    return np.stack([np.stack([rsmg.jacobian_rows(i, theta[i, k], gamma[i, k])[0] for k in range(rsmg.CANDIDATES)])
                     for i in range(rsmg.ARMS)])


def grid_orientations(task: Task, law: TimeLaw, hold: float) -> tuple[np.ndarray, np.ndarray]:
    """The schedule grid (STEP apart, over the motion and its hold) and the rotor's commanded R (N, 3, 3) on it."""
    grid = np.arange(int(np.ceil((law.duration + hold) / STEP)) + 1) * STEP
    return grid, task.motion.orientation(law(grid, order=0)[0])


def schedule_grips(task: Task, law: TimeLaw, hold: float, speed_share: float = SPEED_SHARE) -> ScheduleGrid:
    """The schedule grid, the contact points and the grips scheduled on them; Stuck where none keeps the band
    and |det A| (checks.refusal explains why). `speed_share`: of the joints' speed limits, for general contacts."""
    grid, rot = grid_orientations(task, law, hold)
    n_approach = int(round(task.approach_time / STEP))
    n_swing = max(1, int(round(task.swing_time / STEP))) + n_approach
    if task.contacts == "fixed":
        theta, gamma = gammas(rot)
        contacts = FixedContacts(gamma, candidate_rows(theta, gamma), band(task), theta)
    else:
        contacts = GeneralContacts(rot, STEP, band(task), Swing(n_swing, n_approach), speed_share)
    return ScheduleGrid(grid, contacts, search_holds(contacts, task, n_swing, n_approach), n_approach)
