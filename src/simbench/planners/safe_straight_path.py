"""Paper 000's safe straight paths for the 4-DOF spherical arm (eqs. 21-34, flowchart Fig. 10).

The tool follows the line between the tool points of q_init and q_goal (eqs. 21-22), q2 linear (eq. 24); q1, q3,
q4 follow (eqs. 23, 25, 26), and where q4 would be negative q2 moves instead (eq. 27). Of the two branches (eq. 28)
the rule that reproduces Table 2: keep q1 continuous unless that breaks the q3 limits on the path; then take the
forward branch (q3 <= 90 deg) after the start. A path leaving the workspace gets a new initial q3 (Fig. 8,
eqs. 30-34). The method is solved at every control sample, not only at its nd points.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np
from pydantic import Field

from simbench.api import REVOLUTE, Planner
from simbench.api.trajectory import JointTrajectory, control_grid
from simbench.core.errors import RunError
from simbench.planners import rate
from simbench.robots.spherical_arm import D1, D4, KINDS, LOWER, UPPER, fk
from simbench.scenario.schema import JointVector, SimbenchModel

_AXIS_TOL = 1e-9  # m: a line passing this close to the lift axis crosses it (q1 keeps its value across)
_LIMIT_TOL = 1e-12
_CHECK_SAMPLES = 4001  # path samples on which the branch rule and the workspace test are decided


class Task(SimbenchModel):
    """`task:` of paper 000's straight path: the initial and goal configurations and the method's settings."""

    start: JointVector
    goal: JointVector
    nd: int = Field(11, ge=2, le=100000, description="number of method points printed as waypoints (Table 2: 11)")
    workspace_repair: bool = Field(True, description="make a new initial q3 when the path leaves the workspace")


@dataclass(frozen=True)
class Line:
    """One run of the method: the configurations, their tool points, the branch choices, and its check-grid
    geometry (_check_geometry) cached."""

    q_init: np.ndarray
    q_goal: np.ndarray
    x_init: np.ndarray
    x_goal: np.ndarray
    backward_start: bool
    flip_at: float | None
    forward_only: bool
    _checked: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def points(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Line points X(s) (eqs. 21-22) and the linear q2(s) (eq. 24)."""
        return np.ascontiguousarray(self.coordinates(s).T), self.lift(s)

    def coordinates(self, s: np.ndarray) -> np.ndarray:
        """x, y, z of the line points X(s) as rows (3, N) (faster than an (N, 1) by (3,) broadcast)."""
        return self.x_init[:, None] + (self.x_goal - self.x_init)[:, None] * s

    def lift(self, s: np.ndarray) -> np.ndarray:
        """The linear q2(s) (eq. 24)."""
        return self.q_init[1] + s * (self.q_goal[1] - self.q_init[1])

    def backward(self, s: np.ndarray) -> np.ndarray:
        """Whether each sample takes the backward branch (q3 > 90 deg, eq. 28)."""
        if self.forward_only:
            return np.full(s.shape, self.backward_start) & (s == 0)
        flipped = np.zeros(s.shape, bool) if self.flip_at is None else s >= self.flip_at
        return flipped ^ self.backward_start


def _azimuth_of_travel(x: np.ndarray, y: np.ndarray, d: np.ndarray, line: Line) -> np.ndarray:
    """atan2(y, x) of each point (eq. 23); on the lift axis itself (d = 0), the direction the line heads in."""
    azimuth = np.arctan2(y, x)
    heading = line.x_goal[:2] - line.x_init[:2]
    azimuth[d < 1e-15] = np.arctan2(heading[1], heading[0])
    return azimuth


def _geometry(line: Line, s: np.ndarray) -> dict[str, np.ndarray]:
    """The method's branch-free values at s (eqs. 23-27): z, q2, q4, the forward azimuth and elevation, where eq. 27
    holds q4 at 0 (`repaired`) and the unrepaired pivot height."""
    x, y, z = line.coordinates(s)
    d = np.hypot(x, y)
    h_lin = z - line.lift(s) - D1
    q4 = np.hypot(d, h_lin) - D4  # eq. 26
    repaired = q4 < -_LIMIT_TOL
    h = h_lin.copy()
    h[repaired] = np.sqrt(np.clip(D4**2 - d[repaired] ** 2, 0.0, None))  # eq. 27: q4 = 0, q2 moves
    q4 = np.clip(q4, 0.0, None)
    q4[repaired] = 0.0
    return {"z": z, "q2": z - D1 - h, "q4": q4, "azimuth": _azimuth_of_travel(x, y, d, line),
            "elevation": np.arctan2(h, d), "repaired": repaired, "h_lin": h_lin}  # eq. 25


