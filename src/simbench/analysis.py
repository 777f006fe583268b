"""Metrics and events from a Recording: how well the tool followed the plan, and what it came near.

Tracking: joint errors; the tool's distance from the planned path (the polyline of the planned tool points),
its lag along the path, and its error against the time-indexed reference. Events, each
{t_start, t_end, kind, detail}:
  singularity_events  spans where the recorded configuration lies near one of the robot's singular sets;
  limit_events        `joint_limit` (the plan asks for a value beyond a joint's range), `at_limit` (the joint
                      sits at a limit), `reference_jump` (the plan steps farther in one sample than the joint's
                      speed limit allows in ten: a discontinuity), `velocity_limit` (the plan is faster than
                      the joint can go) and `actuator_saturation` (a joint's actuator at its force bound: the
                      motor cannot give what tracking the plan takes).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from simbench.budget import SEARCH_PAIRS

from simbench.robots import Robot, Tolerance
from simbench.sim import Recording
from simbench.trajectory import JointTrajectory

_JUMP_FACTOR = 10.0
_NEAR_REFERENCE = 2.0  # s: the tool is measured against the planned path within this time of its reference
_BACK_ON_PATH = 1e-3  # m: after a jump, the tool counts as back on the path within this distance


@dataclass(frozen=True)
class Analysis:
    """Tracking summary, event lists, the per-sample series behind them, the names of the robot's singularity
    measures among those series, and what the robot adds to the report (closure error, say)."""

    tracking: dict
    singularity_events: list[dict]
    limit_events: list[dict]
    series: dict[str, np.ndarray]
    measures: tuple[str, ...] = ()
    extra: dict = field(default_factory=dict)


def spans(mask: np.ndarray) -> list[tuple[int, int]]:
    """Index ranges [start, end] (inclusive) of the runs of True in mask."""
    padded = np.concatenate([[False], np.asarray(mask, bool), [False]])
    edges = np.flatnonzero(padded[1:] != padded[:-1])
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2])]


def _event(t: np.ndarray, span: tuple[int, int], kind: str, detail: dict) -> dict:
    return {"t_start": float(t[span[0]]), "t_end": float(t[span[1]]), "kind": kind, "detail": detail}


def path_deviation(path: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance of each point from the polyline `path`.

    A point's nearest vertex, at distance r, bounds its distance from the path, and every point of a segment
    lies within half the longest segment, h, of one of its ends; so only segments with an end within r + h of
    the point can be nearer, and a k-d tree finds those ends. Far from the path (r > 100 h) the nearest vertex is
    taken as is: it is then within h^2 / 2r < h / 200 of the exact distance.
    """
    keep = np.concatenate([[True], np.any(np.diff(path, axis=0) != 0, axis=1)])
    vertices = _subdivided(path[keep])
    if len(vertices) == 1:
        return np.linalg.norm(points - vertices[0], axis=1)
    tree = cKDTree(vertices)
    best, _ = tree.query(points)
    half = 0.5 * np.linalg.norm(np.diff(vertices, axis=0), axis=1).max()
    close = np.flatnonzero(best <= 100 * half)
    if close.size == 0:
        return best
    radius = best[close] + half + 1e-12
    counts = tree.query_ball_point(points[close], radius, return_length=True)  # >= 1: the nearest vertex
    # Points taken in batches of about SEARCH_PAIRS (point, vertex) pairs (a batch ends with the point that
    # crosses the bound), so that memory stays bounded where many vertices crowd one place.
    batch_of = (np.cumsum(counts) - counts) // SEARCH_PAIRS
    for part in np.split(np.arange(close.size), np.flatnonzero(np.diff(batch_of)) + 1):
        batch = close[part]
        best[batch] = np.minimum(best[batch], _nearest_segment(tree, vertices, points[batch], radius[part]))
    return best


