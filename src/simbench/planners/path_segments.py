"""cartesian_path's segments as a scenario writes them: decoupled_path's lines and arcs, each placed where the file
says or relative to where the path is, and the corners where one segment's tangent turns from the last one's.

A line's start is `start`, or where the previous segment ends (the tool's point at `task.start` for the first);
it ends at `end`, or `by` [dx, dy, dz] from its start in the world frame, or `by_tool` [dx, dy, dz] from its start
in the tool's frame at `task.start` (R_start @ offset). An arc's centre is `center`, or `center_by` from where the
arc starts (world), or `center_by_tool` from there with the whole arc written in the tool's frame at `task.start`
(its centre's offset, `normal` and `ref` turned by R_start); a relative arc may leave out `radius` (the distance
from its centre to where it starts, in its plane) and `start` (the angle of that point from `ref`; with `ref` left
out too, ref points there, so the arc starts at angle 0 and `end` is the angle it sweeps). Offsets are lengths in
the scenario's unit, converted to metres at load like every point.

A corner: where a segment's tangent turns from the previous one's by more than CORNER. Under a time law continuous
in s the tool's speed is continuous there but its velocity turns within one control step: a jump of
2 v sin(angle / 2), which a joint's rate follows in one step too. The plan says so (corner_warnings).
"""

from __future__ import annotations

import numpy as np

from simbench.api import REVOLUTE
from simbench.maths.paths import Arc, Composite, Line
from simbench.planners.decoupled_path import ArcSpec, LineSpec, Segment
from simbench.scenario.schema import Angle, Position, PositiveLength

CORNER = np.deg2rad(1.0)  # rad: a join whose tangents differ by more is a corner the plan warns of
_PLANE_TOL = 1e-6  # m: a relative arc's first point must lie this near its plane (decoupled_path's join tolerance)
_LINE_ENDS = ("end", "by", "by_tool")
_ARC_CENTRES = ("center", "center_by", "center_by_tool")


def _one_of(model, names: tuple[str, ...]) -> str:
    """The one of `names` the model gives, or ValueError naming them."""
    given = [name for name in names if getattr(model, name) is not None]
    if len(given) != 1:
        listed = ", ".join(f"'{name}'" for name in names[:-1]) + f" or '{names[-1]}'"
        got = " and ".join(f"'{name}'" for name in given) or "none"
        raise ValueError(f"expected exactly one of {listed}, got {got}")
    return given[0]


def _offset(model, name: str, rotation: np.ndarray) -> np.ndarray:
    """The offset field `name` (world frame), or `name`_tool's turned by the tool's rotation at the task's start."""
    world = getattr(model, name)
    return np.array(world) if world is not None else rotation @ np.array(getattr(model, f"{name}_tool"))


class OpenLine(LineSpec):
    """A line: from `start` or where the path is, to `end`, or by `by` (world) or `by_tool` (the tool's frame at the
    task's start) from its start."""

    start: Position | None = None
    end: Position | None = None
    by: Position | None = None
    by_tool: Position | None = None

    @property
    def placed_by(self) -> str:
        """The field that places its end: end, by or by_tool."""
        return next(name for name in _LINE_ENDS if getattr(self, name) is not None)

    def _not_a_point(self) -> OpenLine:
        """Exactly one of end, by, by_tool; an offset of some length; start and end apart (a line's end is checked
        against the tool's point where its start is left out: cartesian_path.check)."""
        name = _one_of(self, _LINE_ENDS)
        if name != "end" and np.linalg.norm(getattr(self, name)) < 1e-9:
            raise ValueError(f"a line needs a length: {name} is [0, 0, 0]")
        return super()._not_a_point() if name == "end" and self.start is not None else self

    def misfit(self, first: np.ndarray, rotation: np.ndarray) -> None:
        """Nothing: a line is placed wherever the path is (cartesian_path.check judges where it starts)."""

    def build_from(self, first: np.ndarray, rotation: np.ndarray) -> Line:
        """The segment, from `start` or else `first` (where the path is), the tool's frame at the start `rotation`."""
        p0 = np.asarray(first if self.start is None else self.start, float)
        return Line(p0, np.array(self.end) if self.end is not None else p0 + _offset(self, "by", rotation))


