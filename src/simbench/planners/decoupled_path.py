"""Paper 002's joint time histories for lines, circle arcs and composite paths of a decoupled arm (PUMA 600).

The tool follows lines and arcs (eqs. 23-37), its orientation held or slerped; the wrist centre is p - R TOOL.
  - q3 from the wrist centre's distance (eq. 9 as corrected: docs/papers/002-puma600.md, Errata), with
    v = tan(q3/2) the quadratic v^2 (C - A - K) + 2 B v + (A + C - K) = 0 (eqs. 12-14), its two roots the
    elbow's two sides;
  - q1 and q2 in closed form from eq. 1; q4, q5, q6 from the spherical wrist.

The configuration (puma600's docstring) is the task's or, with `configuration: auto`, the one of the 8 that keeps
the whole path inside the joint ranges and speed limits with the most margin (ours); none: refused, saying where.
The wrist follows its branch continuously through q5 = 0 (ours: a fixed wrist flag turns q4 and q6 by 180 deg in
one sample there). Every joint is made continuous and centred in its range by whole turns.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from itertools import product
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from simbench.api import Planner
from simbench.api.trajectory import JointTrajectory, control_grid
from simbench.core.errors import RunError
from simbench.maths.paths import Arc, Composite, Line
from simbench.planners import rate
from simbench.robots import puma600
from simbench.robots.puma600 import A2, A3, D3, D4, JOINTS, LOWER, QD_MAX, TOOL, UPPER
from simbench.scenario.schema import Angle, Direction, Orientation, Position, PositiveLength, SimbenchModel

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
    """A circle arc (eqs. 28-37): angles about the normal from `ref` (default: world x on the plane, or y)."""

    center: Position
    radius: PositiveLength
    normal: Direction
    start: Angle
    end: Angle
    ref: Direction | None = None

    @model_validator(mode="after")
    def _proper_arc(self) -> "ArcSpec":
        self._check_angles(self.start)
        return self

    def _check_angles(self, start: float | None) -> None:
        """Different start and end angles (start None: known only once the arc is placed), ref off the normal."""
        if start is not None and abs(self.end - start) < 1e-9:
            raise ValueError("an arc needs different start and end angles")
        if self.ref is not None and abs(np.dot(self.ref, self.normal)) > 1 - 1e-6:
            raise ValueError("ref must not be parallel to the normal")

    def default_ref(self) -> list[float]:
        """`ref`, or where it is left out world x (world y for a normal near x), which Arc projects onto the plane."""
        if self.ref is not None:
            return list(self.ref)
        return [1.0, 0.0, 0.0] if abs(self.normal[0]) < 0.99 else [0.0, 1.0, 0.0]

    def build(self) -> Arc:
        """The path segment."""
        return Arc.from_plane(self.center, self.radius, self.normal, self.start, self.end, self.default_ref())


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
    """Which of the 8 inverse-kinematics solutions the arm starts in (puma600 module docstring)."""

    arm: Literal["righty", "lefty"] = "righty"
    elbow: Literal["up", "down"] = "up"
    wrist: Literal["noflip", "flip"] = "noflip"

    def flags(self) -> np.ndarray:
        """The (arm, elbow, wrist) signs."""
        return np.array([puma600.ARM[self.arm], puma600.ELBOW[self.elbow], puma600.WRIST[self.wrist]])

    def label(self) -> str:
        """arm/elbow/wrist, as the report and the CLI print it."""
        return f"{self.arm}/{self.elbow}/{self.wrist}"


CONFIGURATIONS = tuple(Configuration(arm=a, elbow=e, wrist=w)
                       for a, e, w in product(puma600.ARM, puma600.ELBOW, puma600.WRIST))


class Task(SimbenchModel):
    """`task:` of paper 002's method: the tool's path, its orientation, the arm's configuration."""

    path: list[Segment] = Field(min_length=1)
    orientation: Orientation
    orientation_end: Orientation | None = None
    configuration: Literal["auto"] | Configuration = Field(
        "auto", description="'auto': of the 8 IK solutions, the one that keeps the whole path inside the joint "
                            "ranges and speed limits with the most margin; or {arm, elbow, wrist}")

    def build_path(self) -> Composite:
        """The tool's path as one composite, s shared by arc length."""
        return Composite(tuple(seg.build() for seg in self.path))

    def rotations(self, s: np.ndarray) -> np.ndarray:
        """Tool orientation R (N, 3, 3) along the path: held, or slerped to orientation_end."""
        start = self.orientation.matrix()
        if self.orientation_end is None:
            return np.broadcast_to(start, (len(s), 3, 3)).copy()
        from scipy.spatial.transform import Rotation, Slerp  # imported when planned, not when registered

        ends = Rotation.from_matrix([start, self.orientation_end.matrix()])
        return Slerp([0.0, 1.0], ends)(np.clip(s, 0.0, 1.0)).as_matrix()


