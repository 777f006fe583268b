"""A bench's tasks: random lines and arcs for a robot, through, near and far from its singular set (i mod 3), each
drawn by its own generator (the suite's seed, the robot's name, i), so that more tasks keep the first ones.

Each passes through the tool's point at an anchor q_a (its end, where the set bounds the reach), LENGTH times the
reach on either side, the orientation at q_a held; the joints at its ends follow from q_a by damped Newton steps.
`through`: q_a on the set; `near`: q_a off it, its gap between the NEAR percentiles of the robot's gap; `far`: gap
at least the FAR percentile. A failed draw is drawn again, at most TRIES times; so is one whose anchor, start, goal
or a continuation step between puts two of the arm's geoms, or one and the floor, in contact as the derived scene
collides them (a pair already touching at the model's reference pose, qpos0 or a `home` keyframe, is excluded
there: robots.model_scene).

This is the benchmark's definition sb-1 (GENERATOR): a suite names the version its tasks are drawn by, and a change
to what a seed draws (a constant here, the seeding, the shipped arms' mappings) is a new version, drawn by a
generator of its own beside the old ones (VERSIONS), so that a leaderboard of sb-1 can be drawn again.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from simbench.commands.bench.robots import SINGULAR_TOL, BenchRobot
from simbench.core.errors import RunError
from simbench.core.forked import dealt
from simbench.maths.paths import Arc, Line
from simbench.maths.rotations import matrix_to_quat
from simbench.planners.resolved_rates import orientation_error, pose_jacobian, tool_pose

GENERATOR = "sb-1"  # the newest version of the benchmark's definition: a suite's default
KINDS = ("through", "near", "far")
NEAR = (2.0, 10.0)  # percentiles of the robot's gap: a `near` anchor's lies between
FAR = 50.0  # percentile of the robot's gap: a `far` anchor's is at least this
BAND_SAMPLES = 2000
LENGTH = (0.06, 0.15)  # share of the reach on either side of the anchor
RADIUS = (0.15, 0.35)  # share of the reach: an arc's radius
MARGIN = 0.1  # share of each joint range's width kept clear at either end
TOLERANCE = (1e-7, 1e-6)  # m, rad: the continuation's error at the start
STEPS = 60  # continuation steps from the anchor to either end
TRIES = 200  # draws a task may take: a self-collision refuses one too
MIN_DURATION = 1.0  # s
HOLD = 0.3  # s


@dataclass(frozen=True)
class Task:
    """One task: joints at the start and the end, the path (one segment as a scenario writes it, SI), the
    orientation held (quaternion w, x, y, z), the anchor and its gap, and the duration asked."""

    robot: str
    index: int
    kind: str
    shape: str
    start: tuple[float, ...]
    goal: tuple[float, ...]
    segment: dict
    orientation: tuple[float, ...]
    anchor: tuple[float, ...]
    anchor_gap: float
    length: float
    duration: float

    @property
    def id(self) -> str:
        return f"{self.robot}-t{self.index:04d}"


def draw(robot: BenchRobot, count: int, seed: int, version: str = GENERATOR) -> list[Task]:
    """The robot's first `count` tasks at `seed`, as benchmark version `version` (one of VERSIONS) draws them."""
    return [VERSIONS[version](robot, i, seed) for i in range(count)]


def draw_all(robots: Sequence[BenchRobot], count: int, seed: int, version: str = GENERATOR,
             workers: int = 1) -> list[list[Task]]:
    """draw's tasks of each robot, drawn by `workers` processes at once (forked: core.forked.dealt), each task by
    its own generator as draw draws it, so that any count of processes draws the same tasks; the first task in
    order that none of its draws found raises RunError, as draw raises it."""
    if workers > 1:  # what every task reads, made here once rather than in each process
        for robot in robots:
            robot.model_arm().contacts()
            bands(robot)
        if any(robot.singular is None for robot in robots):
            import scipy.optimize  # noqa: F401  (_on_set's minimize)
    drawn = dealt([(_drawn_or_error, (VERSIONS[version], robot, i, seed)) for robot in robots for i in range(count)],
                  workers, "drawing the bench's tasks")
    for task in drawn:
        if isinstance(task, RunError):
            raise task
    return [drawn[r * count:(r + 1) * count] for r in range(len(robots))]