class OpenArc(ArcSpec):
    """An arc about `center`, or about `center_by` (world) from where it starts, or written in the tool's frame at
    the task's start: `center_by_tool`, its normal and ref turned into the world by the tool's rotation there; a
    relative one may leave out radius and start (the module's docstring)."""

    center: Position | None = None
    center_by: Position | None = None
    center_by_tool: Position | None = None
    radius: PositiveLength | None = None
    start: Angle | None = None

    def _proper_arc(self) -> OpenArc:
        """Exactly one centre; an absolute one with its radius and start; angles apart where they are known."""
        if _one_of(self, _ARC_CENTRES) == "center":
            missing = [name for name in ("radius", "start") if getattr(self, name) is None]
            if missing:
                raise ValueError(f"an arc about 'center' needs its {' and '.join(missing)} (only one about "
                                 "'center_by' or 'center_by_tool' may leave them out)")
        self._check_angles(self.start if self.start is not None or self.ref is not None else 0.0)
        return self

    def _turn(self, rotation: np.ndarray) -> np.ndarray:
        """What turns a relative arc's vectors into the world: `rotation`, the tool's at the task's start, for
        center_by_tool; else none."""
        return rotation if self.center_by_tool is not None else np.eye(3)

    def _placed(self, first: np.ndarray, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """A relative arc in the world: its centre, its normal, its first point's offset from the centre in its
        plane, and that point's distance from the plane (m)."""
        turn = self._turn(rotation)
        center = first + turn @ np.array(self.center_by if self.center_by is not None else self.center_by_tool)
        normal = turn @ np.array(self.normal)
        away = first - center
        off = float(away @ normal)
        return center, normal, away - off * normal, off

    def misfit(self, first: np.ndarray, rotation: np.ndarray) -> tuple[str, str] | None:
        """(field, what is wrong) of a relative arc that cannot start at `first`: its plane away from it, its
        centre on it, or an angle to sweep of zero."""
        if self.center is not None:
            return None
        name = "center_by" if self.center_by is not None else "center_by_tool"
        _, _, away, off = self._placed(first, rotation)
        if abs(off) > _PLANE_TOL:
            return f"arc.{name}", (f"puts the arc's plane {abs(off) * 1e3:.3f} mm from where it starts (the offset's "
                                   "part along the normal): give an offset across the normal")
        if np.linalg.norm(away) < _PLANE_TOL:
            return f"arc.{name}", "puts the arc's centre where it starts: give an offset across the normal"
        start = self.build_from(first, rotation).theta0
        if abs(self.end - start) < 1e-9:
            return "arc.end", f"is the angle where the arc starts ({np.rad2deg(start):.3f} deg): it sweeps none"
        return None

    def build_from(self, first: np.ndarray, rotation: np.ndarray) -> Arc:
        """The segment: an absolute arc as written, a relative one about its centre from `first` (where the path
        is), center_by_tool's vectors in the tool's frame at the start, `rotation`."""
        if self.center is not None:
            return self.build()
        center, normal, away, _ = self._placed(first, rotation)
        radius = self.radius if self.radius is not None else float(np.linalg.norm(away))
        ref = away if self.ref is None and self.start is None else self._turn(rotation) @ np.array(self.default_ref())
        frame = Arc.from_plane(center, radius, normal, 0.0, 0.0, ref)  # its ref projected onto the plane
        start = (self.start if self.start is not None
                 else float(np.arctan2(away @ np.cross(frame.normal, frame.ref), away @ frame.ref)))
        return Arc.from_plane(center, radius, normal, start, self.end, frame.ref)


class PathSegment(Segment):
    """One piece of the path: `line: {...}` or `arc: {...}`, placed absolutely or from where the path is."""

    line: OpenLine | None = None
    arc: OpenArc | None = None

    @property
    def spec(self) -> OpenLine | OpenArc:
        """The line or the arc."""
        return self.line if self.line is not None else self.arc


def place(path: list[PathSegment], tool: np.ndarray, rotation: np.ndarray) -> tuple[list, tuple[str, str] | None]:
    """The path's segments (paths.Line, paths.Arc), each from where the one before ends, the first from `tool` (the
    tool's point at the task's start), by_tool offsets turned by `rotation` (its orientation there); and None, or
    those before the first that cannot be placed and (field, what is wrong) of it."""
    segments, at = [], tool
    for i, seg in enumerate(path):
        wrong = seg.spec.misfit(at, rotation)
        if wrong is not None:
            return segments, (f"task.path[{i}].{wrong[0]}", wrong[1])
        segments.append(seg.spec.build_from(at, rotation))
        at = segments[-1].point(np.ones(1))[0]
    return segments, None


def placed_path(segments: list) -> list[dict]:
    """The placed segments as the absolute form writes them, in SI (m, rad): for the report."""
    out = []
    for seg in segments:
        if isinstance(seg, Line):
            out.append({"line": {"start": np.asarray(seg.p0).tolist(), "end": np.asarray(seg.p1).tolist()}})
        else:
            out.append({"arc": {"center": seg.center.tolist(), "radius": seg.radius, "normal": seg.normal.tolist(),
                                "ref": seg.ref.tolist(), "start": seg.theta0, "end": seg.theta1}})
    return out


def corners(path: Composite, robot, t: np.ndarray, s: np.ndarray, qd: np.ndarray) -> list[dict]:
    """Each join where the tangent turns by more than CORNER: the segment after it, the angle (rad), the plan's
    first sample at or past it (its time), the tool's speed there, the velocity's jump 2 v sin(angle / 2) (m/s),
    and the joint whose rate the plan changes most between two samples beside it, by how much (SI)."""
    out = []
    speed = path.length * np.gradient(s, t)
    for i in range(1, len(path.segments)):
        a, b = path.segments[i - 1].tangent(np.ones(1))[0], path.segments[i].tangent(np.zeros(1))[0]
        angle = float(np.arctan2(np.linalg.norm(np.cross(a, b)), a @ b))
        if angle <= CORNER:
            continue
        k = min(int(np.searchsorted(s, path.bounds[i])), len(s) - 1)
        jumps = np.abs(np.diff(qd[max(k - 2, 0):k + 3], axis=0)).max(axis=0)
        j = int(np.argmax(jumps))
        out.append({"segment": i, "angle": angle, "t": float(t[k]), "tool_speed": float(speed[k]),
                    "velocity_jump": float(2 * speed[k] * np.sin(angle / 2)), "joint": robot.joints[j],
                    "rate_jump": float(jumps[j])})
    return out


def corner_warning(corner: dict, robot) -> str:
    """The plan's warning of one corner (corners), in degrees and millimetres."""
    i, joint = corner["segment"], corner["joint"]
    rate = (f"{np.rad2deg(corner['rate_jump']):.1f} deg/s" if robot.kinds[robot.joints.index(joint)] == REVOLUTE
            else f"{corner['rate_jump'] * 1e3:.1f} mm/s")
    return (f"task.path[{i}] turns {np.rad2deg(corner['angle']):.1f} deg from the end of task.path[{i - 1}], a corner "
            f"at t = {corner['t']:.3f} s: the tool's velocity there ({corner['tool_speed'] * 1e3:.1f} mm/s) turns "
            f"within one control step, a jump of {corner['velocity_jump'] * 1e3:.1f} mm/s, and "
            f"{joint}'s rate jumps by {rate}: a step the servos meet with a jolt (past a force limit in the run, "
            "say); an arc tangent to both segments rounds it")
