"""Metrics and events from a Recording: how well the tool followed the plan, and what it came near.

Tracking: joint errors; the tool's distance from the planned path (the polyline of the planned tool points),
its lag along the path, and its error against the time-indexed reference, as per-sample series; the metrics
(simbench.api.Metric, the shipped `tracking` among them: simbench.tracking) reduce them to figures. Events
(simbench.api.Event):
  singularity_events  spans where the recorded configuration lies near one of the robot's singular sets;
  limit_events        `joint_limit` (the plan asks for a value beyond a joint's range), `at_limit` (the joint
                      sits at a limit), `reference_jump` (the plan steps farther in one sample than the joint's
                      speed limit allows in ten: a discontinuity), `velocity_limit` (the plan is faster than
                      the joint can go) and `actuator_saturation` (a joint's actuator at its force bound: the
                      motor cannot give what tracking the plan takes).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from simbench import windowed
from simbench.api import Event, Metric
from simbench.registry import metrics_for
from simbench.robots import Robot, Tolerance
from simbench.sim import Recording
from simbench.trajectory import JointTrajectory, gradient_rows, joined
from simbench.windowed import Departure, Rises, Spans, spans
from simbench.windowed import norms as _norms

if TYPE_CHECKING:
    from simbench.scenario import Scenario

_JUMP_FACTOR = 10.0
_BACK_ON_PATH = 1e-3  # m: after a jump, the tool counts as back on the path within this distance
_BATCH = 1 << 15  # points _deviation searches at once, each with a few (point, stretch) pairs a level
_LEAF = 2  # the capsule tree's smallest stretches: 2^_LEAF segments, searched one by one (a quarter of the memory)


def path_deviation(path: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance of each point from the polyline `path` (see `_deviation` for how it is searched)."""
    n = len(points)
    return _deviation(np.asarray(path, float), np.asarray(points, float), [(0, n, 0, len(path) - 1)])


def deviation_near_reference(path: np.ndarray, points: np.ndarray, window: int, start: int = 0) -> np.ndarray:
    """Distance of each points[k], the tool at path sample start + k, from the stretch of the sampled path within
    about `window` samples of its own (from `window` to twice that: the path is cut into blocks of `window`
    samples, each searched with its neighbours). A path that comes back to the same place later, a rotor turning
    many times say, then does not hide a point that is off its own stretch, and the search stays as cheap as on a
    path that never returns.
    The blocks are searched a group at a time (windowed.group: whole blocks, at most windowed.GROUP samples, or
    windowed.LONG in a run of more than windowed.WINDOW), each group on the stretch of path its blocks need, so
    that the search's memory does not grow with the run (a tree of the whole ten-minute soak's path and its search
    took 180 MB); every shipped scenario is one group. Blocks and groups are counted from the path's first sample,
    so points given a group at a time (`start`, the analysis' windows) are searched as the run's points all at
    once. Points and path are (N, 3)."""
    path, points = np.asarray(path, float), np.asarray(points, float)
    n = len(points)
    if start + n > len(path):
        raise ValueError(f"deviation_near_reference: {n} points from sample {start} of a path of {len(path)}")
    per = windowed.group(window, len(path)) // window  # blocks a group
    groups: dict[int, list[tuple[int, int, int, int]]] = {}
    for first in range(start - start % window, start + n, window):  # each block's first sample
        groups.setdefault(first // window // per, []).append(
            (max(first, start) - start, min(first + window, start + n) - start, path_from(first, window),
             min(first + 2 * window, len(path)) - 1))
    out = np.empty(n)
    for group in groups.values():
        a0, b0, lo, hi = group[0][0], group[-1][1], group[0][2], group[-1][3]  # block ranges ascend with start
        shifted = [(a - a0, b - a0, first - lo, last - lo) for a, b, first, last in group]
        out[a0:b0] = _deviation(path[lo:hi + 1], points[a0:b0], shifted, planned_at=start + a0 - lo)
    return out


def path_from(start: int, window: int) -> int:
    """The first path sample that `deviation_near_reference` reads for the points from sample `start` on: the
    first of the block before theirs."""
    return max(start - start % window - window, 0)


