"""Paper 002's joint time histories for lines, circle arcs and composite paths of a decoupled arm (PUMA 600).

The tool follows a path of lines and arcs (eqs. 23-37) on a time law, with its orientation held (or turned
by slerp to a second orientation along the path). Because the wrist is spherical, the wrist centre follows the
path offset by the tool: p_w = p - R TOOL. Its joints come from the paper's method:

  - q3 from the wrist centre's distance alone: |P|^2 = a2^2 + a3^2 + d4^2 + d3^2 + 2 a2 a3 cos q3 - 2 a2 d4 sin q3
    (eq. 9 as corrected in NOTES.md), solved with v = tan(q3/2) as the quadratic
    v^2 (C - A - K) + 2 B v + (A + C - K) = 0 (eqs. 12-14), whose two roots are the elbow's two sides;
  - q1 and q2 in closed form from eq. 1: (Px, Py) = Rz(q1) (r, d3) and (r, -Pz) = [[g, -h], [h, g]] (c2, s2),
    g = a3 c3 - d4 s3 + a2, h = a3 s3 + d4 c3;
  - q4, q5, q6 from the spherical wrist (Rx(90 deg) R_36 = Rz(q4) Ry(-q5) Rz(q6)).

The configuration (arm, elbow, wrist) is chosen once and kept; every joint is made continuous along the path
and put on the turn that lies within its range at the start. All samples are solved at once (vectorised).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field, model_validator
from scipy.spatial.transform import Rotation, Slerp

from simbench.errors import RunError
from simbench.paths import Arc, Composite, Line
from simbench.planners import Planner, rate
from simbench.robots import puma600
from simbench.robots.puma600 import A2, A3, D3, D4, LOWER, TOOL, UPPER
from simbench.schema import Angle, Direction, Orientation, Position, PositiveLength, SimbenchModel
from simbench.trajectory import JointTrajectory, control_grid

# Eq. 9 corrected: |P|^2 = C + A cos q3 + B sin q3 (eq. 12's A, B, C).
COEF_A = 2 * A2 * A3
COEF_B = -2 * A2 * D4
COEF_C = A2**2 + A3**2 + D4**2 + D3**2
_JOIN_TOL = 1e-6  # m: consecutive segments must meet within this


class LineSpec(SimbenchModel):
    """A line from `start` to `end` (eq. 23)."""

    start: Position
    end: Position

    @model_validator(mode="after")
    def _not_a_point(self) -> "LineSpec":
        if np.linalg.norm(np.subtract(self.end, self.start)) < 1e-9:
            raise ValueError("a line needs two different points: start equals end")
        return self

    def build(self) -> Line:
        """The path segment."""
        return Line(np.array(self.start), np.array(self.end))


class ArcSpec(SimbenchModel):
    """A circle arc (eqs. 28-37): centre, radius, plane normal, angles measured about the normal from `ref`
    (default: the world x axis projected onto the plane, or y where x is normal to it)."""

    center: Position
    radius: PositiveLength
    normal: Direction
    start: Angle
    end: Angle
    ref: Direction | None = None

    @model_validator(mode="after")
    def _proper_arc(self) -> "ArcSpec":
        if abs(self.end - self.start) < 1e-9:
            raise ValueError("an arc needs different start and end angles")
        if self.ref is not None and abs(np.dot(self.ref, self.normal)) > 1 - 1e-6:
            raise ValueError("ref must not be parallel to the normal")
        return self

    def build(self) -> Arc:
        """The path segment."""
        ref = self.ref
        if ref is None:
            ref = [1.0, 0.0, 0.0] if abs(self.normal[0]) < 0.99 else [0.0, 1.0, 0.0]
        return Arc.from_plane(self.center, self.radius, self.normal, self.start, self.end, ref)


class Segment(SimbenchModel):
    """One piece of the path: `line: {...}` or `arc: {...}`."""

    line: LineSpec | None = None
    arc: ArcSpec | None = None

    @model_validator(mode="after")
    def _exactly_one(self) -> "Segment":
        if (self.line is None) == (self.arc is None):
            raise ValueError("expected exactly one of 'line' or 'arc'")
        return self

    def build(self):
        """The path segment."""
        return (self.line or self.arc).build()


class Configuration(SimbenchModel):
    """Which of the 8 inverse-kinematics solutions the arm keeps along the path (puma600 module docstring)."""

    arm: Literal["righty", "lefty"] = "righty"
    elbow: Literal["up", "down"] = "up"
    wrist: Literal["noflip", "flip"] = "noflip"

    def flags(self) -> np.ndarray:
        """The (arm, elbow, wrist) signs."""
        return np.array([puma600.ARM[self.arm], puma600.ELBOW[self.elbow], puma600.WRIST[self.wrist]])


class Task(SimbenchModel):
    """`task:` of paper 002's method: the tool's path, its orientation, the arm's configuration."""

    path: list[Segment] = Field(min_length=1)
    orientation: Orientation
    orientation_end: Orientation | None = None
    configuration: Configuration = Configuration()

    def build_path(self) -> Composite:
        """The tool's path as one composite, s shared by arc length."""
        return Composite(tuple(seg.build() for seg in self.path))

    def rotations(self, s: np.ndarray) -> np.ndarray:
        """Tool orientation R (N, 3, 3) along the path: held, or slerped to orientation_end."""
        start = self.orientation.matrix()
        if self.orientation_end is None:
            return np.broadcast_to(start, (len(s), 3, 3)).copy()
        ends = Rotation.from_matrix([start, self.orientation_end.matrix()])
        return Slerp([0.0, 1.0], ends)(np.clip(s, 0.0, 1.0)).as_matrix()


