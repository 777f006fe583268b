"""Where the RSMG's arms grip the rotor (paper 001, section 4): the round robin's candidate contact points.

`FixedContacts` is the paper's scheme: three points a arm (a, b, c, Fig. 10; simbench puts them 120 deg apart,
rsmg.POINTS), taken in round-robin order. `GeneralContacts` (`contacts: general`) offers every point of a dense
Fibonacci sphere, ranked at each re-grip by how long it keeps gamma inside eq. 45's band and how firmly (|det A|,
eqs. 36-39, 46) the holding arms then hold the rotor; it also keeps joint speeds under SPEED_SHARE of their limit.
Its arrays are `Lazy` (planners.rsmg_lazy), computed as the search reads them, so planning grows with the motion's
length, not its square.

The band in gamma is a band in the angle d between the EM axis and the arm's axis (eqs. 10-11): cos d =
cos ALPHA cos BETA + sin ALPHA sin BETA cos gamma. In the rotor's frame the arm's axis is a_i(t) = R(t)^T u_i, so a
point is usable while its angle to a_i(t) stays in the band: one matrix product ranks the whole dense set (`dwell`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from simbench.maths.vectors import cross
from simbench.planners.rsmg_lazy import CACHE_FLOATS, BoundedCache, Lazy, LazyExit, first_false, first_out
from simbench.robots import rsmg

_DENSE = 400  # points of the dense candidate set: neighbours about 10 deg apart
_SHORTLIST = 4  # points tried a re-grip, best first
_APART = np.deg2rad(25.0)  # the shortlist's points at least this far apart from one another
SPEED_SHARE = 0.9  # a hold or a swing asks a joint for at most this share of its speed limit
_HORIZON = 8  # swings (with their approach): the dwell beyond which a point is as good as any longer one
_FIRM_WEIGHT = 2.0  # the firmness's weight in a point's score against its dwell (both about 0-1)
_QUINTIC_SAMPLES = 41  # where a swing's quintic's speed is checked
FIRM_SPEED = np.deg2rad(150.0)  # rad/s
FIRM_CAP = 0.5
_FIRM_STRIDE = 4  # schedule steps between the samples a point's firmness is ranked on
_BLOCK_STEPS = 256  # schedule steps in a cached block of the dense set's band test
_BLOCK_SAMPLES = 64  # firmness samples in a cached block of the dense set's rows of A


def fibonacci_sphere(n: int) -> np.ndarray:
    """n nearly evenly spread unit vectors (n, 3): the golden-angle spiral."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = np.pi * (1.0 + np.sqrt(5.0)) * k
    r = np.sqrt(1.0 - z**2)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def cos_d(gamma: np.ndarray) -> np.ndarray:
    """cos of the angle between the EM axis and the arm's axis at gamma (spherical triangle u_i, w_i, v_i)."""
    return np.cos(rsmg.ALPHA) * np.cos(rsmg.BETA) + np.sin(rsmg.ALPHA) * np.sin(rsmg.BETA) * np.cos(gamma)


def angular_speed(rot: np.ndarray, step: float) -> np.ndarray:
    """The rotor's angular speed (N,) in rad/s along orientations (N, 3, 3) sampled `step` s apart."""
    rel = np.einsum("nji,njk->nik", rot[:-1], rot[1:])  # R_k^T R_k+1
    cos = np.clip((np.trace(rel, axis1=1, axis2=2) - 1) / 2, -1.0, 1.0)
    speed = np.arccos(cos) / step
    return np.concatenate([speed, speed[-1:]]) if speed.size else np.zeros(len(rot))