def _drawn_or_error(generator: Callable[[BenchRobot, int, int], Task], robot: BenchRobot, index: int,
                    seed: int) -> Task | RunError:
    """The task, or the RunError that says none was found (returned, so that the first in order is raised)."""
    try:
        return generator(robot, index, seed)
    except RunError as err:
        return err


def draw_one(robot: BenchRobot, index: int, seed: int) -> Task:
    """Task `index` of the robot at `seed`; RunError where TRIES draws found none."""
    rng = np.random.default_rng([seed, zlib.crc32(robot.name.encode()), index])
    kind, shape = KINDS[index % 3], robot.shapes[(index // 3) % len(robot.shapes)]
    for _ in range(TRIES):
        task = _attempt(robot, index, kind, shape, rng)
        if task is not None:
            return task
    raise RunError(f"no {kind} {shape} found for {robot.name} in {TRIES} draws (task {index})")


VERSIONS: dict[str, Callable[[BenchRobot, int, int], Task]] = {"sb-1": draw_one}
"""Each version of the benchmark's definition simbench has, and its generator of one task (robot, index, seed)."""


def _attempt(robot: BenchRobot, index: int, kind: str, shape: str, rng: np.random.Generator) -> Task | None:
    arm = robot.model_arm()
    anchor = _anchor(robot, kind, rng)
    if anchor is None:
        return None
    (point,), (rot,) = tool_pose(arm, anchor[None])
    before, after = rng.uniform(*LENGTH, 2) * arm.reach
    if robot.boundary and kind != "far":
        after = 0.0
    segment, path = _path(point, before, after, shape, arm.reach, robot.plane, rng)
    samples = path.point(np.linspace(0, 1, 201))
    if robot.floor is not None and samples[:, 2].min() < robot.floor:
        return None
    u = before / (before + after)
    start, back = _follow(arm, anchor, path, np.linspace(u, 0.0, STEPS + 1)[1:], rot, robot.hold)
    if start is None:
        return None
    goal, ahead = (_follow(arm, anchor, path, np.linspace(u, 1.0, STEPS + 1)[1:], rot, robot.hold) if u < 1
                   else (anchor, []))
    if goal is None or not _clear(robot, np.array([anchor, *back, *ahead])):
        return None
    length = float(np.linalg.norm(np.diff(samples, axis=0), axis=1).sum())
    rot_start = rot if robot.hold else arm.tool_rotation(start[None])[0]
    return Task(robot.name, index, kind, shape, tuple(start.tolist()), tuple(goal.tolist()),
                segment, tuple(matrix_to_quat(rot_start[None])[0].tolist()), tuple(anchor.tolist()),
                float(robot.gap_of(anchor[None])[0]), length, max(MIN_DURATION, length / robot.speed))


def _ranges(arm) -> tuple[np.ndarray, np.ndarray]:
    low = np.where(np.isfinite(arm.lower), arm.lower, -np.pi)
    high = np.where(np.isfinite(arm.upper), arm.upper, np.pi)
    width = high - low
    return low + MARGIN * width, high - MARGIN * width


def _inside(arm, q: np.ndarray) -> bool:
    return bool(np.all(q >= arm.lower) and np.all(q <= arm.upper))


def _anchor(robot: BenchRobot, kind: str, rng: np.random.Generator) -> np.ndarray | None:
    """q_a for `kind` (the module's docstring), or None for a draw that found none."""
    arm = robot.model_arm()
    low, high = _ranges(arm)
    q = rng.uniform(low, high)
    near, far = bands(robot)
    if kind == "far":
        return q if robot.gap_of(q[None])[0] >= far else None
    singular = _on_set(robot, q)
    if singular is None or kind == "through":
        return singular
    target = rng.uniform(*near)
    v = rng.normal(size=arm.dof)
    v /= np.linalg.norm(v)
    lo, hi = 0.0, 0.05
    while robot.gap_of((singular + hi * v)[None])[0] < target:
        lo, hi = hi, 2 * hi
        if hi > 2.0:
            return None
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if robot.gap_of((singular + mid * v)[None])[0] < target else (lo, mid)
    near = singular + hi * v
    return near if _inside(arm, near) else None


def bands(robot: BenchRobot) -> tuple[tuple[float, float], float]:
    """The robot's near band and far threshold (rad): percentiles NEAR and FAR of its gap over BAND_SAMPLES
    configurations drawn at seed 0 (each robot's own: a rank_loss gap runs smaller than an angle's)."""
    if "bands" not in robot.cache:
        low, high = _ranges(robot.model_arm())
        gaps = robot.gap_of(np.random.default_rng(0).uniform(low, high, (BAND_SAMPLES, len(low))))
        near = np.percentile(gaps, NEAR)
        robot.cache["bands"] = ((float(near[0]), float(near[1])), float(np.percentile(gaps, FAR)))
    return robot.cache["bands"]


def _on_set(robot: BenchRobot, q: np.ndarray) -> np.ndarray | None:
    """q put on the robot's singular set: by the robot's own rule, or by minimising its rank_loss gap."""
    arm = robot.model_arm()
    if robot.singular is not None:
        q = robot.singular(q)
        return q if _inside(arm, q) else None
    from scipy.optimize import minimize

    low, high = arm.lower, arm.upper
    found = minimize(lambda x: float(robot.gap_of(np.clip(x, low, high)[None])[0]), q, method="Nelder-Mead",
                     options={"xatol": 1e-9, "fatol": 1e-10, "maxiter": 4000 * arm.dof})
    q = np.clip(found.x, low, high)
    return q if robot.gap_of(q[None])[0] < SINGULAR_TOL else None


def _path(point: np.ndarray, before: float, after: float, shape: str, reach: float, plane: bool,
          rng: np.random.Generator) -> tuple[dict, Line | Arc]:
    """A line or an arc through `point`, `before` and `after` (m) of it on either side (in the plane z = const
    where `plane`): its segment (as a scenario writes it, SI) and the path."""
    flat = np.array([1.0, 1.0, 0.0 if plane else 1.0])
    d = rng.normal(size=3) * flat
    d /= np.linalg.norm(d)
    if shape == "line":
        a, b = point - before * d, point + after * d
        return {"line": {"start": a.tolist(), "end": b.tolist()}}, Line(a, b)
    normal = np.array([0.0, 0.0, 1.0]) if plane else np.cross(d, rng.normal(size=3))
    normal /= np.linalg.norm(normal)
    radius = float(rng.uniform(*RADIUS) * reach)
    inward = np.cross(normal, d)  # in the plane, normal to the direction of travel at the point
    center = point + radius * inward
    ref = (point - center) / radius
    start, end = -before / radius, after / radius
    segment = {"arc": {"center": center.tolist(), "radius": radius, "normal": normal.tolist(), "start": start,
                       "end": end, "ref": ref.tolist()}}
    return segment, Arc.from_plane(center, radius, normal, start, end, ref)


def _follow(arm, q: np.ndarray, path, s: np.ndarray, rot: np.ndarray,
            hold: bool) -> tuple[np.ndarray | None, list[np.ndarray]]:
    """The joints at path(s[-1]), followed from q along path(s) by damped Newton steps (the orientation `rot` held
    where `hold`), and the joints at each step; None where the last point is not reached within TOLERANCE or a
    joint leaves its range."""
    q = q.copy()
    rows = 6 if hold else 3
    steps = []
    for k, point in enumerate(path.point(s)):
        last = k == len(s) - 1
        for _ in range(50 if last else 8):
            (at,), (turned,), (jac,) = pose_jacobian(arm, q[None])  # one pass: the error's and the step's
            error = point - at
            if hold:
                error = np.concatenate([error, orientation_error(rot, turned)])
            if np.linalg.norm(error[:3]) < TOLERANCE[0] and np.linalg.norm(error[3:]) < TOLERANCE[1]:
                break
            jac = jac[:rows]
            damping = 1e-6 if last else 1e-4
            q = q + jac.T @ np.linalg.solve(jac @ jac.T + damping * np.eye(rows), error)
        else:
            if last:
                return None, steps
        steps.append(q)
    return (q if _inside(arm, q) else None), steps


def _clear(robot: BenchRobot, q: np.ndarray) -> bool:
    """Whether no configuration of q (N, dof) puts two of the arm's geoms, or one and the floor, in contact, as its
    derived scene collides them (robots.contacts: the pairs touching at the reference pose excluded)."""
    contacts = robot.model_arm().contacts()
    return not any(contacts.at(row) for row in np.atleast_2d(q))
