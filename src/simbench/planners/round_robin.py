"""Paper 001's "Round Robin" operation of the RSMG (section 4, Fig. 10): unlimited rotor motion by re-gripping.

The rotor's commanded orientation R(t) is given: turns about a fixed axis, or a tumble (a spin about a rotor
axis while that axis precesses), on a time law. Each arm holds one of its three candidate contact points; while
it does, its base angle and gamma follow from the IK of the point's current direction (eqs. 12-23). An arm must
let go before its gamma leaves (10, 170) deg (eq. 45, less `gamma_margin`), and the arms gripping the rotor
keep their Jacobian A far from losing rank over the whole schedule: while one arm swings (|det A| of the three
holding), and while all four grip (the largest 3 x 3 minor, eqs. 36-39: four gripping arms can lose rank too,
and then no swing rescues them, since each three of them is as weak). Eq. 46 puts rank loss at |det A| < 0.01;
the schedule keeps this measure >= `det_a_min`, ours, since near 0.01 the rotor is held so loosely that it
drifts by degrees. A motion for which no schedule keeps both is refused (RunError). Its
next point, with `contacts: fixed` (the paper's scheme), is the next candidate in round-robin order (a -> b -> c
-> a) whose gamma is inside the band when the arm gets there; with `contacts: general` (the default, issue 16)
any point of the rotor the arm reaches, the one that keeps its gamma inside the band longest and the holding arms'
|det A| highest over the coming motion (planners.rsmg_contacts), with the floor on |det A| rising with the
rotor's speed and every hold and swing inside the joints' speed limits. A motion general contacts cannot follow
is refused before it is simulated, with the limit that binds (the joints' speed, the time a re-grip takes, or
|det A| and the band), its numbers, and a longer duration over which the same motion is scheduled. While an arm
swings (a quintic in theta and gamma, matching position, speed and acceleration at both ends) the other three arms
hold the rotor, and only one arm swings at a time, so at least three always grip. A swing ends `approach_time`
before the grip: the arm then
follows its next point, not yet gripping, so that its servos settle and the weld goes on where the plan has the
point (ours: the paper switches the electromagnet on when the arm arrives; without the approach a long fast
swing ends a millimetre or two off, and the gripping arms then fight over the rotor).

Closing the loop at each grip (ours; `regrip_feedback`, on by default): a weld holds the EM wherever it touches,
so an arm that grips while the rotor is off its command grips a point off the candidate, and its planned hold
(the IK of the candidate) then pulls against the other arms. Open loop, the paper's way, these offsets add up
grip after grip: in ten minutes of tumbling the rotor drifted by degrees, then tens of degrees, then was lost.
With feedback, when an arm grips, its hold is re-solved for the point it really holds, found from the rotor's
orientation (which a controller has from the gripping arms' encoders by the direct kinematics, eq. 32), so
that every gripping arm pulls the rotor towards its command; the change is eased in over _EASE and out over
the next swing.

Switches are planned ahead: with the gripping arms' exits e_1 <= e_2 <= ... (the times their gammas leave the
band less a margin), the first arm lets go by min_k (e_k - k T_swing), so that every arm can swing in turn
before its exit; and by e_A - T_swing, e_A the time the four arms' A would fall under `det_a_min`, so that one
of them (any) holds another point by then.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations, product
from typing import Annotated, Literal, NamedTuple

import numpy as np
from pydantic import Field, model_validator

from simbench import heap, pages
from simbench.api import Planner
from simbench.errors import RunError
from simbench.planners.rsmg_contacts import (CACHE_FLOATS, FIRM_CAP, FIRM_SPEED, SPEED_SHARE, BoundedCache,
                                             FixedContacts, GeneralContacts, Lazy, LazyExit, Swing, angular_speed,
                                             exit_upto, first_false, first_out)
from simbench.robots import rsmg
from simbench.rotations import axis_rotation, matrix_to_quat
from simbench.schema import Direction, NonNegativeAngle, SimbenchModel, seconds
from simbench.timing import TimeLaw
from simbench.trajectory import JointTrajectory, Switch, control_grid, gradient_rows
from simbench.vectors import triple

_STEP = 0.005  # s: the schedule's time step
_FIT = 4  # schedule steps on each side of a swing from which its end states are fitted; a hold is longer
# Most choices the schedule's search tries. General contacts rarely back up: 300 tries beyond one a possible re-grip
# (a swing's time apart), so that a long motion's hundreds of re-grips fit.
_SEARCH = {"fixed": 2000, "general": 300}
_EARLIER = 2  # earlier releases a swing apart that the search may try after the latest one, per next point
_EASE = 0.1  # s: a grip's revised hold blends in from the old one over this time
_QUINTIC = TimeLaw("quintic", 1.0)
_STARTS = 24  # sets of initial grips general contacts try at most (the longest lasting)
_SLOWER = (1.25, 1.5, 2.0, 3.0, 4.0)  # a refused motion's durations tried, as multiples of the task's
# control samples whose orientations and rates are found at a time, in planning (_rotor_references, _joint_rates)
# and during the run, as grips ask for them (_Orientations): the temporaries of a rotation matrix for each of
# 65,536 samples took 28 MB
_BLOCK = 8192
_MARKER = np.array([0.0, 0.0, 1.0])  # the rotor point whose path the report tracks (scaled to 1.2 x radius)
# The floor on the holding arms' |det A| (eq. 46 puts rank loss at 0.01) unless the task sets det_a_min: with the
# paper's three points 0.15; with general contacts 0.3, which they keep on every motion of the benchmark, and which
# rises with the rotor's speed (GeneralContacts.floor) to keep a fast rotor within 1 deg of its command (at 0.15,
# random motions at 73-175 deg/s, three arms holding near the floor, ran up to 1.9 deg off).
_DET_A_MIN = {"fixed": 0.15, "general": 0.3}


Turns = Annotated[float, Field(ge=-100, le=100)]  # a motion of more turns is a typo: it would run for hours


class Motion(SimbenchModel):
    """The rotor's commanded motion. `turns`: `turns` turns about `axis`. `tumble`: `spin_turns` about the
    rotor's `spin_axis` while that axis turns `precession_turns` about `precession_axis`."""

    kind: Literal["turns", "tumble"]
    axis: Direction = [0.0, 0.0, 1.0]
    turns: Turns = 1.0
    spin_axis: Direction = [0.0, 0.0, 1.0]
    spin_turns: Turns = 1.0
    precession_axis: Direction = [1.0, 0.0, 0.0]
    precession_turns: Turns = 1.0

    def orientation(self, s: np.ndarray) -> np.ndarray:
        """R (N, 3, 3) at path parameters s in [0, 1]: a tumble is the precession's rotation after the spin's."""
        s = np.asarray(s, float)

        def turning(axis: list[float], turns: float) -> np.ndarray:  # about a unit axis (schema.Direction)
            return axis_rotation(np.broadcast_to(np.array(axis), (len(s), 3)), 2 * np.pi * turns * s)

        if self.kind == "turns":
            return turning(self.axis, self.turns)
        return turning(self.precession_axis, self.precession_turns) @ turning(self.spin_axis, self.spin_turns)