class FixedContacts:
    """The paper's scheme, from every arm's gamma (4, 3, N) and rows of A (4, 3, N, 3) on each point (and theta)."""

    def __init__(self, gamma: np.ndarray, rows: np.ndarray, band: tuple[float, float],
                 theta: np.ndarray | None = None):
        self.gamma, self._rows, self.theta = gamma, rows, theta
        self._next_bad = first_false((gamma > band[0]) & (gamma < band[1]))  # NaN (out of reach) is never inside
        self.count = gamma.shape[1]

    @property
    def n(self) -> int:
        """Steps of the grid."""
        return self.gamma.shape[-1]

    def next_bad(self, arm: int, k: int) -> np.ndarray:
        return self._next_bad[arm, k]

    def rows(self, arm: int, k: int) -> np.ndarray:
        return self._rows[arm, k]

    def path(self, arm: int, k: int, first: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        """theta and gamma of the arm holding point k at steps first to stop."""
        return self.theta[arm, k, first:stop], self.gamma[arm, k, first:stop]

    def point(self, arm: int, k: int) -> np.ndarray:
        return rsmg.POINTS[arm, k]

    def label(self, arm: int, k: int) -> str:
        return "abc"[k]

    def forget(self) -> None:
        """Nothing is cached."""

    def initial_points(self, arm: int) -> list[int]:
        """The points the arm may grip at t = 0: those inside the band then."""
        return [k for k in range(self.count) if self._next_bad[arm, k, 0] > 0]

    def next_points(self, arm: int, held: dict[int, int], grip: int) -> list[int]:
        """The next point in round-robin order, then the one after."""
        return [(held[arm] + 1) % self.count, (held[arm] + 2) % self.count]

    def swing_fits(self, arm: int, k_from: int, k_to: int, release: np.ndarray) -> np.ndarray:
        """Any: the paper's scheme does not limit a swing (the run checks its speeds)."""
        return np.ones(release.shape, bool)

    def floor(self, det_a_min: float) -> float:
        """The floor on the holding arms' type A measure: det_a_min throughout."""
        return det_a_min


class Swing(NamedTuple):
    """A swing on the schedule grid: its steps in all, the last `approach` following the next point."""

    steps: int
    approach: int


class GeneralContacts:
    """Any point of a dense set the arm reaches. `rot` (N, 3, 3): commanded orientations `step` s apart."""

    def __init__(self, rot: np.ndarray, step: float, band: tuple[float, float], swing: Swing,
                 speed_share: float = SPEED_SHARE):
        self.rot, self.step, self.band, self.swing = rot, step, band, swing
        self.dense = fibonacci_sphere(_DENSE)
        self.count = _DENSE
        self.axes = np.einsum("nji,aj->ani", rot, rsmg.U)  # a_i(t) = R(t)^T u_i, (4, N, 3)
        self.cos_band = (cos_d(band[1]), cos_d(band[0]))  # cos d falls as gamma rises
        self.qd_limit = speed_share * rsmg.QD_MAX[0]
        self.horizon = _HORIZON * swing.steps
        self._cache = BoundedCache(CACHE_FLOATS)

    @property
    def n(self) -> int:
        """Steps of the grid."""
        return len(self.rot)

    def forget(self) -> None:
        """Drop every cached array once the plan is found: the Lazy blocks refer back to this object, so the cache
        would otherwise live on as cyclic garbage."""
        self._cache.clear()

    def lazy(self, make) -> Lazy:
        """A Lazy array along this grid, its blocks in this object's cache."""
        return Lazy(self.n, make, self._cache)

    def _ik(self, arm: int, k: int, steps) -> np.ndarray:
        """theta and gamma (steps, 2) of the arm holding point k at grid steps `steps` (eqs. 12-23)."""
        return np.stack(rsmg.ik(arm, self.rot[steps] @ self.dense[k]), axis=1)

    def angles(self, arm: int, k: int) -> Lazy:
        """theta and gamma (N, 2) of the arm holding point k along the grid, computed as read."""
        def make(first: int, stop: int) -> np.ndarray:
            return self._ik(arm, k, slice(first, stop))
        return self._cache.fetch(("angles", arm, k), lambda: self.lazy(make))

    def _around(self, arm: int, k: int, first: int, stop: int) -> np.ndarray:
        """angles(arm, k) at steps first - 1 to stop + 1 within the grid; the two edge steps are solved together,
        not with their blocks (saving a third of the IK), even where one is unwanted: NumPy rounds a single row's
        product unlike a longer one's."""
        edges = self._ik(arm, k, [max(first - 1, 0), min(stop, self.n - 1)])
        return np.concatenate([edges[:1]] * (first > 0) + [self.angles(arm, k)[first:stop]] +
                              [edges[1:]] * (stop < self.n))

    def path(self, arm: int, k: int, first: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        """theta and gamma of the arm holding point k at steps first to stop."""
        both = self.angles(arm, k)[first:stop]
        return both[:, 0], both[:, 1]

    def rows(self, arm: int, k: int) -> Lazy:
        """The arm's row of A holding point k (N, 3) (eqs. 34-35), computed as read."""
        def make(first: int, stop: int) -> np.ndarray:
            both = self.angles(arm, k)[first:stop]
            return rsmg.a_row(arm, both[:, 0], both[:, 1])
        return self._cache.fetch(("rows", arm, k), lambda: self.lazy(make))

    def next_bad(self, arm: int, k: int) -> LazyExit:
        """For each step, the first at or after it where holding point k puts gamma outside the band (eq. 45) or
        a joint over SPEED_SHARE of its speed limit."""
        def make(first: int, stop: int) -> np.ndarray:
            lo = max(first - 1, 0)  # a step either side for the rates at the ends
            both = self._around(arm, k, first, stop)
            theta, gamma = both[:, 0], both[:, 1]
            ok = (gamma > self.band[0]) & (gamma < self.band[1])
            if ok.any() and len(ok) > 1:
                speed = np.maximum(np.abs(np.gradient(np.unwrap(np.nan_to_num(theta)), self.step)),
                                   np.abs(np.gradient(np.nan_to_num(gamma), self.step)))
                ok &= speed < self.qd_limit
            return ok[first - lo:first - lo + stop - first]
        return self._cache.fetch(("next_bad", arm, k), lambda: LazyExit(self.lazy(make)))

    def point(self, arm: int, k: int) -> np.ndarray:
        return self.dense[k]

    def floor(self, det_a_min: float) -> np.ndarray:
        """The floor on the holding arms' |det A| at each step (N,): det_a_min up to FIRM_SPEED, then in proportion
        to the rotor's speed, up to FIRM_CAP. The servos' lag grows with speed and reaches the rotor through A^-1
        (eq. 33), so a faster rotor must be held more firmly."""
        speed = angular_speed(self.rot, self.step)
        return np.maximum(det_a_min, np.minimum(FIRM_CAP, det_a_min * speed / FIRM_SPEED))

    def label(self, arm: int, k: int) -> str:
        return f"p{k}"

    def _blocks(self, name: str, arm: int, lo: int, hi: int, size: int, make, points=slice(None)) -> np.ndarray:
        """Items lo to hi along axis 1 of a per-arm array over the dense set's `points`, from cached blocks of `size`
        items that make(arm, first, stop) computes."""
        parts = [self._cache.fetch((name, arm, b), lambda b=b: make(arm, b * size, (b + 1) * size))[points]
                 for b in range(lo // size, (hi - 1) // size + 1)]
        whole = np.concatenate(parts, axis=1) if len(parts) > 1 else parts[0]
        return whole[:, lo - (lo // size) * size:hi - (lo // size) * size]

    def _inside(self, arm: int, first: int, stop: int) -> np.ndarray:
        """Whether each dense point is inside the arm's band at steps first to stop (K, steps)."""
        c = self.dense @ self.axes[arm, first:min(stop, self.n)].T
        return (c > self.cos_band[0]) & (c < self.cos_band[1])

    def _dense_rows(self, arm: int, first: int, stop: int) -> np.ndarray:
        """Every dense point's row of A for the arm (K, samples, 3) at firmness samples first to stop."""
        steps = np.arange(first, stop) * _FIRM_STRIDE
        steps = steps[steps < self.n]
        return row_of_a(arm, np.einsum("nij,kj->kni", self.rot[steps], self.dense))

    def dwell(self, arm: int, start: int) -> np.ndarray:
        """For every dense point (K,), the first step from `start` (up to the horizon) where it leaves the band."""
        def make():
            stop = min(start + self.horizon, self.n)
            return start + first_out(self._blocks("dense_inside", arm, start, stop, _BLOCK_STEPS, self._inside))
        return self._cache.fetch(("dwell", arm, start), make)

    def initial_points(self, arm: int) -> list[int]:
        """The points to try at t = 0: the longest inside the band, a shortlist far apart."""
        exits = self.dwell(arm, 0)
        inside = np.flatnonzero(exits > 0)
        return _spread(self.dense, inside, exits[inside].astype(float))

    def next_points(self, arm: int, held: dict[int, int], grip: int) -> list[int]:
        """The points for `arm` to grip at step `grip`, best first: inside the band from the approach to a swing
        after the grip, scored by dwell (0-1, up to the horizon) and firmness (eq. 46, `_firmness`)."""
        start = max(grip - self.swing.approach, 0)
        until = self.dwell(arm, start)
        usable = np.flatnonzero((until > grip + self.swing.steps) | (until >= self.n))
        if not usable.size:
            return []
        stop = np.minimum(until[usable], min(grip + self.horizon, self.n))
        dwell = (stop - grip) / max(min(self.horizon, self.n - grip), 1)
        firm = self._firmness(arm, held, usable, grip, stop)
        return _spread(self.dense, usable, dwell + _FIRM_WEIGHT * np.minimum(firm, 1.0))

    def _firmness(self, arm: int, held: dict[int, int], usable: np.ndarray, grip: int, stop: np.ndarray) -> np.ndarray:
        """For each usable point, the least |det A| of it with each two of the other arms' rows from the grip until
        it leaves (`stop`), as a share of sin(BETA)^3, the largest it can be."""
        first, last = grip // _FIRM_STRIDE, (int(stop.max()) - 1) // _FIRM_STRIDE + 1
        row = self._blocks("dense_rows", arm, first, last, _BLOCK_SAMPLES, self._dense_rows, usable)  # (P, J, 3)
        steps = np.arange(first, last) * _FIRM_STRIDE
        others = [self.rows(a, k)[steps] for a, k in sorted(held.items()) if a != arm]
        least = np.full(row.shape[:2], np.inf)
        for i in range(len(others)):
            for j in range(i + 1, len(others)):
                least = np.minimum(least, np.abs(np.einsum("kni,ni->kn", row, cross(others[i], others[j]))))
        held_then = steps[None, :] < stop[:, None]  # each point's samples before it leaves
        least = np.where(held_then, np.nan_to_num(least, nan=0.0), np.inf).min(axis=1)
        return least / np.sin(rsmg.BETA) ** 3

    def swing_fits(self, arm: int, k_from: int, k_to: int, release: np.ndarray) -> np.ndarray:
        """Whether the swing's quintic from point k_from, let go at each step of `release`, to point k_to keeps both
        joints under SPEED_SHARE of their limit."""
        release = np.asarray(release)
        end = release + self.swing.steps - self.swing.approach
        ok = (release >= 1) & (end + 1 < self.n)
        fits = np.zeros(release.shape, bool)
        if not ok.any():
            return fits
        release, end = release[ok], end[ok]
        h = (self.swing.steps - self.swing.approach) * self.step
        peak = np.zeros(release.shape)
        # theta and gamma a step before, at and a step after the release and the swing's end, (3, M, 2): one read
        before = self.angles(arm, k_from)[np.stack([release - 1, release, release + 1])]
        after = self.angles(arm, k_to)[np.stack([end - 1, end, end + 1])]
        for joint in range(2):
            a, b = before[..., joint], after[..., joint]
            a0, b0 = a[1], b[1]
            if joint == 0:  # theta goes the shorter way round (the plan keeps it on the nearest turn)
                b0 = a0 + np.angle(np.exp(1j * (b0 - a0)))
            start = np.stack([a0, *_rates(a, self.step, joint == 0)], axis=1)
            finish = np.stack([b0, *_rates(b, self.step, joint == 0)], axis=1)
            peak = np.maximum(peak, _quintic_peak(start, finish, h))
        fits[ok] = np.nan_to_num(peak, nan=np.inf) < self.qd_limit
        return fits


def row_of_a(arm: int, v: np.ndarray) -> np.ndarray:
    """The arm's row of A, w_i x v_i (eq. 34), for EM axes v (..., 3), in closed form: w = a u + b v + c (u x v) at
    ALPHA from u and BETA from v (eqs. 10-11), c > 0 as rsmg.ik keeps; NaN out of reach. No IK needed."""
    u = rsmg.U[arm]
    cuv = v @ u
    den = 1.0 - cuv**2
    with np.errstate(invalid="ignore", divide="ignore"):
        a = (np.cos(rsmg.ALPHA) - np.cos(rsmg.BETA) * cuv) / den
        b = (np.cos(rsmg.BETA) - np.cos(rsmg.ALPHA) * cuv) / den
        c2 = (1.0 - a**2 - b**2 - 2 * a * b * cuv) / den
        c = np.where(c2 >= 0, np.sqrt(np.abs(c2)), np.nan)
    normal = cross(u, v)
    w = np.stack([a * u[j] + b * v[..., j] + c * normal[..., j] for j in range(3)], axis=-1)
    return cross(w, v)


def _rates(y: np.ndarray, step: float, angle: bool) -> tuple[np.ndarray, np.ndarray]:
    """Rate and acceleration (M,) at the middle of samples y (3, M) a step apart (central differences)."""
    before, here, after = y
    if angle:
        before = here - np.angle(np.exp(1j * (here - before)))
        after = here + np.angle(np.exp(1j * (after - here)))
    return (after - before) / (2 * step), (after - 2 * here + before) / step**2


def quintic(h: float, ends: np.ndarray) -> np.ndarray:
    """Coefficients (6, ...) of the quintics over [0, h] meeting (value, rate, acceleration) ends[:3] at 0 and
    ends[3:] at h."""
    a = np.array([[1, 0, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0], [0, 0, 2, 0, 0, 0],
                  [1, h, h**2, h**3, h**4, h**5], [0, 1, 2 * h, 3 * h**2, 4 * h**3, 5 * h**4],
                  [0, 0, 2, 6 * h, 12 * h**2, 20 * h**3]], float)
    return np.linalg.solve(a, ends)


def _quintic_peak(start: np.ndarray, end: np.ndarray, h: float) -> np.ndarray:
    """The largest |rate| (M,) of quintics over [0, h] from (value, rate, acceleration) start (M, 3) to end."""
    coef = quintic(h, np.concatenate([start, end], axis=1).T)  # (6, M)
    t = np.linspace(0.0, h, _QUINTIC_SAMPLES)
    powers = np.stack([np.zeros_like(t)] + [(i + 1) * t**i for i in range(5)])  # d/dt of t^0..t^5
    return np.abs(coef.T @ powers).max(axis=1)


def _spread(points: np.ndarray, candidates: np.ndarray, score: np.ndarray) -> list[int]:
    """Up to _SHORTLIST candidates (indices into points), best score first, each _APART from those before."""
    picked: list[int] = []
    for i in np.argsort(-score, kind="stable"):
        k = int(candidates[i])
        if all(points[k] @ points[j] < np.cos(_APART) for j in picked):
            picked.append(k)
            if len(picked) == _SHORTLIST:
                break
    return picked


def random_motion(rng: np.random.Generator | np.random.RandomState, contacts: str = "general") -> dict:
    """One untuned random `round_robin` motion (SI) as random_motions draws it: its `task` and `timing` sections,
    a turn about a random axis or a tumble (spin and precession) with even odds, over 6 to 30 s."""
    def axis() -> list[float]:
        v = rng.normal(size=3)
        return (v / np.linalg.norm(v)).tolist()

    def turns(lo: float, hi: float) -> float:
        return float(rng.choice([-1.0, 1.0]) * rng.uniform(lo, hi))

    if rng.random() < 0.5:
        motion = {"kind": "turns", "axis": axis(), "turns": turns(1, 5)}
    else:
        motion = {"kind": "tumble", "spin_axis": axis(), "spin_turns": turns(1, 3), "precession_axis": axis(),
                  "precession_turns": turns(0.5, 2)}
    return {"task": {"motion": motion, "contacts": contacts},
            "timing": {"law": "trapezoidal", "accel_fraction": 0.1, "duration": round(rng.uniform(6, 30), 2),
                       "hold": 0.5}}


def random_motions(n: int, seed: int, contacts: str = "general") -> list[dict]:
    """n untuned random `round_robin` scenario documents (SI) for tests and benchmarks (random_motion)."""
    rng = np.random.default_rng(seed)
    return [{"name": f"rsmg_motion_{seed}_{i}", "robot": "rsmg", "planner": "round_robin",
             **random_motion(rng, contacts)} for i in range(n)]