def _configurations(geometry: dict[str, np.ndarray], backward: np.ndarray) -> np.ndarray:
    """Joint values (N, 4) on the given branches (eq. 28), q1 not yet unwrapped."""
    azimuth, elevation = geometry["azimuth"], geometry["elevation"]
    return np.stack([np.where(backward, azimuth - np.pi, azimuth), geometry["q2"],
                     np.where(backward, np.pi - elevation, elevation), geometry["q4"]], axis=-1)


def _solve(line: Line, s: np.ndarray, backward: np.ndarray) -> np.ndarray:
    """Joint values at path parameters s on the given branches (eqs. 23-28), q1 not yet unwrapped."""
    return _configurations(_geometry(line, s), backward)


def _pinned(line: Line, s: np.ndarray, q: np.ndarray) -> np.ndarray:
    """q with its samples at s = 0 set to the initial configuration itself (in place)."""
    q[s == 0] = line.q_init
    return q


def evaluate(line: Line, s: np.ndarray) -> np.ndarray:
    """Configurations (N, 4) at path parameters s; s = 0 is the initial configuration itself."""
    s = np.asarray(s, float)
    q = _pinned(line, s, _solve(line, s, line.backward(s)))
    q[:, 0] = np.unwrap(np.concatenate([[line.q_init[0]], q[:, 0]]))[1:]  # q1 continuous from q1_init
    return q


def derivative(line: Line, s: np.ndarray) -> np.ndarray:
    """dq/ds (N, 4), each sample differenced on its own branch; a difference that straddles the lift axis
    crossing takes the other branch past it, as the plan does there, so that q1 stays continuous."""
    s = np.asarray(s, float)
    backward = line.backward(s)

    def solve(x: np.ndarray) -> np.ndarray:
        if line.flip_at is None or line.forward_only:
            return _solve(line, x, backward)
        return _solve(line, x, backward ^ ((x >= line.flip_at) != (s >= line.flip_at)))

    return rate(solve, s, np.array(KINDS) == REVOLUTE)


def build(q_init: np.ndarray, q_goal: np.ndarray) -> Line:
    """Set up the method for q_init -> q_goal and decide its branches by the rule in the module docstring."""
    q_init, q_goal = np.asarray(q_init, float), np.asarray(q_goal, float)
    x_init, x_goal = fk(q_init)[0], fk(q_goal)[0]
    u0, du = x_init[:2], x_goal[:2] - x_init[:2]
    flip_at = None
    if du @ du > 0:
        s_star = -(u0 @ du) / (du @ du)
        if 0 < s_star < 1 and np.linalg.norm(u0 + s_star * du) <= _AXIS_TOL:
            flip_at = float(s_star)
    # The start's branch: the one whose q1 is continuous with q1_init as the tool leaves the start point.
    leaving = u0 if np.hypot(*u0) > 1e-15 else du
    backward_start = bool(np.cos(np.arctan2(leaving[1], leaving[0]) - q_init[0]) < 0)
    line = Line(q_init, q_goal, x_init, x_goal, backward_start, flip_at, forward_only=False)
    grid = _check_grid()
    if line.backward(grid[1:]).any():
        q3 = _checked_configurations(line)[:, 2]
        if np.any((q3 < LOWER[2] - _LIMIT_TOL) | (q3 > UPPER[2] + _LIMIT_TOL)):
            line = replace(line, forward_only=True)
    return line


@lru_cache(maxsize=8)
def _check_grid(nd: int = 11) -> np.ndarray:
    """The samples the branch rule and workspace test are decided on (read-only, cached): even ones and nd's."""
    grid = np.union1d(np.linspace(0.0, 1.0, _CHECK_SAMPLES), np.linspace(0.0, 1.0, nd))
    grid.flags.writeable = False
    return grid


def _check_geometry(line: Line, nd: int = 11) -> dict[str, np.ndarray]:
    """_geometry on the check grid of nd, solved once per line (read-only) for build and exit_reasons."""
    if nd not in line._checked:
        geometry = _geometry(line, _check_grid(nd))
        for value in geometry.values():
            value.flags.writeable = False
        line._checked[nd] = geometry
    return line._checked[nd]