def q3_from_distance(k: np.ndarray, h_sign: np.ndarray) -> np.ndarray:
    """q3 from the squared wrist distance K (eqs. 12-19): the root of eq. 14 whose h has the sign h_sign; NaN where
    it has none (eq. 15 as printed is wrong: docs/papers/002-puma600.md, Errata). Roots as q / a and c / q, free
    of cancellation."""
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
    """Joints (N, 6), not unwrapped, for tool points (N, 3) and orientations (N, 3, 3) in flags (3,) or (N, 3)."""
    flags = np.broadcast_to(flags, (len(points), 3))
    wrist = points - rotations @ TOOL
    q123 = arm_angles(wrist, flags[:, 0], flags[:, 1])
    return np.concatenate([q123, puma600.wrist_angles(q123, rotations, flags[:, 2])], axis=1)


def _wrapped(d: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * d))


def _bridge(values: np.ndarray, bad: np.ndarray) -> np.ndarray:
    """values (N, m) with the rows where `bad` replaced by linear interpolation between the good rows."""
    if not bad.any() or bad.all():
        return values
    good = np.flatnonzero(~bad)
    out = values.copy()
    for j in range(values.shape[1]):
        out[bad, j] = np.interp(np.flatnonzero(bad), good, values[good, j])
    return out


def _singular_wrist(q: np.ndarray) -> np.ndarray:
    """Samples (N,) where the wrist is exactly singular (q5 = 0: wrist_angles sets the undefined q4 to 0)."""
    return np.abs(np.sin(q[:, 4])) < 1e-12


def _pin_wrist(q: np.ndarray) -> np.ndarray:
    """q (N, 6) with q4 at exactly singular samples carried over from the sample before, q6 keeping q4 + q6: the
    wrist passes q5 = 0 without a jump."""
    bad = _singular_wrist(q)
    if not bad.any():
        return q
    last = np.maximum.accumulate(np.where(~bad, np.arange(len(q)), 0))
    out = q.copy()
    out[bad, 3] = q[last[bad], 3]
    out[bad, 5] = q[bad, 5] + q[bad, 3] - out[bad, 3]
    return out


def wrist_branch(q: np.ndarray) -> np.ndarray:
    """The wrist sign (N,) relative to q's (+1 keep, -1 the other solution (q4 + pi, -q5, q6 + pi)) that keeps the
    wrist continuous. The swap is an isometry of wrapped angles, so the branch is a parity: no loop."""
    w = _pin_wrist(q)[:, 3:6]
    other = w + np.stack([np.full(len(w), np.pi), -2 * w[:, 1], np.full(len(w), np.pi)], axis=1)
    stay = np.sum(_wrapped(w[1:] - w[:-1]) ** 2, axis=1)
    swap = np.sum(_wrapped(other[1:] - w[:-1]) ** 2, axis=1)
    parity = np.concatenate([[0], np.cumsum(swap < stay)]) % 2
    return 1.0 - 2.0 * parity


def continuous(q: np.ndarray) -> np.ndarray:
    """Every joint unwrapped, then moved by whole turns to centre its path's span in its range."""
    q = np.unwrap(q, axis=0)
    centre = 0.5 * (q.min(axis=0) + q.max(axis=0))
    return q + 2 * np.pi * np.round((0.5 * (LOWER + UPPER) - centre) / (2 * np.pi))


