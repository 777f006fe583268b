"""The schedule's search (section 4.1-4.3): depth first over which arm lets go when and which point it grips
next, on the schedule grid, keeping the gripping arms inside the gamma band and their A far from rank loss."""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations, product
from typing import NamedTuple

import numpy as np

from simbench.core.errors import RunError
from simbench.maths.vectors import triple
from simbench.planners.rsmg_contacts import FixedContacts, GeneralContacts
from simbench.planners.rsmg_lazy import CACHE_FLOATS, BoundedCache, Lazy, LazyExit, exit_upto, first_false, first_out
from simbench.robots import rsmg

STEP = 0.005  # s: the schedule's time step
FIT = 4  # schedule steps on each side of a swing from which its end states are fitted; a hold is longer
# Most choices the search tries; general contacts get one more a possible re-grip (schedule.search_holds).
SEARCH = {"fixed": 2000, "general": 300}
_EARLIER = 2  # earlier releases a swing apart that the search may try after the latest one, per next point
_STARTS = 24  # sets of initial grips general contacts try at most (the longest lasting)


@dataclass(frozen=True)
class Hold:
    """Arm `arm` grips candidate `point` from step `start` to step `end` (exclusive)."""

    arm: int
    point: int
    start: int
    end: int


@dataclass
class _Choice:
    """A moment where an arm must let go: the (arm, release step, next point) options not yet tried, best first,
    and the one taken."""

    current: dict[int, tuple[int, int]]
    options: list[tuple[int, int, int]]
    taken: tuple[int, int] = (-1, -1)  # (arm, release step)


def _grips(points: dict[int, int], contacts) -> str:
    """Arms and the points they hold, as '1a 2b 3c 4a'."""
    return " ".join(f"{a + 1}{contacts.label(a, p)}" for a, p in sorted(points.items()))


_Current = dict[int, tuple[int, int]]  # each arm's (point it holds, step it grips it from)


def _held(current: _Current) -> dict[int, int]:
    """The point each arm holds, without since when."""
    return {a: p for a, (p, _) in current.items()}


def _latest_and_earlier(works: np.ndarray, n_swing: int) -> list:
    """Of the release steps that work (latest first), the latest and up to _EARLIER earlier ones a swing apart."""
    picked = [works[0]] if works.size else []
    for r in works[1:]:
        if len(picked) > _EARLIER:
            break
        if picked[-1] - r >= n_swing:
            picked.append(r)
    return picked


class _Due(NamedTuple):
    """A step where an arm must let go: the points held, the first step A is under det_a_min (`weak`), the arms'
    (exit step, arm) from the band, soonest first, and whether A's rank loss (any arm may let go) sets it."""

    step: int
    points: dict[int, int]
    weak: int
    exits: list[tuple[int, int]]
    rank_loss: bool

    def others_leave(self, arm: int, n_swing: int) -> bool:
        """Whether another arm leaves the band before `arm` could swing and grip again."""
        return any(e < self.step + n_swing for e, a in self.exits if a != arm)