def _checked_configurations(line: Line, nd: int = 11) -> np.ndarray:
    """Configurations on the check grid of nd on the line's branches, q1 not unwrapped; s = 0 is q_init."""
    s = _check_grid(nd)
    return _pinned(line, s, _configurations(_check_geometry(line, nd), line.backward(s)))


def _limit_tests(q: np.ndarray) -> list[tuple[np.ndarray, str]]:
    """(where it breaks, which) for each limit of q2, q3, q4 but q3's lower one (the flowchart tests it)."""
    tests = []
    for j, name in ((1, "q2"), (2, "q3"), (3, "q4")):
        if j != 2:
            tests.append((q[:, j] < LOWER[j] - _LIMIT_TOL, f"{name} below its lower limit"))
        tests.append((q[:, j] > UPPER[j] + _LIMIT_TOL, f"{name} above its upper limit"))
    return tests


def _eq27_jumps(geometry: dict[str, np.ndarray]) -> np.ndarray:
    """Where eq. 27 makes q2 and q3 step (N,): the q4 = 0 region's boundaries below the pivot (h < 0)."""
    rep = geometry["repaired"]
    edge = np.flatnonzero(rep[1:] != rep[:-1])
    outside = np.where(rep[edge], edge + 1, edge)  # the unrepaired sample of each boundary pair
    jump = np.zeros(rep.shape, bool)
    jump[outside[geometry["h_lin"][outside] < 0]] = True
    return jump


def exit_reasons(line: Line, nd: int = 11) -> list[dict]:
    """Where and why the path leaves the workspace (Fig. 10's test), first s of each; empty if it does not.

    The flowchart's third test is garbled (it fails case 1's start, which the paper says is inside); in its place:
    any joint limit broken, and eq. 27's jump below the pivot (case 4's printed start).
    """
    s, geometry = _check_grid(nd), _check_geometry(line, nd)
    q = _checked_configurations(line, nd)
    dq3 = line.q_goal[2] - line.q_init[2]
    tests = [((line.q_init[2] > np.pi / 2) & (dq3 > 0) & (geometry["z"] < D1), "q3_init > 90 deg, dq3 > 0 and z < d1"),
             (q[:, 2] < LOWER[2] - _LIMIT_TOL, "q3 < -75 deg"),
             *_limit_tests(q),
             (_eq27_jumps(geometry), "eq. 27 jump: the tool leaves the q4 = 0 region below the pivot (q2 and q3 step)")]
    reasons = [{"s": float(s[np.argmax(mask)]), "condition": condition} for mask, condition in tests if np.any(mask)]
    return sorted(reasons, key=lambda r: r["s"])


def tangent_q3(line: Line) -> dict[str, float]:
    """The two new initial q3 offsets of Fig. 8 (eqs. 30-33): S (small) and B (big), NaN if none."""
    d = np.linalg.norm(line.x_goal - line.x_init)
    di, dg = D4 + line.q_init[3], D4 + line.q_goal[3]
    dci, dcg = np.sqrt(di**2 - D4**2), np.sqrt(dg**2 - D4**2)
    with np.errstate(invalid="ignore"):
        a1 = np.arcsin(D4 / dg)
        a2 = np.arccos((d**2 + dg**2 - di**2) / (2 * d * dg))
        out = {}
        for name, angle in (("S", a1 - a2), ("B", a1 + a2)):
            ad2 = d**2 + (dci + dcg) ** 2 - 2 * d * (dci + dcg) * np.cos(angle)  # eq. 32
            out[name] = float(np.arccos((2 * di**2 - ad2) / (2 * di**2)))  # eq. 33
    return out