def _subdivided(vertices: np.ndarray) -> np.ndarray:
    """The same polyline with its long segments cut into pieces no longer than the typical one (the median, or
    1e-5 of the whole length if that is longer): one long segment among short ones (a jump in the plan) would
    otherwise widen every point's search ball to it, and the search would grow with the square of the samples."""
    if len(vertices) < 3:
        return vertices
    length = np.linalg.norm(np.diff(vertices, axis=0), axis=1)
    piece = max(float(np.median(length)), 1e-5 * float(length.sum()))
    cuts = np.ceil(length / piece).astype(int)
    if (cuts <= 1).all():
        return vertices
    # Vertex i followed by cuts[i] - 1 evenly spaced points towards vertex i + 1.
    owner = np.repeat(np.arange(len(length)), cuts)
    fraction = (np.arange(len(owner)) - np.repeat(np.cumsum(cuts) - cuts, cuts)) / cuts[owner]
    points = vertices[owner] + fraction[:, None] * (vertices[owner + 1] - vertices[owner])
    return np.concatenate([points, vertices[-1:]])


def _nearest_segment(tree: cKDTree, vertices: np.ndarray, points: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Each point's distance from the nearest of the segments that have an end within its radius."""
    near = tree.query_ball_point(points, radius)
    counts = np.fromiter(map(len, near), int, len(near))
    vertex = np.concatenate(near).astype(int)
    owner = np.repeat(np.arange(len(points)), counts)
    last = len(vertices) - 2
    distance = np.minimum(_segment_distance(vertices, np.clip(vertex - 1, 0, last), points[owner]),
                          _segment_distance(vertices, np.minimum(vertex, last), points[owner]))
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    return np.minimum.reduceat(distance, first)


def deviation_near_reference(path: np.ndarray, points: np.ndarray, window: int) -> np.ndarray:
    """Distance of each points[k] from the stretch of the sampled path within about `window` samples of path[k]
    (from `window` to twice that: the path is cut into blocks of `window` samples, each searched with its
    neighbours). A path that comes back to the same place later, a rotor turning many times say, then does not
    hide a point that is off its own stretch, and the search stays as cheap as on a path that never returns."""
    out = np.empty(len(points))
    for start in range(0, len(points), window):
        stop = min(start + window, len(points))
        stretch = path[max(start - window, 0):stop + window]
        out[start:stop] = path_deviation(stretch, points[start:stop])
    return out


def _segment_distance(vertices: np.ndarray, seg: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance of each point from the segment vertices[seg] -> vertices[seg + 1]."""
    a, ab = vertices[seg], vertices[seg + 1] - vertices[seg]
    rel = points - a
    u = np.clip(np.einsum("ij,ij->i", rel, ab) / np.einsum("ij,ij->i", ab, ab), 0.0, 1.0)
    return np.linalg.norm(rel - u[:, None] * ab, axis=1)


def _rms(x: np.ndarray, axis=0) -> np.ndarray:
    return np.sqrt(np.mean(np.square(x), axis=axis))


def along_path(points: np.ndarray) -> np.ndarray:
    """Unit tangent (N, 3) of a sampled path; where it rests, the direction it last moved in (or first will)."""
    step = np.gradient(points, axis=0)
    norm = np.linalg.norm(step, axis=1)
    moving = norm > 1e-12 * max(1.0, float(np.abs(points).max()))
    if not moving.any():
        return np.zeros_like(points)
    index = np.maximum.accumulate(np.where(moving, np.arange(len(points)), -1))
    index = np.where(index < 0, np.argmax(moving), index)
    return step[index] / norm[index][:, None]


def tracking(robot: Robot, traj: JointTrajectory, rec: Recording) -> tuple[dict, dict[str, np.ndarray]]:
    """Tracking summary (SI units) and the per-sample series it summarises.

    The tool's error against the planned path splits into its distance from the path near its reference (the
    stretch within _NEAR_REFERENCE s: `deviation_near_reference`; reported as tool_rms and tool_max) and its
    lag: the error's component along the path's tangent at the reference point, positive when the tool trails.
    """
    joint_error = rec.q - traj.q_ref
    deviation = deviation_near_reference(traj.tool_ref, rec.tool, max(1, int(round(_NEAR_REFERENCE / traj.dt))))
    lag = np.einsum("ij,ij->i", traj.tool_ref - rec.tool, along_path(traj.tool_ref))
    arc_ref = np.sum(np.linalg.norm(np.diff(traj.tool_ref, axis=0), axis=1))
    tool_error = np.linalg.norm(rec.tool - traj.tool_ref, axis=1)
    summary = {
        "joint_rms": dict(zip(robot.joints, _rms(joint_error).tolist())),
        "joint_max": dict(zip(robot.joints, np.abs(joint_error).max(axis=0).tolist())),
        "tool_rms": float(_rms(deviation)),
        "tool_max": float(deviation.max()),
        "tool_lag_rms": float(_rms(lag)),
        "tool_lag_max": float(np.abs(lag).max()),
        "tool_error_rms": float(_rms(tool_error)),
        "tool_error_max": float(tool_error.max()),
        "tool_error_final": float(tool_error[-1]),
        "path_length": float(arc_ref),
    }
    series = {"joint_error": joint_error, "path_deviation": deviation, "path_lag": lag, "tool_error": tool_error}
    return summary, series


def singularity_events(robot: Robot, rec: Recording, tol: Tolerance) -> list[dict]:
    """Spans where the recorded state lies near each of the robot's singular sets, with how near at the closest
    sample."""
    t, events = rec.t, []
    for sset in robot.singular_sets(rec, tol):
        for span in spans(sset.distance <= 1.0):
            i = span[0] + int(np.argmin(sset.distance[span[0]:span[1] + 1]))
            detail = {"family": sset.family, "condition": sset.condition, "t_closest": float(t[i]),
                      "distance": float(sset.distance[i]),
                      "gaps_at_closest": {k: float(v[i]) for k, v in sset.gaps.items()}}
            events.append(_event(t, span, sset.name, detail))
    return sorted(events, key=lambda e: (e["t_start"], e["kind"]))


def _waypoint_interval(traj: JointTrajectory, s0: float, s1: float) -> list[int] | None:
    """1-based numbers of the waypoints a step from s0 to s1 lies between (Table 2's row numbers)."""
    if not traj.waypoints:
        return None
    ws = np.array([w["s"] for w in traj.waypoints])
    i = int(np.clip(np.searchsorted(ws, s0, side="right") - 1, 0, len(ws) - 2))
    j = int(np.clip(np.searchsorted(ws, s1, side="left"), i + 1, len(ws) - 1))
    return [i + 1, j + 1]


def plan_limit_events(robot: Robot, traj: JointTrajectory) -> list[dict]:
    """The limits the plan itself breaks, found without simulating: `joint_limit` (a reference beyond a joint's
    range), `velocity_limit` (a reference rate beyond its speed limit) and `reference_jump` (without its cost in
    physics)."""
    return sorted(_joint_limit_events(robot, traj) + _velocity_events(robot, traj)
                  + _jump_events(robot, traj, None), key=lambda e: (e["t_start"], e["kind"]))


def _joint_limit_events(robot: Robot, traj: JointTrajectory) -> list[dict]:
    t, events = traj.t, []
    for j, name in enumerate(robot.joints):
        lo, hi = robot.lower[j], robot.upper[j]
        for bound, limit, beyond in (("lower", lo, traj.q_ref[:, j] < lo - 1e-9),
                                     ("upper", hi, traj.q_ref[:, j] > hi + 1e-9)):
            for span in spans(beyond):
                seg = traj.q_ref[span[0]:span[1] + 1, j]
                worst = float(seg.min() if bound == "lower" else seg.max())
                events.append(_event(t, span, "joint_limit", {
                    "joint": name, "bound": bound, "limit": float(limit), "worst": worst,
                    "excess": abs(worst - float(limit)), "source": "reference"}))
    return events


def _velocity_events(robot: Robot, traj: JointTrajectory) -> list[dict]:
    t, events = traj.t, []
    too_fast = np.abs(traj.qd_ref) > robot.qd_max
    for j, name in enumerate(robot.joints):
        for span in spans(too_fast[:, j]):
            seg = np.abs(traj.qd_ref[span[0]:span[1] + 1, j])
            events.append(_event(t, span, "velocity_limit", {
                "joint": name, "limit": float(robot.qd_max[j]), "worst": float(seg.max())}))
    return events


def _jump_events(robot: Robot, traj: JointTrajectory, deviation: np.ndarray | None) -> list[dict]:
    """Steps of the plan farther than ten samples at the speed limit; with the recorded path deviation, what each
    cost: how far and how long the tool left the path."""
    t, events = traj.t, []
    step = np.diff(traj.q_ref, axis=0)
    jump = np.abs(step) > _JUMP_FACTOR * robot.qd_max * traj.dt
    for k in np.flatnonzero(jump.any(axis=1)):
        detail = {"joints": [robot.joints[j] for j in np.flatnonzero(jump[k])],
                  "step": step[k].tolist(),
                  "s": [float(traj.s[k]), float(traj.s[k + 1])],
                  "between_waypoints": _waypoint_interval(traj, traj.s[k], traj.s[k + 1])}
        if deviation is not None:
            after = deviation[k + 1:]
            peak = int(np.argmax(after))
            back = np.flatnonzero(after[peak:] < _BACK_ON_PATH)
            back_at = k + 1 + peak + int(back[0]) if back.size else len(t) - 1
            detail["cost"] = {"tool_off_path_max": float(after.max()),
                              "time_off_path": float(t[back_at] - t[k + 1]),
                              "back_on_path": bool(back.size)}
        events.append(_event(t, (k, k + 1), "reference_jump", detail))
    return events


def _saturation_events(robot: Robot, rec: Recording) -> list[dict]:
    """Spans where a joint's actuator force sits at its bound (within a part in a million)."""
    events = []
    at_bound = np.abs(rec.force) >= rec.force_limit * (1 - 1e-6)
    for j, name in enumerate(robot.joints):
        for span in spans(at_bound[:, j]):
            events.append(_event(rec.t, span, "actuator_saturation", {
                "joint": name, "limit": float(rec.force_limit[j]),
                "force": float(rec.force[span[0], j]),
                "duration": float(rec.t[span[1]] - rec.t[span[0]] + rec.timestep)}))
    return events


def limit_events(robot: Robot, traj: JointTrajectory, rec: Recording, margin: Tolerance,
                 deviation: np.ndarray) -> list[dict]:
    """Joint-limit, at-limit, reference-jump, velocity-limit and actuator-saturation events."""
    t, events = traj.t, _joint_limit_events(robot, traj)
    for j, (name, kind) in enumerate(zip(robot.joints, robot.kinds)):
        lo, hi = robot.lower[j], robot.upper[j]
        tol = margin.of(kind)
        for bound, limit, near in (("lower", lo, rec.q[:, j] < lo + tol), ("upper", hi, rec.q[:, j] > hi - tol)):
            for span in spans(near):
                seg = rec.q[span[0]:span[1] + 1, j]
                extreme = float(seg.min() if bound == "lower" else seg.max())
                events.append(_event(t, span, "at_limit", {
                    "joint": name, "bound": bound, "limit": float(limit), "extreme": extreme}))
    events += _jump_events(robot, traj, deviation) + _velocity_events(robot, traj) + _saturation_events(robot, rec)
    return sorted(events, key=lambda e: (e["t_start"], e["kind"]))


def analyse(robot: Robot, traj: JointTrajectory, rec: Recording, near: Tolerance, margin: Tolerance) -> Analysis:
    """Everything the report says about a run."""
    summary, series = tracking(robot, traj, rec)
    measures = robot.measures(rec)
    series.update(measures)
    singular = singularity_events(robot, rec, near)
    extra, events, more = robot.summary(traj, rec, series)
    series.update(more)
    singular = sorted(singular + events, key=lambda e: (e["t_start"], e["kind"]))
    if robot.orientation_error in series:  # a task that is an orientation: its error beside the tool point's
        error = series[robot.orientation_error]
        summary.update(orientation_rms=float(_rms(error)), orientation_max=float(error.max()),
                       orientation_final=float(error[-1]))
    return Analysis(tracking=summary, singularity_events=singular,
                    limit_events=limit_events(robot, traj, rec, margin, series["path_deviation"]),
                    series=series, measures=tuple(measures), extra=extra)