@dataclass
class Scheduler:
    """The search of `schedule` on its grid, over `contacts` (rsmg_contacts); a swing of n_swing steps whose last
    n_approach follow the next point. Caches the type A measures it meets."""

    contacts: FixedContacts | GeneralContacts
    det_a_min: float | np.ndarray  # the floor on the type A measure: one, or one a step
    n_swing: int
    n_approach: int
    budget: int = SEARCH["fixed"]
    minors: BoundedCache = field(default_factory=lambda: BoundedCache(CACHE_FLOATS))
    weak_steps: BoundedCache = field(default_factory=lambda: BoundedCache(CACHE_FLOATS))

    @property
    def n(self) -> int:
        """Steps of the grid."""
        return self.contacts.n

    def measure(self, points: dict[int, int], free: int | None = None) -> np.ndarray:
        """The type A measure (N,) of the arms on `points` but `free`: the largest |3 x 3 minor| of their rows of A
        (eqs. 36-39); NaN where an arm is out of reach."""
        gripping = [(a, p) for a, p in sorted(points.items()) if a != free]
        minors = [self.minor(three) for three in combinations(gripping, 3)]
        if isinstance(self.contacts, FixedContacts):
            return np.max(minors, axis=0)
        return self.contacts.lazy(lambda first, stop: np.max([m[first:stop] for m in minors], axis=0))

    def minor(self, three: tuple[tuple[int, int], ...]) -> np.ndarray | Lazy:
        """|det| of three arms' rows of A on their points (N,) (eqs. 36-39), Lazy with general contacts."""
        if three in self.minors:
            return self.minors[three]
        rows = [self.contacts.rows(i, p) for i, p in three]
        if isinstance(self.contacts, FixedContacts):
            return self.minors.keep(three, np.abs(triple(*rows)))
        return self.minors.keep(three, self.contacts.lazy(
            lambda first, stop: np.abs(triple(*(r[first:stop] for r in rows)))))

    def next_weak(self, points: dict[int, int]) -> np.ndarray:
        """For each step, the first at or after it where the four arms on `points` are under det_a_min."""
        key = tuple(points[i] for i in range(rsmg.ARMS))
        if key in self.weak_steps:
            return self.weak_steps[key]
        measure = self.measure(points)
        if isinstance(self.contacts, FixedContacts):
            return self.weak_steps.keep(key, first_false(measure >= self.det_a_min))
        floor = np.broadcast_to(self.det_a_min, (self.n,))
        firm = self.contacts.lazy(lambda first, stop: measure[first:stop] >= floor[first:stop])
        return self.weak_steps.keep(key, LazyExit(firm))

    def holding_firmly(self, current: _Current, arm: int, earliest: int, latest: int) -> np.ndarray:
        """Whether the other arms keep |det A| >= det_a_min through a swing of `arm` released at each step from
        earliest to latest."""
        stop = min(latest + self.n_swing + 1, self.n)
        floor = np.broadcast_to(self.det_a_min, (self.n,))[earliest:stop]
        firm = self.measure(_held(current), free=arm)[earliest:stop] >= floor
        weak = np.concatenate([[0], np.cumsum(~firm)])
        release = np.arange(latest - earliest + 1)
        end = np.minimum(release + self.n_swing + 1, firm.size)
        return weak[end] - weak[release] == 0

    def choices(self, current: _Current, arm: int, earliest: int, latest: int) -> list[tuple[int, int]]:
        """(release step, next point), best first: for each hold wanted after the grip and each next point, the
        latest release that works, then up to _EARLIER earlier ones."""
        n, n_swing, point = self.n, self.n_swing, current[arm][0]
        release = np.arange(latest, earliest - 1, -1)
        release = release[release + n_swing < n]
        grip = release + n_swing
        firm = self.holding_firmly(current, arm, earliest, latest)[release - earliest]
        found = []
        nexts = self.contacts.next_points(arm, _held(current), latest + n_swing)
        holds = ((rsmg.ARMS - 1) * n_swing, n_swing)
        limit = int(np.minimum(grip + holds[0], n - 1).max(initial=0)) + 1  # beyond the longest hold wanted
        ahead = {k: self.ahead(current, arm, k, grip, limit) for k in nexts}
        for hold in holds:
            for k in nexts:
                ready, leaves = ahead[k]
                works = firm & ready & (leaves > np.minimum(grip + hold, n - 1))
                works[works] = self.contacts.swing_fits(arm, point, k, release[works])
                picked = _latest_and_earlier(release[works], n_swing)
                found += [(int(r), k) for r in picked if (int(r), k) not in found]
        return found

    def ahead(self, current: _Current, arm: int, k: int, grip: np.ndarray,
              limit: int) -> tuple[np.ndarray, np.ndarray]:
        """For `arm` gripping point k at each step of `grip`: whether k is inside the band from the approach on, and
        the first step from the grip where k leaves it or A falls under det_a_min (at most `limit`: no further
        blocks are computed)."""
        weak = exit_upto(self.next_weak(_held(current) | {arm: k}), grip, limit)
        bad = self.contacts.next_bad(arm, k)
        ready = exit_upto(bad, grip - self.n_approach, limit) > grip
        return ready, np.minimum(exit_upto(bad, grip, limit), weak)

    def next_choice(self, current: _Current, step: int) -> _Choice | list[Hold] | tuple[int, str, int]:
        """From `step`: the next choice, the last holds if no arm need let go again, or (step, why, arm) if stuck."""
        due = self.due(current, step)
        if isinstance(due, list):
            return due
        options = self.options(current, due)
        return _Choice(current, options) if options else (due.step, self.stuck(due),
                                                          -1 if due.rank_loss else due.exits[0][1])

    def due(self, current: _Current, step: int) -> _Due | list[Hold]:
        """The first step from `step` where an arm must let go (the package's docstring), or the last holds."""
        n, n_swing = self.n, self.n_swing
        # one arm swings at a time; the others were checked to hold until it grips
        step = max(step, *(since for _, since in current.values()))
        points = _held(current)
        while True:
            weak = int(self.next_weak(points)[step])
            exits = sorted((int(self.contacts.next_bad(a, p)[step]), a) for a, p in points.items())
            if exits[0][0] >= n and weak >= n:
                return [Hold(a, p, since, n) for a, (p, since) in current.items()]
            band = min([e - (rank + 1) * n_swing for rank, (e, _) in enumerate(exits) if e < n], default=n)
            deadline = min(band, weak - n_swing)
            if deadline <= step:
                return _Due(step, points, weak, exits, weak < n and weak - n_swing <= band)
            step = deadline

    def options(self, current: _Current, due: _Due) -> list[tuple[int, int, int]]:
        """(arm, release step, next point) for each arm that may let go at `due`, in order of preference."""
        # The arm leaving the band first lets go; if the four arms' A is what runs out first, any arm may.
        arms = [a for _, a in due.exits] if due.rank_loss else [due.exits[0][1]]
        options = []
        for arm in arms:
            if due.others_leave(arm, self.n_swing):
                continue
            earliest = max([current[arm][1] + FIT + 1] + [s for a, (_, s) in current.items() if a != arm])
            options += [(arm, r, k) for r, k in self.choices(current, arm, earliest, due.step)]
        return options

    def stuck(self, due: _Due) -> str:
        """Why no arm can let go at `due`."""
        if due.rank_loss:
            grips = _grips(due.points, self.contacts)
            return (f"at t = {due.weak * STEP:.3f} s the four gripping arms ({grips}) hold the rotor "
                    f"with a largest 3x3 minor of A of {self.measure(due.points)[due.weak]:.4f} and no arm can re-grip "
                    "before then")
        t, arm = f"at t = {due.step * STEP:.3f} s", due.exits[0][1]
        if due.others_leave(arm, self.n_swing):
            return f"{t} arm {arm + 1} must let go but another arm leaves the gamma band before it can grip again"
        return (f"{t} arm {arm + 1} has no next contact point inside the gamma band to swing to while the "
                "others hold the rotor firmly")

    def search(self, current: _Current, budget: int) -> tuple[list[Hold] | None, list, int]:
        """Depth first from the initial grips: (holds or None, where it got stuck, tries spent)."""
        taken: list[_Choice] = []  # the choices on the way so far
        stuck: list[tuple[int, str, int]] = []
        tries = 0
        found = self.next_choice(current, 0)
        while not isinstance(found, list):
            if isinstance(found, _Choice):
                taken.append(found)
            else:
                stuck.append(found)
            while taken and not taken[-1].options:  # back up to the latest choice with an option left
                taken.pop()
            if not taken or tries >= budget:
                return None, stuck, tries
            choice = taken[-1]
            arm, release, nxt = choice.options.pop(0)
            choice.taken = (arm, release)
            tries += 1
            found = self.next_choice({**choice.current, arm: (nxt, release + self.n_swing)}, release + 1)
        return [Hold(a, *c.current[a], r) for c in taken for a, r in [c.taken]] + found, stuck, tries

    def search_from(self, starts: list[dict[int, int]]) -> tuple[list[Hold] | None, list, int]:
        """`search` from each set of initial grips in turn until one succeeds or the budget is spent."""
        stuck, tries = [], 0
        for start in starts:
            holds, more, spent = self.search({a: (p, 0) for a, p in start.items()}, self.budget - tries)
            stuck, tries = stuck + more, tries + spent
            if holds is not None or tries >= self.budget:
                return holds, stuck, tries
        return None, stuck, tries

    def lasting(self, start: dict[int, int]) -> int:
        """Steps until an arm leaves the band or A falls under det_a_min (general contacts: up to their horizon)."""
        if isinstance(self.contacts, FixedContacts):
            return min(int(self.next_weak(start)[0]), *(int(self.contacts.next_bad(a, p)[0]) for a, p in start.items()))
        stop = min(self.contacts.horizon, self.n)
        floor = np.broadcast_to(self.det_a_min, (self.n,))[:stop]
        weak = int(first_out(self.measure(start)[:stop] >= floor))
        return min(weak, *(exit_upto(self.contacts.next_bad(a, p), 0, stop) for a, p in start.items()))

    def starts(self, limits: str) -> list[dict[int, int]]:
        """The initial grips to try, firm at t = 0: each arm's longest-lasting point first, then the others."""
        inside = [self.contacts.initial_points(a) for a in range(rsmg.ARMS)]
        for arm, ks in enumerate(inside):
            if not ks:
                raise RunError(f"arm {arm + 1} can grip none of its contact points inside the gamma band at t = 0")
        first = {a: max(ks, key=lambda k: self.contacts.next_bad(a, k)[0]) for a, ks in enumerate(inside)}
        lasting = {ks: self.lasting(dict(enumerate(ks))) for ks in product(*inside)}
        starts = [dict(enumerate(ks)) for ks, steps in lasting.items() if steps > 0]
        if not starts:
            raise RunError(f"round robin: at t = 0 no set of contact points inside the gamma band holds the rotor "
                           f"firmly; {limits}")
        starts.sort(key=lambda s: (s != first, -lasting[tuple(s.values())]))
        return starts if isinstance(self.contacts, FixedContacts) else starts[:_STARTS]