def repair(line: Line, nd: int) -> tuple[Line, dict]:
    """New initial q3 = q3_init + sign(dq3) q3_S, else q3_B (eq. 34); RunError if neither keeps the path inside."""
    offsets = tangent_q3(line)
    sign = np.sign(line.q_goal[2] - line.q_init[2]) or 1.0
    tried = []
    for name in ("S", "B"):
        if np.isnan(offsets[name]):
            tried.append(f"{name}: the tangent triangle of Fig. 8 has no solution")
            continue
        q_init = line.q_init.copy()
        q_init[2] += sign * offsets[name]
        if not LOWER[2] <= q_init[2] <= UPPER[2]:
            tried.append(f"{name}: new q3_init = {np.rad2deg(q_init[2]):.4f} deg is outside the q3 range")
            continue
        candidate = build(q_init, line.q_goal)
        reasons = exit_reasons(candidate, nd)
        if not reasons:
            info = {"q3_S": offsets["S"], "q3_B": offsets["B"], "chosen": name, "q3_init_new": float(q_init[2])}
            return candidate, info
        tried.append(f"{name}: new q3_init = {np.rad2deg(q_init[2]):.4f} deg still leaves ({reasons[0]['condition']})")
    raise RunError("the straight path leaves the workspace and the new initial q3 of Fig. 8 cannot repair it: "
                   + "; ".join(tried))


def waypoints(line: Line, nd: int) -> tuple[dict, ...]:
    """The method's nd points as Table 2 prints them: X and q, q1 in [0, 2 pi), SI units."""
    s = np.linspace(0.0, 1.0, nd)
    x, _ = line.points(s)
    q = evaluate(line, s)
    q[:, 0] = np.mod(q[:, 0], 2 * np.pi)
    return tuple({"s": float(sk), "X": xk.tolist(), "q": qk.tolist()} for sk, xk, qk in zip(s, x, q))


def _info(line: Line, reasons: list[dict], repair_info: dict | None) -> dict:
    """The plan's info: the method's ends, its branch choices, and the workspace test and repair."""
    return {
        "method": "paper 000: safe straight path (eqs. 21-29), new initial q3 by Fig. 8 (eqs. 30-34)",
        "q_init": line.q_init.tolist(),
        "q_goal": line.q_goal.tolist(),
        "x_init": line.x_init.tolist(),
        "x_goal": line.x_goal.tolist(),
        "branch": {"start": "backward" if line.backward_start else "forward",
                   "lift_axis_crossing_s": line.flip_at,
                   "forward_from_first_point": line.forward_only},
        "workspace_exit": reasons,
        "workspace_repair": repair_info,
    }


def _moved_start(given: Line, line: Line, reasons: list[dict], chosen: str) -> str:
    """The warning that the repaired plan no longer starts where the scenario said (Fig. 8's own choice)."""
    return (f"the straight path from the task's start leaves the workspace ({reasons[0]['condition']} at s = "
            f"{reasons[0]['s']:.4f}); the plan starts instead from Fig. 8's new initial q3 = "
            f"{np.rad2deg(line.q_init[2]):.4f} deg ({chosen}; the task's {np.rad2deg(given.q_init[2]):.4f} deg), "
            f"the tool's start {1e3 * np.linalg.norm(line.x_init - given.x_init):.1f} mm from the task's")


class SafeStraightPath(Planner):
    name = "safe_straight_path"
    description = "paper 000: straight tool path between two configurations, with workspace repair"
    task = Task
    robots = ("spherical_arm",)

    def plan(self, scenario, robot, dt: float) -> JointTrajectory:
        """Paper 000's method on the scenario's start and goal, solved at every control sample."""
        task = scenario.task
        line = build(np.array(task.start), np.array(task.goal))
        reasons = exit_reasons(line, task.nd)
        repair_info = None
        warnings = []
        if reasons and task.workspace_repair:
            given = line
            line, repair_info = repair(line, task.nd)
            warnings.append(_moved_start(given, line, reasons, repair_info["chosen"]))
        elif reasons:
            warnings.append("the straight path leaves the workspace (workspace_repair is off): "
                            + "; ".join(f"{r['condition']} at s = {r['s']:.4f}" for r in reasons))
        law = scenario.timing.law_fn()
        t = control_grid(law.duration, scenario.timing.hold, dt)
        s, ds = law(t, order=1)
        return JointTrajectory(t=t, s=s, q_ref=evaluate(line, s), qd_ref=derivative(line, s) * ds[:, None],
                               tool_ref=line.points(s)[0], waypoints=waypoints(line, task.nd),
                               info=_info(line, reasons, repair_info), warnings=tuple(warnings))

    def check(self, scenario, robot) -> tuple[str, str] | None:
        """A goal whose tool point is the start's gives no line to follow."""
        if np.linalg.norm(fk(np.array(scenario.task.goal)) - fk(np.array(scenario.task.start))) < 1e-9:
            return "task.goal", "its tool point equals the start's: a zero-length path"
        return None


PLANNER = SafeStraightPath()