class Task(SimbenchModel):
    """`task:` of the round-robin scheme."""

    motion: Motion
    swing_time: seconds(0.01, 60.0) = 0.5
    approach_time: seconds(0.0, 60.0) = 0.1
    det_a_min: Annotated[float, Field(gt=0, le=1)] | None = None  # default: _DET_A_MIN of the contacts
    regrip_feedback: bool = True
    gamma_margin: NonNegativeAngle = float(np.deg2rad(12.0))
    contacts: Literal["general", "fixed"] = "general"

    @model_validator(mode="after")
    def _default_det_a_min(self) -> "Task":
        if self.det_a_min is None:
            object.__setattr__(self, "det_a_min", _DET_A_MIN[self.contacts])  # the model is frozen
        return self


@dataclass(frozen=True)
class Hold:
    """Arm `arm` grips candidate `point` from step `start` to step `end` (exclusive)."""

    arm: int
    point: int
    start: int
    end: int


@dataclass
class _Choice:
    """A moment where an arm must let go of the point it holds (current: each arm's (point, held since step)): the
    (arm, release step, next point) options not yet tried, in order of preference, and the one taken."""

    current: dict[int, tuple[int, int]]
    options: list[tuple[int, int, int]]
    taken: tuple[int, int] = (-1, -1)  # (arm, release step)