@dataclass(frozen=True)
class Candidate:
    """One configuration's joint path on the control grid (`flags` (N, 3) a sample) and its margins: `room` (6,)
    each joint's least distance inside its range (rad), `speed` (6,) its largest speed over its limit."""

    configuration: Configuration
    flags: np.ndarray
    q: np.ndarray
    qd: np.ndarray

    @cached_property
    def room(self) -> np.ndarray:
        return np.minimum(self.q.min(axis=0) - LOWER, UPPER - self.q.max(axis=0))

    @cached_property
    def speed(self) -> np.ndarray:
        return np.abs(self.qd).max(axis=0) / QD_MAX

    @cached_property
    def margin(self) -> float:
        """The least margin, each as a share: of the joint's range, of its speed limit. >= 0 within limits."""
        return float(min((self.room / (UPPER - LOWER)).min(), (1.0 - self.speed).min()))

    def worst(self, t: np.ndarray, s: np.ndarray) -> str:
        """Where and by how much the path breaks its worst limit (a candidate with margin < 0), in words."""
        room_share, speed_share = self.room / (UPPER - LOWER), 1.0 - self.speed
        if room_share.min() <= speed_share.min():
            j = int(np.argmin(room_share))
            low, high = LOWER[j] - self.q[:, j], self.q[:, j] - UPPER[j]
            k = int(np.argmax(np.maximum(low, high)))
            bound, limit = ("lower", LOWER[j]) if low[k] > high[k] else ("upper", UPPER[j])
            return (f"{JOINTS[j]} is asked for {np.rad2deg(self.q[k, j]):.1f} deg at t = {t[k]:.3f} s (s = "
                    f"{s[k]:.3f}), {np.rad2deg(-self.room[j]):.1f} deg beyond its {bound} limit "
                    f"{np.rad2deg(limit):.0f} deg")
        j = int(np.argmin(speed_share))
        k = int(np.argmax(np.abs(self.qd[:, j])))
        return (f"{JOINTS[j]} is asked for {np.rad2deg(abs(self.qd[k, j])):.0f} deg/s at t = {t[k]:.3f} s (s = "
                f"{s[k]:.3f}), {self.speed[j]:.2f} times its speed limit {np.rad2deg(QD_MAX[j]):.0f} deg/s")

    def summary(self) -> dict:
        """The report's line on this candidate."""
        return {"configuration": self.configuration.label(), "within_limits": self.margin >= 0,
                "margin": self.margin, "range_room_min_deg": float(np.rad2deg(self.room.min())),
                "speed_ratio_max": float(self.speed.max())}


def candidate(task: Task, path: Composite, s: np.ndarray, ds: np.ndarray, configuration: Configuration) -> Candidate:
    """One configuration's joint path, continuous and centred; speeds from dq/ds on each sample's own branch
    (eqs. 38-40 differentiate the same solution)."""
    points, rotations = path.point(s), task.rotations(s)
    start = configuration.flags()
    flags = np.tile(start, (len(s), 1))
    flags[:, 2] *= wrist_branch(solve(points, rotations, start))
    q = _pin_wrist(solve(points, rotations, flags))
    qd = rate(lambda x: solve(path.point(x), task.rotations(x), flags), s, np.ones(6, bool)) * ds[:, None]
    # where the wrist changes branch or is exactly singular, the differences straddle two branches: bridged
    change = np.diff(flags[:, 2]) != 0
    unsure = _singular_wrist(q) | np.concatenate([change, [False]]) | np.concatenate([[False], change])
    return Candidate(configuration, flags, continuous(q), _bridge(qd, unsure))


def choose(task: Task, path: Composite, t: np.ndarray, s: np.ndarray, ds: np.ndarray) -> tuple[Candidate, dict]:
    """The task's configuration, or with 'auto' the one with the most margin (RunError if none is within limits);
    and the report's words on the choice."""
    if task.configuration != "auto":
        chosen = candidate(task, path, s, ds, task.configuration)
        return chosen, {"chosen": chosen.configuration.label(), "by": "the task"}
    ranked = sorted((candidate(task, path, s, ds, c) for c in CONFIGURATIONS), key=lambda c: -c.margin)
    best = ranked[0]
    if best.margin < 0:
        raise RunError(f"no configuration of the 8 keeps this path within the joint ranges and speed limits; in the "
                       f"nearest, {best.configuration.label()}, {best.worst(t, s)}")
    j, k = int(np.argmin(best.room)), int(np.argmax(best.speed))
    why = (f"the most margin of the {sum(c.margin >= 0 for c in ranked)} of 8 that keep within the limits: every "
           f"joint at least {np.rad2deg(best.room[j]):.1f} deg inside its range ({JOINTS[j]} the nearest), the "
           f"fastest at {best.speed[k]:.2f} of its speed limit ({JOINTS[k]})")
    return best, {"chosen": best.configuration.label(), "by": "auto", "why": why,
                  "candidates": [c.summary() for c in ranked]}