def q3_from_distance(k: np.ndarray, h_sign: np.ndarray) -> np.ndarray:
    """q3 from the squared wrist distance K (eqs. 12-19): the root of eq. 14 whose h has the sign h_sign.

    Eq. 14 has real roots only where |K - C| <= sqrt(A^2 + B^2) (NOTES.md: eq. 15 as printed is wrong); NaN
    elsewhere. The roots are taken as q / a and c / q with q = -(B + sign(B) sqrt(disc)), free of cancellation,
    so a root at q3 = 180 deg (a = 0) comes out as v = inf.
    """
    a = COEF_C - COEF_A - k
    c = COEF_A + COEF_C - k
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # far points overflow: out of reach
        disc = COEF_B**2 - a * c
        big = -(COEF_B + np.sign(COEF_B) * np.sqrt(disc))
        q3a, q3b = 2 * np.arctan(big / a), 2 * np.arctan(c / big)  # eq. 19
    h_a = A3 * np.sin(q3a) + D4 * np.cos(q3a)
    return np.where(disc >= 0, np.where(np.sign(h_a) == h_sign, q3a, q3b), np.nan)


def arm_angles(p: np.ndarray, arm: float, elbow: float) -> np.ndarray:
    """(q1, q2, q3) (N, 3) of wrist-centre points p (N, 3) by the paper's method; NaN where out of reach."""
    q3 = q3_from_distance(np.einsum("ij,ij->i", p, p), elbow * arm)
    with np.errstate(invalid="ignore"):
        r = arm * np.sqrt(p[:, 0] ** 2 + p[:, 1] ** 2 - D3**2)
    q1 = np.arctan2(p[:, 1], p[:, 0]) - np.arctan2(D3, r)
    g = A3 * np.cos(q3) - D4 * np.sin(q3) + A2
    h = A3 * np.sin(q3) + D4 * np.cos(q3)
    q2 = np.arctan2(-g * p[:, 2] - h * r, g * r - h * p[:, 2])
    return np.stack([q1, q2, q3], axis=-1)


def solve(points: np.ndarray, rotations: np.ndarray, flags: np.ndarray) -> np.ndarray:
    """Joints (N, 6) for tool points (N, 3) and orientations (N, 3, 3) in one configuration, not unwrapped."""
    wrist = points - rotations @ TOOL
    q123 = arm_angles(wrist, flags[0], flags[1])
    return np.concatenate([q123, puma600.wrist_angles(q123, rotations, flags[2])], axis=1)