def _gammas(rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """theta and gamma (4, 3, N) of every arm holding every candidate along orientations (N, 3, 3)."""
    theta = np.empty((rsmg.ARMS, rsmg.CANDIDATES, len(rot)))
    gamma = np.empty_like(theta)
    for i in range(rsmg.ARMS):
        for k in range(rsmg.CANDIDATES):
            theta[i, k], gamma[i, k] = rsmg.ik(i, rot @ rsmg.POINTS[i, k])
    return theta, gamma


def _grips(points: dict[int, int], contacts) -> str:
    """Arms and the points they hold, as '1a 2b 3c 4a'."""
    return " ".join(f"{a + 1}{contacts.label(a, p)}" for a, p in sorted(points.items()))


_Current = dict[int, tuple[int, int]]  # each arm's (point it holds, step it grips it from)


def _held(current: _Current) -> dict[int, int]:
    """The point each arm holds, without since when."""
    return {a: p for a, (p, _) in current.items()}


def _band(task: Task) -> tuple[float, float]:
    """(lo, hi): eq. 45's band of gamma, (10, 170) deg, narrowed by task.gamma_margin at both ends."""
    return rsmg.GAMMA_BAND[0] + task.gamma_margin, rsmg.GAMMA_BAND[1] - task.gamma_margin


def _limits(task: Task) -> str:
    """What a refused schedule could not keep, for its RunError."""
    lo, hi = _band(task)
    return (f"no schedule keeps |det A| >= det_a_min = {task.det_a_min:g} (eq. 46{_rising(task)}) and every gripping "
            f"gamma in ({np.rad2deg(lo):.0f}, {np.rad2deg(hi):.0f}) deg (eq. 45 less the margin)")


def _rising(task: Task) -> str:
    """How general contacts raise the floor on |det A| with the rotor's speed (GeneralContacts.floor), in words."""
    if task.contacts == "fixed" or task.det_a_min >= FIRM_CAP:
        return ""
    return (f"; with general contacts rising in proportion to the rotor's speed beyond "
            f"{np.rad2deg(FIRM_SPEED):.0f} deg/s, up to {FIRM_CAP:g}")


def _latest_and_earlier(works: np.ndarray, n_swing: int) -> list:
    """Of the release steps that work (latest first), the latest and up to _EARLIER earlier ones, each at least a
    swing before the one picked before it."""
    picked = [works[0]] if works.size else []
    for r in works[1:]:
        if len(picked) > _EARLIER:
            break
        if picked[-1] - r >= n_swing:
            picked.append(r)
    return picked


class _Due(NamedTuple):
    """A step where an arm must let go: what the arms hold then, the first step the four arms' type A measure is
    under det_a_min, the arms' (exit step, arm) from the band, soonest first, and whether A's rank loss (any arm
    may let go) rather than a gamma's exit (the soonest arm must) sets the deadline."""

    step: int
    points: dict[int, int]
    weak: int
    exits: list[tuple[int, int]]
    rank_loss: bool

    def others_leave(self, arm: int, n_swing: int) -> bool:
        """Whether another arm leaves the band before `arm` could swing and grip again."""
        return any(e < self.step + n_swing for e, a in self.exits if a != arm)


@dataclass
class _Scheduler:
    """The search of `schedule` on its grid: `contacts` (rsmg_contacts' FixedContacts or GeneralContacts) gives
    every arm's row of A on every point and, for each step, the first at or after it where the arm's gamma on the
    point leaves the band, and the points to try next; a swing of n_swing steps whose last n_approach follow the
    next point. Caches the type A measures it meets."""

    contacts: FixedContacts | GeneralContacts
    det_a_min: float | np.ndarray  # the floor on the type A measure: one, or one a step
    n_swing: int
    n_approach: int
    budget: int = _SEARCH["fixed"]
    minors: BoundedCache = field(default_factory=lambda: BoundedCache(CACHE_FLOATS))
    weak_steps: BoundedCache = field(default_factory=lambda: BoundedCache(CACHE_FLOATS))

    @property
    def n(self) -> int:
        """Steps of the grid."""
        return self.contacts.n

    def next_bad(self, arm: int, k: int) -> np.ndarray:
        """For each step (and one past the end), the first at or after it where `arm` on point k is outside the band."""
        return self.contacts.next_bad(arm, k)

    def measure(self, points: dict[int, int], free: int | None = None) -> np.ndarray:
        """The type A measure (N,) of the arms on `points`, all gripping but `free`: rsmg.type_a_measure's, the
        largest |3 x 3 minor| of their rows of A (eqs. 36-39); NaN where an arm is out of reach (never firm)."""
        gripping = [(a, p) for a, p in sorted(points.items()) if a != free]
        minors = [self.minor(three) for three in combinations(gripping, 3)]
        if isinstance(self.contacts, FixedContacts):
            return np.max(minors, axis=0)
        return self.contacts.lazy(lambda first, stop: np.max([m[first:stop] for m in minors], axis=0))

    def minor(self, three: tuple[tuple[int, int], ...]) -> np.ndarray | Lazy:
        """|det| of three arms' rows of A on their points (N,) (eqs. 36-39): an array, or Lazy with general
        contacts."""
        if three in self.minors:
            return self.minors[three]
        rows = [self.contacts.rows(i, p) for i, p in three]
        if isinstance(self.contacts, FixedContacts):
            return self.minors.keep(three, np.abs(triple(*rows)))
        return self.minors.keep(three, self.contacts.lazy(
            lambda first, stop: np.abs(triple(*(r[first:stop] for r in rows)))))

    def next_weak(self, points: dict[int, int]) -> np.ndarray:
        """For each step (and one past the end), the first step at or after it where the four arms gripping
        `points` have a measure under det_a_min."""
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
        """Whether the other arms, on their current points, keep |det A| >= det_a_min throughout a swing of
        `arm` released at each step from earliest to latest."""
        stop = min(latest + self.n_swing + 1, self.n)
        floor = np.broadcast_to(self.det_a_min, (self.n,))[earliest:stop]
        firm = self.measure(_held(current), free=arm)[earliest:stop] >= floor
        weak = np.concatenate([[0], np.cumsum(~firm)])
        release = np.arange(latest - earliest + 1)
        end = np.minimum(release + self.n_swing + 1, firm.size)
        return weak[end] - weak[release] == 0

    def choices(self, current: _Current, arm: int, earliest: int, latest: int) -> list[tuple[int, int]]:
        """(release step, next point) in order of preference: for each hold wanted after the grip and each next
        point, the latest release that works, then up to _EARLIER earlier ones a swing apart. After the grip the
        four arms must stay firm as long as the arm stays inside the band."""
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
        """For `arm` gripping point k at each step of `grip` while the others hold on: whether k is inside the band
        from the swing's approach on, and the first step from the grip where k leaves the band or the four arms'
        A falls under det_a_min, or `limit` if none is before it (the exits are only compared with steps under
        `limit`: looking no further spares the blocks of general contacts beyond)."""
        weak = exit_upto(self.next_weak(_held(current) | {arm: k}), grip, limit)
        bad = self.next_bad(arm, k)
        ready = exit_upto(bad, grip - self.n_approach, limit) > grip
        return ready, np.minimum(exit_upto(bad, grip, limit), weak)

    def next_choice(self, current: _Current, step: int) -> _Choice | list[Hold] | tuple[int, str, int]:
        """From `step`, given what each arm holds since when: the next choice to make, the last holds if no arm
        need let go again, or (step, why, arm) if the schedule is stuck (arm -1 where A's rank sets the deadline)."""
        due = self.due(current, step)
        if isinstance(due, list):
            return due
        options = self.options(current, due)
        return _Choice(current, options) if options else (due.step, self.stuck(due),
                                                          -1 if due.rank_loss else due.exits[0][1])

    def due(self, current: _Current, step: int) -> _Due | list[Hold]:
        """The first step from `step` where an arm must let go (see the module's docstring: the band's exits a
        swing apart, and a swing before the four arms' A runs out), or the last holds if none must."""
        n, n_swing = self.n, self.n_swing
        # one arm swings at a time; the others were checked to hold until it grips
        step = max(step, *(since for _, since in current.values()))
        points = _held(current)
        while True:
            weak = int(self.next_weak(points)[step])
            exits = sorted((int(self.next_bad(a, p)[step]), a) for a, p in points.items())
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
            earliest = max([current[arm][1] + _FIT + 1] + [s for a, (_, s) in current.items() if a != arm])
            options += [(arm, r, k) for r, k in self.choices(current, arm, earliest, due.step)]
        return options

    def stuck(self, due: _Due) -> str:
        """Why no arm can let go at `due`."""
        if due.rank_loss:
            grips = _grips(due.points, self.contacts)
            return (f"at t = {due.weak * _STEP:.3f} s the four gripping arms ({grips}) hold the rotor "
                    f"with a largest 3x3 minor of A of {self.measure(due.points)[due.weak]:.4f} and no arm can re-grip "
                    "before then")
        t, arm = f"at t = {due.step * _STEP:.3f} s", due.exits[0][1]
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
        """`search` from each set of initial grips in turn, until one gives a schedule or the budget's tries are
        spent in all: (holds or None, where it got stuck, tries spent)."""
        stuck, tries = [], 0
        for start in starts:
            holds, more, spent = self.search({a: (p, 0) for a, p in start.items()}, self.budget - tries)
            stuck, tries = stuck + more, tries + spent
            if holds is not None or tries >= self.budget:
                return holds, stuck, tries
        return None, stuck, tries

    def lasting(self, start: dict[int, int]) -> int:
        """Steps until the first arm leaves the band or the four arms' A falls under det_a_min (general contacts:
        looking no further than their horizon, beyond which any start is as good)."""
        if isinstance(self.contacts, FixedContacts):
            return min(int(self.next_weak(start)[0]), *(int(self.next_bad(a, p)[0]) for a, p in start.items()))
        stop = min(self.contacts.horizon, self.n)
        floor = np.broadcast_to(self.det_a_min, (self.n,))[:stop]
        weak = int(first_out(self.measure(start)[:stop] >= floor))
        return min(weak, *(exit_upto(self.next_bad(a, p), 0, stop) for a, p in start.items()))

    def starts(self, limits: str) -> list[dict[int, int]]:
        """The initial grips to try, each holding firmly at t = 0: each arm on its point inside the band longest
        (the paper's start), then other sets of points, those whose A stays firm longest first."""
        inside = [self.contacts.initial_points(a) for a in range(rsmg.ARMS)]
        for arm, ks in enumerate(inside):
            if not ks:
                raise RunError(f"arm {arm + 1} can grip none of its contact points inside the gamma band at t = 0")
        first = {a: max(ks, key=lambda k: self.next_bad(a, k)[0]) for a, ks in enumerate(inside)}
        if isinstance(self.contacts, FixedContacts):
            starts = [s for s in (dict(enumerate(ks)) for ks in product(*inside)) if self.next_weak(s)[0] > 0]
            lasting = {tuple(s.values()): self.lasting(s) for s in starts}
        else:
            lasting = {ks: self.lasting(dict(enumerate(ks))) for ks in product(*inside)}
            starts = [dict(enumerate(ks)) for ks, steps in lasting.items() if steps > 0]
        if not starts:
            raise RunError(f"round robin: at t = 0 no set of contact points inside the gamma band holds the rotor "
                           f"firmly; {limits}")
        starts.sort(key=lambda s: (s != first, -lasting[tuple(s.values())]))
        return starts if isinstance(self.contacts, FixedContacts) else starts[:_STARTS]


def schedule(gamma: np.ndarray, rows: np.ndarray, task: Task, n_swing: int, n_approach: int = 0) -> list[Hold]:
    """Which point each arm holds when, on the schedule grid (section 4.1-4.3), with the paper's candidates (their
    gammas (4, 3, N) and rows of A (4, 3, N, 3) given); RunError where no round-robin choice keeps three arms
    gripping inside the band with A far from rank loss. General contacts go through the same search (`_search`),
    their points ranked instead of taken in turn.

    Time advances until an arm must let go (its deadline, see the module's docstring). Its choices, in order of
    preference: the next candidate in round-robin order, then the one after (the paper's order of trial), each
    let go as late as it can be and still be inside the band when the arm gets there and for long enough after
    (first: for the other three arms to take a swing each; then: for one swing), then a little earlier. If a
    choice leads to an arm with no choice later, the search backs up and takes the next one (depth first, at
    most _SEARCH tries).
    A swing takes n_swing steps, the last n_approach of them following the next point, inside the band too.
    Over the whole schedule, at every step, the gripping arms' rows of A (`rows`, (4, 3, N, 3): every arm on every
    point) keep the type A measure (rsmg.type_a_measure: |det A| of the three holding while one swings, the
    largest 3 x 3 minor while all four grip; eqs. 36-39) >= task.det_a_min (eq. 46's rank-loss test with our
    floor), and every gripping arm's gamma inside eq. 45's band less task.gamma_margin. Four gripping arms whose
    measure falls under the floor cannot be rescued by a swing (each three of them is as weak), so before that
    step one of them must have moved to another point: that is a deadline like a gamma's exit, and any arm may
    take it.
    """
    return _search(FixedContacts(gamma, rows, _band(task)), task, n_swing, n_approach)


class _Stuck(RunError):
    """No schedule: the message says where the search got furthest and why; `step` and `arm` say where (arm -1:
    the four gripping arms' A, not one arm's band)."""

    def __init__(self, message: str, step: int, arm: int):
        super().__init__(message)
        self.step, self.arm = step, arm


def _search(contacts: FixedContacts | GeneralContacts, task: Task, n_swing: int, n_approach: int) -> list[Hold]:
    """`schedule` on any contact points: the holds, or _Stuck."""
    budget = _SEARCH["fixed"] if isinstance(contacts, FixedContacts) else _SEARCH["general"] + contacts.n // n_swing
    scheduler = _Scheduler(contacts, contacts.floor(task.det_a_min), n_swing, n_approach, budget)
    limits = _limits(task)
    holds, stuck, tries = scheduler.search_from(scheduler.starts(limits))
    if holds is None:
        step, why, arm = max(stuck) if stuck else (0, "no schedule", -1)
        raise _Stuck(f"round robin: {why}; {limits}" + (" (search budget spent)" if tries >= budget else ""),
                     step, arm)
    return sorted(holds, key=lambda h: (h.arm, h.start))


def _quintic(t: np.ndarray, t0: float, t1: float, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Quintic in t on [t0, t1] meeting (value, rate, acceleration) `start` at t0 and `end` at t1."""
    h = t1 - t0
    a = np.array([[1, 0, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0], [0, 0, 2, 0, 0, 0],
                  [1, h, h**2, h**3, h**4, h**5], [0, 1, 2 * h, 3 * h**2, 4 * h**3, 5 * h**4],
                  [0, 0, 2, 6 * h, 12 * h**2, 20 * h**3]], float)
    coef = np.linalg.solve(a, np.concatenate([start, end]))
    return np.polynomial.polynomial.polyval(t - t0, coef)


def _arm_path(t: np.ndarray, arm: int, holds: list[Hold], contacts: FixedContacts | GeneralContacts,
              grid: np.ndarray, n_approach: int, out_theta: np.ndarray, out_gamma: np.ndarray) -> None:
    """theta and gamma (N,) of one arm on the control grid t, into out_theta and out_gamma (NaN on entry): the IK
    of its held points (from n_approach steps before each grip), quintic swings between. A swing's end states are
    fitted on the schedule grid (_FIT steps of each hold), whatever the control step."""
    mine = [h for h in holds if h.arm == arm]
    held = []  # per hold: grid times and its theta, gamma there
    for h in mine:
        start, stop = max(h.start - n_approach, 0), min(h.end, grid.size - 1)
        span = grid[start:stop + 1]
        # a hold never released lasts to the reference's end, which may pass the schedule's by up to half a control
        # step (control_grid rounds the samples' count): there it keeps its last value (np.interp's)
        inside = _span(t, span[0], np.inf) if h.end >= grid.size else _span(t, span[0], grid[h.end])
        theta, gamma = contacts.path(arm, h.point, start, stop + 1)
        th = np.unwrap(theta)
        if held:  # keep theta on the turn nearest where the swing began
            th += 2 * np.pi * np.round((held[-1][1][-1] - th[0]) / (2 * np.pi))
        ga = gamma
        out_theta[inside] = np.interp(t[inside], span, th)
        out_gamma[inside] = np.interp(t[inside], span, ga)
        held.append((span, th, ga))
    for (a, (span_a, th_a, ga_a)), (b, (span_b, th_b, ga_b)) in zip(zip(mine, held), zip(mine[1:], held[1:])):
        t0, t1 = grid[a.end], grid[b.start - n_approach]
        swing = _span(t, t0, t1)
        for series, before, after in ((out_theta, th_a, th_b), (out_gamma, ga_a, ga_b)):
            start = _state(span_a[-_FIT - 1:], before[-_FIT - 1:], t0)
            end = _state(span_b[:_FIT + 1], after[:_FIT + 1], t1)
            series[swing] = _quintic(t[swing], t0, t1, start, end)


def _span(t: np.ndarray, start: float, stop: float) -> slice:
    """The samples of increasing times t from `start` to before `stop` as a slice: the mask
    (t >= start) & (t < stop), found by bisection, not by a pass over all samples for every hold (a ten-minute run:
    hundreds of holds, 600,000 samples)."""
    return slice(int(np.searchsorted(t, start)), int(np.searchsorted(t, stop)))


def _state(t: np.ndarray, y: np.ndarray, at: float) -> np.ndarray:
    """Value, rate and acceleration at time `at`, from a quadratic fitted to the samples."""
    c = np.polynomial.polynomial.polyfit(t - at, y, 2)
    return np.array([c[0], c[1], 2 * c[2]])


class _ScheduleGrid(NamedTuple):
    """The schedule on its grid (times `grid`, _STEP apart): the contact points (every arm's theta and gamma on
    each), the holds, and the steps of a swing's approach."""

    grid: np.ndarray
    contacts: FixedContacts | GeneralContacts
    holds: list[Hold]
    n_approach: int


def _rows(theta: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """Every arm's row of A (eqs. 34-35) on every candidate along the grid, (4, 3, N, 3): what `schedule` keeps
    far from rank loss."""
    return np.stack([np.stack([rsmg.jacobian_rows(i, theta[i, k], gamma[i, k])[0] for k in range(rsmg.CANDIDATES)])
                     for i in range(rsmg.ARMS)])


def _schedule_grips(task: Task, law: TimeLaw, hold: float, explain: bool = True,
                    speed_share: float = SPEED_SHARE) -> _ScheduleGrid:
    """The schedule grid, the contact points with every arm's IK on them along the rotor's motion there, and the
    grips scheduled on it. A motion general contacts cannot follow is refused with why (`_refusal`) unless not
    `explain`; `speed_share`: of the joints' speed limit that general contacts keep to."""
    grid = np.arange(int(np.ceil((law.duration + hold) / _STEP)) + 1) * _STEP
    rot = task.motion.orientation(law(grid, order=0)[0])
    n_approach = int(round(task.approach_time / _STEP))
    n_swing = max(1, int(round(task.swing_time / _STEP))) + n_approach
    if task.contacts == "fixed":
        theta, gamma = _gammas(rot)
        contacts = FixedContacts(gamma, _rows(theta, gamma), _band(task), theta)
    else:
        contacts = GeneralContacts(rot, _STEP, _band(task), Swing(n_swing, n_approach), speed_share)
    try:
        holds = _search(contacts, task, n_swing, n_approach)
    except _Stuck as stuck:
        if task.contacts == "fixed" or not explain:
            raise
        raise RunError(_refusal(task, law, hold, stuck, angular_speed(rot, _STEP))) from None
    return _ScheduleGrid(grid, contacts, holds, n_approach)


def _refusal(task: Task, law: TimeLaw, hold: float, stuck: _Stuck, speed: np.ndarray) -> str:
    """Why general contacts cannot follow the motion (`speed`: the rotor's on the grid, rad/s), in physical terms
    and numbers: where the search got furthest, which limit binds (`_cause`), and the shortest of a few longer
    durations over which the same motion is scheduled."""
    step = min(stuck.step, speed.size - 1)
    head = (f"round robin (general contacts): no schedule follows this motion, which turns the rotor at up to "
            f"{np.rad2deg(speed.max()):.0f} deg/s")
    if step > 0:  # where the search got furthest
        where = str(stuck).removeprefix("round robin: ").split("; no schedule")[0]
        head += f" ({where}, the rotor turning at {np.rad2deg(speed[step]):.0f} deg/s there)"
    for factor in _SLOWER:
        slower = TimeLaw(law.name, law.duration * factor, law.accel_fraction)
        try:
            _schedule_grips(task, slower, hold, explain=False)
        except RunError:
            continue
        peak = np.rad2deg(speed.max()) / factor  # the same path on a law stretched in time
        works = (f"the same motion over timing.duration = {slower.duration:.3g} s (up to {peak:.0f} deg/s) is "
                 "scheduled")
        break
    else:
        works = f"nor is the same motion over {_SLOWER[-1]:g} times the duration"
    return f"{head}; {_cause(task, law, hold)}; {works}"


def _cause(task: Task, law: TimeLaw, hold: float) -> str:
    """Which physical limit keeps general contacts from following the motion: the joints' speed (the motion is
    scheduled with it lifted: the speed then asked for), the time a re-grip takes (scheduled with swings and
    approaches twice as fast), or neither: the band and |det A| themselves."""
    try:
        sched = _schedule_grips(task, law, hold, explain=False, speed_share=np.inf)
    except RunError:
        pass
    else:
        qd = np.abs(np.gradient(_joint_paths(sched.grid, sched), _STEP, axis=0))
        row, joint = np.unravel_index(np.argmax(qd), qd.shape)
        if qd[row, joint] >= SPEED_SHARE * rsmg.QD_MAX[joint]:
            return (f"the joints' speed limit binds: with it lifted the motion is scheduled, asking "
                    f"{rsmg.JOINTS[joint]} for {qd[row, joint]:.1f} rad/s at t = {sched.grid[row]:.2f} s, more than "
                    f"the {SPEED_SHARE:.0%} of its {rsmg.QD_MAX[joint]:.1f} rad/s limit that holds and swings keep to")
    quick = task.model_copy(update={"swing_time": task.swing_time / 2, "approach_time": task.approach_time / 2})
    swing = task.swing_time + task.approach_time
    try:
        _schedule_grips(quick, law, hold, explain=False, speed_share=np.inf)
    except RunError:
        lo, hi = (np.rad2deg(b) for b in _band(task))
        return (f"neither the joints' speed nor the re-grips' time binds alone: no set of points keeps |det A| >= "
                f"det_a_min = {task.det_a_min:g} (eq. 46{_rising(task)}) and every gripping gamma in ({lo:.0f}, "
                f"{hi:.0f}) deg (eq. 45 less the margin) with one arm re-gripping at a time")
    return (f"re-gripping binds: the points the arms can hold leave the gamma band (eq. 45) before the arms, one at "
            f"a time and {swing:.2f} s a re-grip (swing_time + approach_time), have re-gripped in turn; at "
            f"{swing / 2:.2f} s a re-grip (and joints without a speed limit) it is scheduled")


def _joint_paths(t: np.ndarray, sched: _ScheduleGrid) -> np.ndarray:
    """q_ref (N, 8) on the control grid: every arm's theta, then every arm's gamma (_arm_path, into its columns)."""
    q_ref = pages.releasable((t.size, 2 * rsmg.ARMS))
    q_ref[:] = np.nan
    for arm in range(rsmg.ARMS):
        _arm_path(t, arm, sched.holds, sched.contacts, sched.grid, sched.n_approach, q_ref[:, arm],
                  q_ref[:, rsmg.ARMS + arm])
    return q_ref


def _switches(holds: list[Hold], grid: np.ndarray, contacts: FixedContacts | GeneralContacts) -> tuple[Switch, ...]:
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


def _engaged(t: np.ndarray, holds: list[Hold], grid: np.ndarray) -> np.ndarray:
    """Which arms grip (N, 4) at each control sample."""
    engaged = pages.releasable((t.size, rsmg.ARMS), bool)
    engaged[:] = False
    for h in holds:
        stop = grid[h.end] if h.end < grid.size else np.inf
        engaged[_span(t, grid[h.start], stop), h.arm] = True
    return engaged


def plan(scenario, robot, dt: float) -> JointTrajectory:
    """Schedule the grips and solve every arm at every control sample. The per-sample arrays are on pages of their
    own (pages.releasable), so that a long run with a recording stride hands their rows back as it passes them
    (sim.simulate's analyser: the ten-minute soak's plan is 117 MB)."""
    task = scenario.task
    law = scenario.timing.law_fn()
    sched = _schedule_grips(task, law, scenario.timing.hold)
    t = control_grid(law.duration, scenario.timing.hold, dt)
    # The search's caches (general contacts': up to 80 MB) go before the per-sample arrays come: the arms' paths
    # read their IK again, a few MB, the same numbers.
    sched.contacts.forget()
    heap.give_back(len(t))
    s = law(t, order=0)[0]
    q_ref = _joint_paths(t, sched)
    switches = _switches(sched.holds, sched.grid, sched.contacts)
    holds, grid, count = sched.holds, sched.grid, sched.contacts.count
    del sched  # the contacts and the rotor's axes on the schedule grid go before the references that remain come
    heap.give_back(len(t))
    engaged = _engaged(t, holds, grid)
    feedback = _RegripFeedback(task.motion, s, q_ref, holds, grid, dt, round(task.swing_time / dt)) \
        if task.regrip_feedback else None
    tool_ref, quat = _rotor_references(task.motion, s)
    info = {
        "method": "paper 001: round-robin re-gripping (section 4)",
        "design": {"alpha": rsmg.ALPHA, "beta": rsmg.BETA, "arms": rsmg.ARMS, "candidates": count},
        "contacts": task.contacts,
        "grips": len(holds) - rsmg.ARMS,
        "fewest_gripping": int(engaged.sum(axis=1).min()),
    }
    return JointTrajectory(t=t, s=s, q_ref=q_ref, qd_ref=_joint_rates(q_ref, dt), tool_ref=tool_ref, info=info,
                           switches=switches, series={"rotor_quat_ref": quat, "engaged_ref": engaged},
                           initial={"rotor": quat[0].tolist()}, feedback=feedback)


def _rotor_references(motion: Motion, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The marker's planned point (N, 3) and the rotor's planned orientation as quaternions (N, 4) at path
    parameters s, from the rotor's orientations a _BLOCK of samples at a time: all of a long run's at once (43 MB
    on the ten-minute soak's 600,000 samples), and the temporaries of their matrices and quaternions, would be
    planning's peak. Each row's numbers are those of the whole run's arrays."""
    tool_ref, quat = pages.releasable((len(s), 3)), pages.releasable((len(s), 4))
    for i in range(0, len(s), _BLOCK):
        rot = motion.orientation(s[i:i + _BLOCK])
        tool_ref[i:i + _BLOCK] = rot @ (_MARKER * 1.2 * rsmg.RADIUS)
        quat[i:i + _BLOCK] = matrix_to_quat(rot)
    return tool_ref, quat


def _joint_rates(q_ref: np.ndarray, dt: float) -> np.ndarray:
    """np.gradient(q_ref, dt, axis=0), as the grip feedback's revisions take it (trajectory.revise), _BLOCK rows at
    a time (trajectory.gradient_rows): the same numbers, without temporaries of three and a half times q_ref at
    once (on the soak's 600,000 samples, 135 MB).
    The spacing is the control period, not the differences of t: np.gradient takes a block whose t steps happen to
    be equal for uniform, and rounds differently there."""
    qd_ref = pages.releasable(q_ref.shape)
    for lo in range(0, len(q_ref), _BLOCK):
        qd_ref[lo:lo + _BLOCK] = gradient_rows(q_ref, lo, min(lo + _BLOCK, len(q_ref)), dt)
    return qd_ref


class _RegripFeedback:
    """At a grip during the run, the gripping arm's references from then until its release and over the swing
    after it, up to its next grip, re-solved for the point it really gripped (see the module's docstring). A change
    ends by the arm's next grip, whose own change takes over there: so no change touches the rows a later one
    reads, and the references revised in place (simbench.run) are those revised in copies."""

    def __init__(self, motion: Motion, s: np.ndarray, q_ref: np.ndarray, holds: list[Hold], grid: np.ndarray,
                 dt: float, n_swing: int):
        self.rot, self.q_ref, self.dt, self.n_swing = _Orientations(motion, s), q_ref, dt, n_swing
        rows = len(q_ref)

        def row(step: int) -> int:  # a schedule step's control row (the end of the reference past the schedule)
            return min(int(round(grid[step] / dt)), rows) if step < grid.size else rows

        # (arm, grip row) -> its release row and the arm's next grip row (the end of the reference if none)
        self.release: dict[tuple[int, int], tuple[int, int]] = {}
        for arm in {h.arm for h in holds}:
            own = sorted((h for h in holds if h.arm == arm), key=lambda h: h.start)
            for h, after in zip(own, own[1:] + [None]):
                if h.start > 0:
                    self.release[arm, row(h.start)] = row(h.end), rows if after is None else row(after.start)

    def __call__(self, switch: Switch, model, data, k: int):
        if not switch.active:
            return None
        arm = switch.detail["arm"] - 1
        k_release, k_next = self.release[arm, k]
        tip = data.site(f"em{arm + 1}_tip").xpos
        point = data.body("rotor").xmat.reshape(3, 3).T @ (tip / np.linalg.norm(tip))  # in the rotor's frame
        theta, gamma = rsmg.ik(arm, self.rot.rows(k, k_release) @ point)
        if not (np.isfinite(theta).all() and np.isfinite(gamma).all()):
            return None  # the point leaves the arm's reach before its release: keep the plan
        columns = [arm, rsmg.ARMS + arm]
        old = self.q_ref[k:k_release][:, columns]
        theta = np.unwrap(theta)
        theta += 2 * np.pi * np.round((old[0, 0] - theta[0]) / (2 * np.pi))
        change = np.stack([theta, gamma], axis=1) - old
        ease = _smoothstep(np.arange(k_release - k) * self.dt / _EASE)
        swing = self.q_ref[k_release:min(k_release + self.n_swing, k_next)][:, columns]
        out = _smoothstep(1 - np.arange(len(swing)) / max(self.n_swing, 1))
        q = np.concatenate([old + ease[:, None] * change, swing + out[:, None] * change[-1:]])
        return k, columns, q


class _Orientations:
    """The rotor's commanded orientations R (N, 3, 3) at the plan's path parameters s, found from the motion a
    block of _BLOCK rows at a time as the run's grips ask for them, not kept whole: all of them would hold 43 MB
    through the ten-minute soak's run. The grips come in time order, so the blocks before the latest asked for are
    dropped (and found again should an earlier row be asked for); each row is then found about once, though the
    four arms' holds overlap."""

    def __init__(self, motion: Motion, s: np.ndarray):
        self.motion, self.s = motion, s
        self.blocks: dict[int, np.ndarray] = {}

    def rows(self, a: int, b: int) -> np.ndarray:
        """R at rows a..b-1: the same numbers as motion.orientation(s)[a:b] (each row's own)."""
        first, last = a // _BLOCK, max(b - 1, a) // _BLOCK
        self.blocks = {i: block for i, block in self.blocks.items() if i >= first}
        for i in range(first, last + 1):
            if i not in self.blocks:
                self.blocks[i] = self.motion.orientation(self.s[i * _BLOCK:(i + 1) * _BLOCK])
        return np.concatenate([self.blocks[i][max(a - i * _BLOCK, 0):b - i * _BLOCK] for i in range(first, last + 1)])


def _smoothstep(u: np.ndarray) -> np.ndarray:
    """0 before u = 0, 1 after u = 1, the quintic time law between (zero rate and acceleration at both ends)."""
    return _QUINTIC(u, order=0)[0]



class RoundRobin(Planner):
    """Paper 001: RSMG rotor motion by round-robin re-gripping of four electromagnet arms."""

    name = "round_robin"
    description = "paper 001: RSMG rotor motion by round-robin re-gripping of four electromagnet arms"
    task = Task
    robots = ("rsmg",)
    # The schedule's search with general contacts: the ten-minute soak's tumble plans in 14 s, 23 us a sample in
    # all (2026-11-23), of which budget.py's _SAMPLE_SECONDS (planning and analysing) covers 10; three_turns takes
    # 2 us a sample.
    seconds_per_sample = 13e-6

    def plan(self, scenario, robot, dt: float) -> JointTrajectory:
        return plan(scenario, robot, dt)


PLANNER = RoundRobin()