def _require_reach(task: Task, path: Composite, t: np.ndarray, s: np.ndarray) -> None:
    """RunError at the first sample whose wrist centre is out of reach (in every configuration alike)."""
    bad = np.isnan(solve(path.point(s), task.rotations(s), CONFIGURATIONS[0].flags())).any(axis=1)
    if bad.any():
        k = int(np.argmax(bad))
        point = path.point(s[k:k + 1])[0]
        raise RunError(f"the path leaves the arm's reach at s = {s[k]:.4f} (t = {t[k]:.3f} s), tool point "
                       f"[{point[0]:.4f}, {point[1]:.4f}, {point[2]:.4f}] m: its wrist centre cannot be reached")


def segment_waypoints(path: Composite, s: np.ndarray, q_ref: np.ndarray) -> tuple[dict, ...]:
    """Each segment's ends: s, the tool point, and the joints at the control sample at or after it."""
    bounds = path.bounds
    wp_q = q_ref[np.minimum(np.searchsorted(s, bounds), len(s) - 1)]
    return tuple({"s": float(b), "X": x.tolist(), "q": qq.tolist()}
                 for b, x, qq in zip(bounds, path.point(bounds), wp_q))


def _branch_changes(chosen: Candidate, t: np.ndarray, s: np.ndarray) -> list[dict]:
    """Where the wrist changes branch through q5 = 0, and to which."""
    flips = np.flatnonzero(np.diff(chosen.flags[:, 2])) + 1
    return [{"t": float(t[k]), "s": float(s[k]), "to": "noflip" if chosen.flags[k, 2] > 0 else "flip"} for k in flips]


def join_gap(segments: list) -> tuple[str, str] | None:
    """(field, what is wrong) of the first path segment that does not start where the one before ends, or None."""
    for i in range(1, len(segments)):
        gap = np.linalg.norm(segments[i].point(np.array([0.0]))[0] - segments[i - 1].point(np.array([1.0]))[0])
        if gap > _JOIN_TOL:
            return f"task.path[{i}]", f"starts {gap * 1e3:.3f} mm from where task.path[{i - 1}] ends"
    return None


class DecoupledPath(Planner):
    name = "decoupled_path"
    description = "paper 002: lines, circle arcs and composite tool paths by the wrist-distance method"
    task = Task
    robots = ("puma600",)

    def plan(self, scenario, robot, dt: float) -> JointTrajectory:
        """Solve the tool path at every control sample by paper 002's method."""
        task = scenario.task
        path = task.build_path()
        law = scenario.timing.law_fn()
        t = control_grid(law.duration, scenario.timing.hold, dt)
        s, ds = law(t, order=1)
        _require_reach(task, path, t, s)
        chosen, choice = choose(task, path, t, s, ds)
        tool_ref = path.point(s)
        speed = np.linalg.norm(np.gradient(tool_ref, t, axis=0), axis=1)
        info = {
            "method": "paper 002: q3 from the wrist distance (eqs. 9-19, corrected), q1 and q2 closed form, "
                      "spherical wrist",
            "configuration": choice,
            "wrist_branch_changes": _branch_changes(chosen, t, s),
            "segments": [("line" if seg.line else "arc") for seg in task.path],
            "path_length": path.length,
            "tool_speed_max": float(speed.max()),
        }
        return JointTrajectory(t=t, s=s, q_ref=chosen.q, qd_ref=chosen.qd, tool_ref=tool_ref,
                               waypoints=segment_waypoints(path, s, chosen.q), info=info)

    def random_task(self, robot, random: np.random.RandomState) -> dict | None:
        """A random reachable line, torch at a random orientation (random_tasks.puma_line)."""
        from simbench.planners import random_tasks  # imported when drawn, not when registered

        return random_tasks.first(lambda: random_tasks.puma_line(random), "PUMA line")

    def check(self, scenario, robot) -> tuple[str, str] | None:
        """Segments must join end to start, and every segment's ends must be within the wrist's reach."""
        task = scenario.task
        segments = [seg.build() for seg in task.path]
        broken = join_gap(segments)
        if broken is not None:
            return broken
        bounds = Composite(tuple(segments)).bounds
        for i, seg in enumerate(segments):
            ends = np.array([0.0, 1.0])
            q = solve(seg.point(ends), task.rotations(bounds[i:i + 2]), CONFIGURATIONS[0].flags())
            for j, name in enumerate(("start", "end")):
                if np.isnan(q[j]).any():
                    point = seg.point(ends[j:j + 1])[0]
                    kind = "line" if task.path[i].line else "arc"
                    return (f"task.path[{i}].{kind}", f"its {name} [{point[0]:.4f}, {point[1]:.4f}, "
                            f"{point[2]:.4f}] m is outside the workspace (the wrist centre cannot be reached)")
        return None


PLANNER = DecoupledPath()
