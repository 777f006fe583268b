"""A path point no joint values reach, refused at load (cartesian_path.check): farther from the anchor of the joint
nearest the world than the chain's reach (robots.chain), which bounds every point the tool takes.
"""

from __future__ import annotations

import numpy as np

from simbench.maths.paths import Arc

_ROUNDING = 1e-9  # m: a path point past the reach by this much at most is not refused


def beyond_reach(path: list, segments: list, robot) -> tuple[str, str] | None:
    """The first segment with a point the arm certainly cannot reach: farther from the base joint's anchor than the
    reach (robots.chain: the chain's length from that anchor, which no joint values exceed). A line's farthest point
    is an end, its start the tool's or the last segment's end; an arc's is _farthest."""
    anchor = robot.anchor
    for i, (seg, segment) in enumerate(zip(path, segments)):
        point = segment.point(np.ones(1))[0] if seg.line is not None else _farthest(segment, anchor)
        far = float(np.linalg.norm(point - anchor))
        if far > robot.reach + _ROUNDING:
            if seg.line is None:
                field, what = f"task.path[{i}].arc", "has its farthest point"
            else:
                by = seg.line.placed_by
                field, what = f"task.path[{i}].line.{by}", "lies" if by == "end" else "puts the line's end"
            return field, (f"{what} {far * 1e3:.1f} mm from {robot.base_joint}'s anchor, beyond the arm's reach of "
                           f"{robot.reach * 1e3:.1f} mm (its chain's length from there): no joint values put the "
                           "tool there")
    return None


def _farthest(arc: Arc, centre: np.ndarray) -> np.ndarray:
    """The arc's point farthest from `centre`: an end, or the circle's farthest point (at the angle of the circle's
    centre seen from `centre`, in the arc's plane) where the arc passes it."""
    away = arc.center - centre
    theta = np.arctan2(away @ np.cross(arc.normal, arc.ref), away @ arc.ref)
    low, high = sorted((arc.theta0, arc.theta1))
    theta += 2 * np.pi * np.ceil((low - theta) / (2 * np.pi))  # its first turn at or past the arc's lower end
    s = [0.0, 1.0] + ([(theta - arc.theta0) / (arc.theta1 - arc.theta0)] if theta <= high else [])
    points = arc.point(np.array(s))
    return points[np.argmax(np.linalg.norm(points - centre, axis=1))]