def _deviation(path: np.ndarray, points: np.ndarray, blocks: list[tuple[int, int, int, int]],
               planned_at: int | None = None) -> np.ndarray:
    """Distance of points[a:b] from the polyline path[first:last + 1], for each block (a, b, first, last).

    Exact to 1e-13 of the coordinates' scale, near the path or far from it: a branch and bound over a tree of
    the path's stretches of 2^l segments (`_capsules`), each bounded by a capsule about its chord, so that each
    point examines a few stretches a level (`_nearest`). `planned_at`: points[k] is planned at path[k + planned_at],
    and the segment there gives the first bound. Repeated samples are dropped first: the polyline is the same.

    Own code, not scipy's cKDTree with an exact refinement: a k-d tree bounds a piece of path by a ball about its
    middle, which a point far from a path curving about it, or near a path crawling into motion (hundreds of short
    segments in one place), cannot tell apart, where a capsule about a chord can: it took 1.5 to 11 times as long on
    the shipped scenarios (BENCHMARKS.md, issue 34).
    """
    if len(path) == 0:
        raise ValueError("path_deviation needs a path of at least one point")
    moved = path[1:] != path[:-1]  # repeated samples add nothing (x, y and z apart, as in `_norms`)
    keep = np.concatenate([[True], moved[:, 0] | moved[:, 1] | moved[:, 2]])
    index = np.cumsum(keep) - 1  # each sample's vertex among those kept
    vertices = path[keep]
    planned = None  # each point's planned vertex, where known
    if planned_at is not None and len(points) + planned_at <= len(path):
        planned = index[planned_at:planned_at + len(points)]
    first = np.empty(len(points), int)
    last = np.empty(len(points), int)
    for a, b, lo, hi in blocks:
        first[a:b], last[a:b] = index[lo], index[hi]
    out = np.empty(len(points))
    single = first == last
    out[single] = _norms(points[single] - vertices[first[single]])
    todo = np.flatnonzero(~single)
    if todo.size:
        tree = _capsules(vertices)
        for part in np.array_split(todo, -(-todo.size // _BATCH)):  # memory bounded on a long run
            guess = first[part] if planned is None else np.clip(planned[part], first[part], last[part] - 1)
            out[part] = _nearest(tree, points[part], first[part], last[part] - 1, guess)
    return out


def _distance(ax, ay, az, bx, by, bz, px, py, pz) -> np.ndarray:
    """Distance of each point p from the segment a -> b (the point a where b = a), coordinates as separate
    arrays."""
    abx, aby, abz = bx - ax, by - ay, bz - az
    rx, ry, rz = px - ax, py - ay, pz - az
    length2 = abx * abx + aby * aby + abz * abz
    u = rx * abx + ry * aby + rz * abz
    np.divide(u, length2, out=u, where=length2 > 0)
    u[length2 <= 0] = 0.0
    np.clip(u, 0.0, 1.0, out=u)
    ex, ey, ez = rx - u * abx, ry - u * aby, rz - u * abz
    return np.sqrt(ex * ex + ey * ey + ez * ez)


@dataclass(frozen=True)
class _Capsules:
    """A polyline's vertices (padded to 2^depth segments with copies of the last; x, y and z apart) and, for
    every level l >= _LEAF, its stretches of 2^l segments each as a capsule: the chord a -> a + ab from its first
    vertex to its last, and a radius r within which every point of the stretch lies of the chord. Level l's rows:
    ax, ay, az, abx, aby, abz, 1 / |ab|^2 (0 for a stretch that closes) and r."""

    xyz: tuple[np.ndarray, np.ndarray, np.ndarray]
    levels: list[np.ndarray | None]  # None below _LEAF
    scale: float  # the largest coordinate


def _capsules(vertices: np.ndarray) -> _Capsules:
    """The capsule tree of a polyline of at least two vertices. A stretch's radius is its halves' larger plus the
    distance of its middle vertex from its chord: its halves' chords lie within that of its own chord (a
    segment's distance from a chord is greatest at one of its ends)."""
    segments = len(vertices) - 1
    depth = int(np.ceil(np.log2(segments))) if segments > 1 else 0
    size = 1 << depth
    x, y, z = (np.concatenate([c, np.repeat(c[-1], size - segments)]) for c in vertices.T)  # padded, apart
    levels: list[np.ndarray | None] = [None] * _LEAF  # below _LEAF, stretches are searched segment by segment
    radius = np.zeros(size)
    for level in range(1, depth + 1):
        step = 1 << level
        ax, ay, az = x[0:size:step], y[0:size:step], z[0:size:step]
        abx, aby, abz = x[step::step] - ax, y[step::step] - ay, z[step::step] - az
        length2 = abx * abx + aby * aby + abz * abz
        inverse = np.zeros_like(length2)
        np.divide(1.0, length2, out=inverse, where=length2 > 0)
        mx, my, mz = x[step // 2:size:step] - ax, y[step // 2:size:step] - ay, z[step // 2:size:step] - az
        u = np.clip((mx * abx + my * aby + mz * abz) * inverse, 0.0, 1.0)
        mx, my, mz = mx - u * abx, my - u * aby, mz - u * abz
        radius = np.maximum(radius[0::2], radius[1::2]) + np.sqrt(mx * mx + my * my + mz * mz)
        if level >= _LEAF:
            levels.append(np.array([ax, ay, az, abx, aby, abz, inverse, radius]))
    return _Capsules((x, y, z), levels, float(np.abs(vertices).max()))


def _cover(first: int, last: int) -> list[tuple[int, int]]:
    """The stretches (level, index) of a capsule tree that together are segments first..last, at most two a
    level (a segment tree's query)."""
    out, lo, hi, level = [], first, last + 1, 0
    while lo < hi:
        if lo & 1:
            out.append((level, lo))
            lo += 1
        if hi & 1:
            hi -= 1
            out.append((level, hi))
        lo, hi, level = lo >> 1, hi >> 1, level + 1
    return out


def _nearest(tree: _Capsules, points: np.ndarray, first: np.ndarray, last: np.ndarray,
             guess: np.ndarray) -> np.ndarray:
    """Each point's distance from segments first..last of the tree's polyline (the same for runs of points), to
    1e-13 of the scale of the path's and the point's coordinates (1e-12 m within 9 m of the origin).

    Branch and bound, level by level from the largest stretches that make up a point's range (`_cover`) down to
    stretches of 2^_LEAF segments, whose segments are then measured one by one: a stretch's capsule bounds its
    distance from a point from below (the distance from its chord less its radius) and from above (plus the radius:
    every point of the chord lies within the radius of the stretch). The first upper bound is the distance from
    segment `guess` or the one before it. A stretch that cannot come nearer than the least upper bound so far by
    the tolerance is dropped, the others split in two.
    """
    vx, vy, vz = tree.xyz
    px, py, pz = (np.ascontiguousarray(c) for c in points.T)
    count = len(points)
    tol = 1e-13 * (1.0 + np.maximum(tree.scale, np.abs(points).max(axis=1)))  # each point's: 25 times rounding's

    def exact(k: np.ndarray, seg: np.ndarray) -> np.ndarray:
        """Each point k's distance from its segment seg, _BATCH pairs at a time: the leaves' pairs, some ten a
        point, at once would take a dozen temporaries of them (35 MB more a batch on the ten-minute soak)."""
        out = np.empty(len(k))
        for a in range(0, len(k), _BATCH):
            i, s = k[a:a + _BATCH], seg[a:a + _BATCH]
            out[a:a + _BATCH] = _distance(vx[s], vy[s], vz[s], vx[s + 1], vy[s + 1], vz[s + 1], px[i], py[i], pz[i])
        return out

    everyone = np.arange(count)
    before = np.maximum(guess - 1, first)
    bound = np.minimum(exact(everyone, guess), exact(everyone, before))
    heads = np.flatnonzero(np.concatenate(([True], (first[1:] != first[:-1]) | (last[1:] != last[:-1]))))
    fresh: dict[int, list[tuple[int, int, int]]] = {}
    for a, b in zip(heads.tolist(), np.append(heads[1:], count).tolist()):
        for level, node in _cover(int(first[a]), int(last[a])):
            fresh.setdefault(level, []).append((a, b, node))
    leaves = [(np.arange(a, b).repeat(1 << level), np.tile(np.arange(node << level, (node + 1) << level), b - a))
              for level in range(_LEAF) for a, b, node in fresh.get(level, ())]  # small stretches at the ends
    k = j = np.empty(0, int)
    for level in range(len(tree.levels) - 1, _LEAF - 1, -1):
        if level in fresh:
            k = np.concatenate([k, *(np.arange(a, b) for a, b, _ in fresh[level])])
            j = np.concatenate([j, *(np.full(b - a, node) for a, b, node in fresh[level])])
        if k.size == 0:
            continue
        table = tree.levels[level]
        assert table is not None
        ax, ay, az, abx, aby, abz, inverse, radius = table.take(j, axis=1)
        rx, ry, rz = px[k] - ax, py[k] - ay, pz[k] - az
        u = (rx * abx + ry * aby + rz * abz) * inverse
        np.clip(u, 0.0, 1.0, out=u)
        rx -= u * abx
        ry -= u * aby
        rz -= u * abz
        d = np.sqrt(rx * rx + ry * ry + rz * rz)
        np.minimum.at(bound, k, d + radius)
        keep = d - radius < bound[k] - tol[k]
        k, j = k[keep], 2 * j[keep]
        k, j = np.concatenate([k, k]), np.concatenate([j, j + 1])
    span = 1 << (_LEAF - 1)  # the children of the last level's stretches, segment by segment
    leaves.append((np.repeat(k, span), (j[:, None] * span + np.arange(span)).ravel()))
    k, seg = (np.concatenate(parts) for parts in zip(*leaves))
    if k.size:
        np.minimum.at(bound, k, exact(k, seg))
    return bound


def along_path(points: np.ndarray) -> np.ndarray:
    """Unit tangent (N, 3) of a sampled path; where it rests, the direction it last moved in (or first will)."""
    return _Tangents(points).rows(0, len(points))


class _Tangents:
    """`along_path` of a planned path, a window of rows at a time: each row's step from the rows either side of
    it (np.gradient's, the same numbers as over the whole path), and where the path rests the direction it last
    moved in, carried from the windows before, or the one it first will, found ahead."""

    def __init__(self, points: np.ndarray):
        self.points = points
        self.floor = 1e-12 * max(1.0, max(float(points.max(initial=0.0)), -float(points.min(initial=0.0))))
        self.last: np.ndarray | None = None  # the unit step where the path last moved, in the windows before
        self.first: np.ndarray | None = None  # where it first moves, once looked for

    def _steps(self, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The steps of rows lo..hi-1, their lengths, and whether the path moves there."""
        step = gradient_rows(self.points, lo, hi)
        norm = _norms(step)
        return step, norm, norm > self.floor

    def rows(self, lo: int, hi: int) -> np.ndarray:
        """The unit tangents at rows lo..hi-1 (windows asked for in order)."""
        step, norm, moving = self._steps(lo, hi)
        index = np.maximum.accumulate(np.where(moving, np.arange(len(moving)), -1))
        before = self.last
        if index[-1] >= 0:
            self.last = step[index[-1]] / norm[index[-1]]
        if index[0] >= 0:  # the window moves at its first row: every row has a step of its own or before it
            return step[index] / norm[index][:, None]
        seen = index >= 0  # the rows before the window's first move take the last before it, or the first after
        out = np.empty_like(step)
        out[seen] = step[index[seen]] / norm[index[seen]][:, None]
        out[~seen] = before if before is not None else self._first_move(lo)
        return out

    def _first_move(self, lo: int) -> np.ndarray:
        """The unit step where the path first moves at or after row lo (no move before it), zero if it never
        does."""
        if self.first is None:
            self.first = np.zeros(3)
            for a in range(lo, len(self.points), windowed.LONG):
                step, norm, moving = self._steps(a, min(a + windowed.LONG, len(self.points)))
                if moving.any():
                    k = int(np.argmax(moving))
                    self.first = step[k] / norm[k]
                    break
        return self.first


@dataclass(frozen=True)
class Analysis:
    """Tracking summary, event lists, the per-sample series behind them (at the recording's kept rows), the names
    of the robot's singularity measures among those series, what the robot adds to the report (closure error,
    say), the number of samples analysed, and where the path deviation and the orientation error rose above every
    sample before them (windowed.Rises: the verdict's first sample beyond a tolerance). `extremes`: what every
    sample shows and the kept rows of a strided run may miss: "qd_ref_peak", each joint's largest planned rate
    magnitude (dof,), and "singular_min", each singular set's least distance (in multiples of the near
    tolerance). `tracking`: the figures of the shipped metric `tracking`; `metrics`: every other metric's, by its
    name."""

    tracking: dict
    singularity_events: list[Event]
    limit_events: list[Event]
    series: dict[str, np.ndarray]
    measures: tuple[str, ...] = ()
    extra: dict = field(default_factory=dict)
    samples: int = 0
    rises: dict[str, Rises] = field(default_factory=dict)
    extremes: dict = field(default_factory=dict)
    metrics: dict[str, dict] = field(default_factory=dict)


def _event(t: np.ndarray, span: tuple[int, int], kind: str, detail: dict) -> Event:
    return Event(float(t[span[0]]), float(t[span[1]]), kind, detail)


def _waypoint_interval(traj: JointTrajectory, s0: float, s1: float) -> list[int] | None:
    """1-based numbers of the waypoints a step from s0 to s1 lies between (Table 2's row numbers)."""
    if not traj.waypoints:
        return None
    ws = np.array([w["s"] for w in traj.waypoints])
    i = int(np.clip(np.searchsorted(ws, s0, side="right") - 1, 0, len(ws) - 2))
    j = int(np.clip(np.searchsorted(ws, s1, side="left"), i + 1, len(ws) - 1))
    return [i + 1, j + 1]


def plan_limit_events(robot: Robot, traj: JointTrajectory) -> list[Event]:
    """The limits the plan itself breaks, found without simulating: `joint_limit` (a reference beyond a joint's
    range), `velocity_limit` (a reference rate beyond its speed limit) and `reference_jump` (without its cost in
    physics)."""
    limits = _PlanLimits(robot)
    limits.add(traj, 0)
    return sorted(limits.events(traj.t) + _jump_events(robot, traj, _jumps(robot, traj, 0, len(traj.t) - 1)),
                  key=lambda e: (e.t_start, e.kind))


class _Bounds:
    """The spans where each column of a per-joint series (N, dof) lies below its lower level or above its upper
    one, each with its extreme there (the least below, the largest above), seen a window at a time."""

    def __init__(self, lower: np.ndarray, upper: np.ndarray):
        self.lower, self.upper = lower, upper
        self.spans = {(j, bound): Spans(min if bound == "lower" else max)
                      for j in range(len(lower)) for bound in ("lower", "upper")}

    def add(self, values: np.ndarray, lo: int) -> None:
        """The window of samples lo.. of the series."""
        for j in range(values.shape[1]):
            x = values[:, j]
            for bound, beyond in (("lower", x < self.lower[j]), ("upper", x > self.upper[j])):
                extreme = np.min if bound == "lower" else np.max
                self.spans[j, bound].add(beyond, lo, lambda a, b, x=x, extreme=extreme: float(extreme(x[a:b + 1])))

    def finish(self) -> list[tuple[int, str, int, int, float]]:
        """Every span as (joint, bound, first, last, extreme), a joint at a time, its lower bound's first."""
        return [(j, bound, first, last, extreme) for (j, bound), spans_of in self.spans.items()
                for first, last, extreme in spans_of.finish()]


class _PlanLimits:
    """The spans where the plan's references pass a joint's range (`joint_limit`, with the worst reference) or its
    rates a joint's speed limit (`velocity_limit`, with the fastest), the plan seen a window at a time: a joint at
    a time, so that there are no (N, dof) temporaries on a long run."""

    def __init__(self, robot: Robot):
        self.robot = robot
        self.beyond = _Bounds(robot.lower - 1e-9, robot.upper + 1e-9)
        self.fast = [Spans(max) for _ in range(robot.dof)]
        self.peak = np.zeros(robot.dof)  # each joint's largest |qd_ref| so far

    def add(self, traj: JointTrajectory, lo: int) -> None:
        """The plan's rows lo.. (traj: those rows alone)."""
        robot = self.robot
        self.beyond.add(traj.q_ref, lo)
        for j in range(robot.dof):
            speed = np.abs(traj.qd_ref[:, j])
            self.fast[j].add(speed > robot.qd_max[j], lo, lambda a, b, speed=speed: float(speed[a:b + 1].max()))
            self.peak[j] = max(self.peak[j], float(speed.max(initial=0.0)))

    def events(self, t: np.ndarray) -> list[Event]:
        """The spans' events, a joint at a time (its range, then its speed limit), t the whole plan's times."""
        robot, events = self.robot, []
        for j, bound, first, last, worst in self.beyond.finish():
            limit = float(robot.lower[j] if bound == "lower" else robot.upper[j])
            events.append(_event(t, (first, last), "joint_limit", {
                "joint": robot.joints[j], "bound": bound, "limit": limit, "worst": worst,
                "excess": abs(worst - limit), "source": "reference"}))
        for j, spans_of in enumerate(self.fast):
            events += [_event(t, (first, last), "velocity_limit", {
                "joint": robot.joints[j], "limit": float(robot.qd_max[j]), "worst": worst})
                for first, last, worst in spans_of.finish()]
        return events


@dataclass(frozen=True)
class _Jump:
    """A step k -> k + 1 of the plan that jumps (`_jumps`): the joints that jump, the step and the path parameters
    at both ends, taken when it is found (a long run's plan rows are let go once they have been analysed)."""

    k: int
    joints: list[int]
    step: list[float]
    s: list[float]


def _jumps(robot: Robot, traj: JointTrajectory, first: int, stop: int) -> list[_Jump]:
    """The steps k -> k + 1 of the plan, first <= k < stop, farther than ten samples at the speed limit: a joint
    at a time, the steps as np.diff gives them, so that there are no (N, dof) temporaries on a long run; a joint a
    row, so that `any` runs along the samples (as in `_norms`)."""
    limit = _JUMP_FACTOR * robot.qd_max * traj.dt
    q, s = traj.q_ref[first:stop + 1], traj.s[first:stop + 1]
    jump = np.stack([np.abs(np.diff(q[:, j])) > limit[j] for j in range(len(limit))])
    return [_Jump(first + k, np.flatnonzero(jump[:, k]).tolist(), (q[k + 1] - q[k]).tolist(),
                  [float(s[k]), float(s[k + 1])]) for k in np.flatnonzero(jump.any(axis=0)).tolist()]


def _jump_events(robot: Robot, traj: JointTrajectory, jumps: list[_Jump],
                 departures: dict[int, Departure] | None = None) -> list[Event]:
    """The plan's jumps (`_jumps`); with the tool's departure from the path after each (the recorded path
    deviation's), what each cost: how far and how long the tool left the path."""
    t, events = traj.t, []
    for jump in jumps:
        k = jump.k
        detail = {"joints": [robot.joints[j] for j in jump.joints], "step": jump.step, "s": jump.s,
                  "between_waypoints": _waypoint_interval(traj, *jump.s)}
        if departures is not None:
            away = departures[k]
            back_at = away.back_at if away.back_at is not None else len(t) - 1
            detail["cost"] = {"tool_off_path_max": away.peak, "time_off_path": float(t[back_at] - t[k + 1]),
                              "back_on_path": away.back_at is not None}
        events.append(_event(t, (k, k + 1), "reference_jump", detail))
    return events


def _closest(a: tuple, b: tuple) -> tuple:
    """Of two pieces of a span near a singular set, (distance, sample, gaps) at the closest sample: the first."""
    return b if b[0] < a[0] else a


def analyse(robot: Robot, traj: JointTrajectory, rec: Recording, near: Tolerance, margin: Tolerance,
            window: int | None = None, scenario: Scenario | None = None) -> Analysis:
    """Everything the report says about a run, from every recorded sample, `window` samples at a time (default:
    `windowed.window_size`: all of a run as short as every shipped scenario), so that a long run's analysis holds
    a window of per-sample arrays and what it keeps of them: the figures and events of the whole run, and the
    per-sample series at the recording's kept rows (every row without a recording stride). `scenario` (a Scenario,
    or None) is what the metrics are made for (Metric.for_run)."""
    run = Analyser(robot, traj, near, margin, window, scenario)
    for lo in range(0, rec.t.size, run.window):
        run.add(rec.rows(lo, min(lo + run.window, rec.t.size)))
    return run.finish(rec)


class Analyser:
    """The analysis of a run, fed its samples a window at a time, in order (as they are simulated: simbench.sim,
    whose windows' samples are then let go). A window's plan is final: the plan's feedback revises the references
    of samples still to come only.

    Tracking series: joint errors; the tool's distance from the planned path (the polyline of the planned tool
    points) near its reference (the stretch within windowed.NEAR_REFERENCE s: `deviation_near_reference`) and its
    lag: the error's component along the path's tangent at the reference point, positive when the tool trails; and
    its error against the time-indexed reference. The robot's measures, singular sets and summary (a Summariser's
    windows, or with none the whole run's `summary` at the end), then every registered metric (registry.metrics_for)
    given the same windows: with no Summariser, the whole run as one at the end. Spans of events that reach a
    window's edge go on into the next (windowed.Spans)."""

    def __init__(self, robot: Robot, traj: JointTrajectory, near: Tolerance, margin: Tolerance,
                 window: int | None = None, scenario: Scenario | None = None):
        self.robot, self.traj, self.near = robot, traj, near
        self.window = window or windowed.window_size(traj.dt, len(traj.t))  # samples a window (`analyse`, sim)
        self.samples, self.seconds = 0, 0.0  # analysed so far, and the time `add` took
        self.tangents = _Tangents(traj.tool_ref)
        self.metrics: list[Metric] = metrics_for(robot, traj, scenario)
        self.rises = {"path_deviation": Rises(), robot.orientation_error: Rises()}
        self.kept: dict[str, list[np.ndarray]] = {}  # each series' kept rows, window by window
        self.measures: tuple[str, ...] = ()
        self.summariser = robot.summariser(traj) if robot.streams else None
        self.singular: list[Spans] = []
        self.sets: list = []  # each singular set's name, family and condition
        self.least: dict[str, float] = {}  # each singular set's least distance so far
        margins = np.array([margin.of(kind) for kind in robot.kinds])
        self.at_limit = _Bounds(robot.lower + margins, robot.upper - margins)
        self.saturated = [Spans(lambda first, _: first) for _ in range(robot.dof)]
        self.plan_limits = _PlanLimits(robot)
        self.plan_kept: list[JointTrajectory] = []  # the plan at the recording's kept rows, window by window
        self.jumps: list[_Jump] = []
        self.departures: dict[int, Departure] = {}
        self.force_limit, self.timestep = np.zeros(0), 0.0

    @property
    def streams(self) -> bool:
        """Whether the robot's summary comes a window at a time (a Summariser): else it needs the whole run."""
        return self.summariser is not None

    def add(self, rec: Recording) -> None:
        """The next window: the recording of samples lo..hi-1 (Recording.rows), lo the samples so far."""
        start = time.perf_counter()
        self._add(rec)
        self.seconds += time.perf_counter() - start

    def _add(self, rec: Recording) -> None:
        lo = self.samples
        hi = self.samples = lo + rec.t.size
        traj = self.traj.rows(slice(lo, hi))
        if rec.kept is not None:
            self.plan_kept.append(traj.rows(rec.kept))
        self.force_limit, self.timestep = rec.force_limit, rec.timestep
        self.plan_limits.add(traj, lo)
        for jump in _jumps(self.robot, self.traj, max(lo - 1, 0), hi - 1):  # each step once its rows are final
            self.jumps.append(jump)
            self.departures[jump.k] = Departure(jump.k + 1, _BACK_ON_PATH)
        series = self._tracking(traj, rec, lo, hi)
        measures = self.robot.measures(rec)
        self.measures = tuple(measures)
        series.update(measures)
        self._singular(self.robot.singular_sets_from(rec, self.near, measures), lo)
        if self.summariser is not None:
            series.update(self.summariser.add(traj, rec, series))
            self._orientation(series, lo)
            self._measure(traj, rec, series)
        self._limits(rec, lo)
        keep = slice(None) if self.summariser is None or rec.kept is None else rec.kept
        for name, values in series.items():
            self.kept.setdefault(name, []).append(values[keep])

    def _tracking(self, traj: JointTrajectory, rec: Recording, lo: int, hi: int) -> dict[str, np.ndarray]:
        """The tracking series of samples lo..hi-1."""
        joint_error = rec.q - traj.q_ref
        deviation = deviation_near_reference(self.traj.tool_ref, rec.tool, windowed.near_reference(self.traj.dt), lo)
        behind = traj.tool_ref - rec.tool  # the tool to its reference: its error, and along the tangent its lag
        lag = np.einsum("ij,ij->i", behind, self.tangents.rows(lo, hi))
        tool_error = _norms(behind)
        self.rises["path_deviation"].add(deviation, lo)
        for away in self.departures.values():
            away.add(deviation, lo)
        return {"joint_error": joint_error, "path_deviation": deviation, "path_lag": lag, "tool_error": tool_error}

    def _orientation(self, series: dict[str, np.ndarray], lo: int) -> None:
        """Where the orientation error rose, where the task is an orientation (beside the tool point's)."""
        error = series.get(self.robot.orientation_error)
        if error is not None:
            self.rises[self.robot.orientation_error].add(error, lo)

    def _measure(self, traj: JointTrajectory, rec: Recording, series: dict[str, np.ndarray]) -> None:
        """The metrics' next window."""
        for metric in self.metrics:
            metric.add(traj, rec, series)

    def _singular(self, sets: list, lo: int) -> None:
        """The spans where the recorded state lies near each of the robot's singular sets, with the closest sample."""
        if not self.singular:
            self.singular = [Spans(_closest) for _ in sets]
            self.sets = [(s.name, s.family, s.condition) for s in sets]

        for sset in sets:
            self.least[sset.name] = min(self.least.get(sset.name, np.inf), float(sset.distance.min(initial=np.inf)))
        for spans_of, sset in zip(self.singular, sets):
            def closest(a: int, b: int, sset=sset) -> tuple:
                i = a + int(np.argmin(sset.distance[a:b + 1]))
                return float(sset.distance[i]), lo + i, {k: float(v[i]) for k, v in sset.gaps.items()}
            spans_of.add(sset.distance <= 1.0, lo, closest)

    def _limits(self, rec: Recording, lo: int) -> None:
        """The spans where a joint sits at a limit (with its extreme there) or its actuator at its force bound."""
        self.at_limit.add(rec.q, lo)
        for j in range(self.robot.dof):
            force = rec.force[:, j]
            self.saturated[j].add(np.abs(force) >= rec.force_limit[j] * (1 - 1e-6), lo,
                                  lambda a, b, force=force: float(force[a]))

    def plan_from(self) -> int:
        """The first row of the plan that the windows still to come read: the step into the next window (its
        jump, its tangent) and the stretch of path its search takes (`path_from`). The rows before it may be let
        go (sim.simulate's analyser does), but for the plan's times, which the events are stamped with."""
        lo = self.samples
        return max(min(lo - 1, path_from(lo, windowed.near_reference(self.traj.dt))), 0)

    def plan(self) -> JointTrajectory:
        """The plan at the recording's kept rows analysed so far, without its feedback (spent): what the outputs
        of a run with a recording stride show, kept as the run goes, since its other rows may be let go."""
        return replace(joined(self.plan_kept), feedback=None)

    def finish(self, whole: Recording | None = None) -> Analysis:
        """The whole run's analysis; `whole`, the run's recording, is needed where the robot has no Summariser."""
        robot, traj, t = self.robot, self.traj, self.traj.t
        series = {name: np.concatenate(parts) if len(parts) > 1 else parts[0] for name, parts in self.kept.items()}
        singular = []
        for spans_of, (name, family, condition) in zip(self.singular, self.sets):
            for first, last, (distance, i, gaps) in spans_of.finish():
                detail = {"family": family, "condition": condition, "t_closest": float(t[i]), "distance": distance,
                          "gaps_at_closest": gaps}
                singular.append(_event(t, (first, last), name, detail))
        if self.summariser is not None:
            extra, events = self.summariser.finish()
        else:  # the whole run's summary, then its series at the kept rows
            if whole is None:
                raise ValueError(f"robot '{robot.name}' has no Summariser: its analysis needs the whole run's "
                                 "recording")
            extra, events, more = robot.summary(traj, whole, series)
            series.update(more)
            self._orientation(series, 0)
            self._measure(traj, whole, series)
            if whole.kept is not None:
                series = {name: v[whole.kept] for name, v in series.items()}
        figures = {metric.name: metric.finish() for metric in self.metrics}
        return Analysis(tracking=figures.pop("tracking"), metrics=figures, singularity_events=sorted(
                            singular + [Event.of(e) for e in events], key=lambda e: (e.t_start, e.kind)),
                        limit_events=self._limit_events(), series=series, measures=self.measures, extra=extra,
                        samples=self.samples,
                        rises={k: v for k, v in self.rises.items() if k is not None and v.at},
                        extremes={"qd_ref_peak": self.plan_limits.peak.copy(), "singular_min": dict(self.least)})

    def _limit_events(self) -> list[Event]:
        """Joint-limit, at-limit, reference-jump, velocity-limit and actuator-saturation events."""
        robot, traj, t = self.robot, self.traj, self.traj.t
        events = self.plan_limits.events(t)
        for j, bound, first, last, extreme in self.at_limit.finish():
            limit = robot.lower[j] if bound == "lower" else robot.upper[j]
            events.append(_event(t, (first, last), "at_limit", {"joint": robot.joints[j], "bound": bound,
                                                               "limit": float(limit), "extreme": extreme}))
        events += _jump_events(robot, traj, self.jumps, self.departures)
        for j, spans_of in enumerate(self.saturated):
            events += [_event(t, (first, last), "actuator_saturation", {
                "joint": robot.joints[j], "limit": float(self.force_limit[j]), "force": force,
                "duration": float(t[last] - t[first] + self.timestep)}) for first, last, force in spans_of.finish()]
        return sorted(events, key=lambda e: (e.t_start, e.kind))