def continuous(q: np.ndarray) -> np.ndarray:
    """Every joint unwrapped along the samples, then moved by whole turns so the start lies in range if it can."""
    q = np.unwrap(q, axis=0)
    mid = 0.5 * (LOWER + UPPER)
    turns = np.round((mid - q[0]) / (2 * np.pi))
    return q + 2 * np.pi * turns


def plan(scenario, robot, dt: float) -> JointTrajectory:
    """Solve the tool path at every control sample by paper 002's method."""
    task = scenario.task
    path = task.build_path()
    law = scenario.timing.law_fn()
    t = control_grid(law.duration, scenario.timing.hold, dt)
    s, ds = law(t, order=1)
    flags = task.configuration.flags()

    def evaluate(x: np.ndarray) -> np.ndarray:
        return solve(path.point(x), task.rotations(x), flags)

    raw = evaluate(s)
    bad = np.isnan(raw).any(axis=1)
    if bad.any():
        k = int(np.argmax(bad))
        point = path.point(s[k:k + 1])[0]
        raise RunError(f"the path leaves the arm's reach at s = {s[k]:.4f} (t = {t[k]:.3f} s), tool point "
                       f"[{point[0]:.4f}, {point[1]:.4f}, {point[2]:.4f}] m: its wrist centre cannot be reached")
    q_ref = continuous(raw)
    qd_ref = rate(evaluate, s, np.ones(6, bool)) * ds[:, None]
    tool_ref = path.point(s)
    bounds = path.bounds
    grid = np.union1d(np.linspace(0.0, 1.0, 2001), bounds)
    wp_q = continuous(evaluate(grid))[np.searchsorted(grid, bounds)]  # from s = 0, as q_ref: the same turns
    waypoints = tuple({"s": float(b), "X": x.tolist(), "q": qq.tolist()}
                      for b, x, qq in zip(bounds, path.point(bounds), wp_q))
    speed = np.linalg.norm(np.gradient(tool_ref, t, axis=0), axis=1)
    info = {
        "method": "paper 002: q3 from the wrist distance (eqs. 9-19, corrected), q1 and q2 closed form, "
                  "spherical wrist",
        "configuration": task.configuration.model_dump(),
        "segments": [("line" if seg.line else "arc") for seg in task.path],
        "path_length": path.length,
        "tool_speed_max": float(speed.max()),
    }
    return JointTrajectory(t=t, s=s, q_ref=q_ref, qd_ref=qd_ref, tool_ref=tool_ref, waypoints=waypoints, info=info)


def check(scenario, robot) -> tuple[str, str] | None:
    """Segments must join end to start, and every segment's ends must be within the wrist's reach."""
    task = scenario.task
    segments = [seg.build() for seg in task.path]
    for i in range(1, len(segments)):
        gap = np.linalg.norm(segments[i].point(np.array([0.0]))[0] - segments[i - 1].point(np.array([1.0]))[0])
        if gap > _JOIN_TOL:
            return f"task.path[{i}]", f"starts {gap * 1e3:.3f} mm from where task.path[{i - 1}] ends"
    flags = task.configuration.flags()
    for i, seg in enumerate(segments):
        ends = np.array([0.0, 1.0])
        q = solve(seg.point(ends), task.rotations(ends), flags)
        for j, name in enumerate(("start", "end")):
            if np.isnan(q[j]).any():
                point = seg.point(ends[j:j + 1])[0]
                kind = "line" if task.path[i].line else "arc"
                return (f"task.path[{i}].{kind}", f"its {name} [{point[0]:.4f}, {point[1]:.4f}, {point[2]:.4f}] m is "
                        "outside the workspace (the wrist centre cannot be reached)")
    return None


PLANNER = Planner(
    name="decoupled_path",
    description="paper 002: lines, circle arcs and composite tool paths by the wrist-distance method",
    task=Task,
    plan=plan,
    robots=("puma600",),
    check=check,
)
