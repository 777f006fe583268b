"""Random tasks nobody tuned for, as plain scenario documents (SI units): what the tests and benchmarks draw
(fixed seeds) to check the planners beyond the papers' own cases, through the same loading as a user's file, and
what the planners' `random_task` hooks draw for an environment's resets. Each generator takes a NumPy Generator
or RandomState (`uniform`, `normal`, `random`, `choice`), so the same draws serve both."""

from __future__ import annotations

from typing import Union

import numpy as np
from scipy.spatial.transform import Rotation

from simbench.core.errors import RunError
from simbench.maths.rotations import rotation_angle
from simbench.maths.timing import TimeLaw
from simbench.planners import learnt_fk
from simbench.robots import agile_eye, puma600

Random = Union[np.random.Generator, np.random.RandomState]
ATTEMPTS = 10_000  # draws before a generator gives up (none comes near it on the shipped robots)

# A box around the PUMA 600's reach (its wrist centre reaches up to a2 + d4 + a3 ~ 0.88 m from the shoulder).
_PUMA_BOX = (np.array([-0.7, -0.7, -0.6]), np.array([0.7, 0.7, 0.5]))
_PUMA_SPEED = 0.2  # m/s: the tool's mean speed along a random line (the shipped seams run at 0.1-0.25)

# Agile Eye tasks (benchmarks/bench_agile_eye_planning): the shipped avoidance scenario's margins.
AGILE_EYE_MARGIN = np.deg2rad(10.0)  # from the singular curves
AGILE_EYE_CLEARANCE = np.deg2rad(1.0)  # outside the obstacles
AGILE_EYE_KCI_MIN = 0.1
AGILE_EYE_ENDS = np.deg2rad(15.0)  # the ends' least angle to the singular curves
AGILE_EYE_ENDS_KCI = 0.15  # and their least KCI
AGILE_EYE_RADII = np.deg2rad([4.0, 10.0])


def _puma_reaches(points: np.ndarray, rot: np.ndarray) -> bool:
    """Whether the wrist centre of every tool point, at orientation rot, is within the arm's reach (Craig's
    IK in any one configuration: the reach does not depend on it)."""
    q = puma600.ik(points, np.broadcast_to(rot, (len(points), 3, 3)), np.array([-1.0, 1.0, 1.0]))
    return not np.isnan(q).any()


def _torch(rng: Random, cone: float | None) -> Rotation:
    """A uniform random orientation; with `cone` (rad), one whose torch axis (z of the tool) is within that angle
    of straight down, uniform on the cap, turned uniformly about the axis."""
    if cone is None:
        return Rotation.random(random_state=rng)
    tilt = np.arccos(rng.uniform(np.cos(cone), 1.0))  # uniform on the spherical cap
    axis = Rotation.from_euler("z", rng.uniform(0, 2 * np.pi)).apply([1.0, 0.0, 0.0])
    down = Rotation.from_euler("x", np.pi)  # z of the tool along -z of the world
    return Rotation.from_rotvec(tilt * axis) * down * Rotation.from_euler("z", rng.uniform(0, 2 * np.pi))


def puma_line(rng: Random, cone: float | None = None) -> dict | None:
    """One draw of puma_lines: the `task` and `timing` sections of a random line, or None where the draw is
    rejected (too short, or out of reach)."""
    a, b = rng.uniform(*_PUMA_BOX, size=(2, 3))
    rot = _torch(rng, cone)
    length = float(np.linalg.norm(b - a))
    if length < 0.05 or not _puma_reaches(a + np.linspace(0, 1, 101)[:, None] * (b - a), rot.as_matrix()):
        return None
    return {"task": {"path": [{"line": {"start": a.tolist(), "end": b.tolist()}}],
                     "orientation": {"convention": "quat", "value": rot.as_quat(scalar_first=True).tolist()}},
            "timing": {"law": "quintic", "duration": round(max(1.0, length / _PUMA_SPEED), 3), "hold": 0.3}}


def puma_lines(n: int, seed: int, cone: float | None = None) -> list[dict]:
    """n `decoupled_path` scenarios: a line between two uniform points of a box around the PUMA's reach, the
    torch at a uniform random orientation (or within `cone` rad of straight down, as a welding torch is held),
    every point of the line reachable (by its wrist centre), the configuration left to the planner (`auto`);
    quintic time law at a mean tool speed of 0.2 m/s (at least 1 s)."""
    rng = np.random.default_rng(seed)
    out: list[dict] = []
    while len(out) < n:
        drawn = puma_line(rng, cone)
        if drawn is not None:
            out.append({"name": f"puma_line_{seed}_{len(out)}", "robot": "puma600", "planner": "decoupled_path",
                        **drawn})
    return out


def first(draw, what: str) -> dict:
    """draw() until it gives a task (not None), at most ATTEMPTS times; RunError past that."""
    for _ in range(ATTEMPTS):
        found = draw()
        if found is not None:
            return found
    raise RunError(f"no random {what} found in {ATTEMPTS} draws")


def orientation_doc(rot: np.ndarray) -> dict:
    """A rotation matrix as a scenario's orientation (a scalar-first quaternion)."""
    return {"convention": "quat", "value": Rotation.from_matrix(rot).as_quat(scalar_first=True).tolist()}


def _plain_joints(start: np.ndarray, goal: np.ndarray, s: np.ndarray) -> np.ndarray:
    """The Agile Eye's plain joint path (working mode 0) from start to goal, at path fractions s."""
    theta0 = agile_eye.ik(start, 0)[0]
    theta1 = theta0 + np.angle(np.exp(1j * (agile_eye.ik(goal, 0)[0] - theta0)))
    return theta0 + s[:, None] * (theta1 - theta0)


def plain_path_crosses(start: np.ndarray, goal: np.ndarray, samples: int = 2000) -> bool:
    """Whether det A changes sign along the Agile Eye's plain joint path from start to goal."""
    theta = _plain_joints(start, goal, np.linspace(0.0, 1.0, samples))
    det = np.linalg.det(agile_eye.jacobians(theta, agile_eye.fk_track(theta, start))[0])
    return bool(np.any(np.sign(det[1:]) * np.sign(det[:-1]) < 0))


def _plain_platform(start: np.ndarray, goal: np.ndarray, samples: int = 1001) -> np.ndarray:
    """The exact FK of the plain joint path on the 4-5-6-7 time law, followed from the start, at `samples` times."""
    s = TimeLaw("4567", 1.0)(np.linspace(0.0, 1.0, samples), order=0)[0]
    return agile_eye.fk_track(_plain_joints(start, goal, s), start)


def agile_eye_task(rng: Random, count: int) -> dict | None:
    """One draw of agile_eye_tasks with `count` obstacles: an `avoidance_4567` task section, or None where the
    draw is rejected (ends near a singular curve or of low KCI, a plain path crossing the type 2 surface, no
    obstacle placed)."""
    ends = learnt_fk.sample_workspace(2, rng)
    if (agile_eye.axis_gaps(ends).min() < AGILE_EYE_ENDS or plain_path_crosses(*ends)
            or agile_eye.kci(agile_eye.ik(ends, 0), ends).min() < AGILE_EYE_ENDS_KCI):
        return None
    path = _plain_platform(*ends)
    edges = np.linspace(0.2, 0.8, count + 1)
    obstacles = []
    for k in range(count):
        for _ in range(100):
            radius = rng.uniform(*AGILE_EYE_RADII)
            at = path[int(round(rng.uniform(edges[k], edges[k + 1]) * (len(path) - 1)))]
            axis = rng.normal(size=3)
            nudge = Rotation.from_rotvec(axis / np.linalg.norm(axis) * rng.uniform(0, radius / 2)).as_matrix()
            center = at @ nudge
            away = rotation_angle(np.broadcast_to(center, (2, 3, 3)), ends).min()
            if away > radius + AGILE_EYE_CLEARANCE + np.deg2rad(5):
                obstacles.append({"name": f"obstacle{k + 1}", "center": orientation_doc(center),
                                  "radius": float(radius)})
                break
    if len(obstacles) < count:
        return None
    return {"start": orientation_doc(ends[0]), "goal": orientation_doc(ends[1]), "obstacles": obstacles,
            "singularity_clearance": float(AGILE_EYE_MARGIN), "obstacle_clearance": float(AGILE_EYE_CLEARANCE),
            "kci_min": AGILE_EYE_KCI_MIN, "avoidance": {"window": 1.0, "max_windows": 4, "estimator": "network"}}


def agile_eye_tasks(n: int, seed: int) -> list[dict]:
    """n `avoidance_4567` task sections (SI) within the learnt FK's workspace whose plain path runs into 1 or 2
    obstacles (task k: 1 + k mod 2) and does not cross the type 2 surface: each obstacle a ball (AGILE_EYE_RADII)
    near the plain path's platform in its own part of [0.2 T, 0.8 T], clear of both ends; margins as the shipped
    scenario's."""
    rng = np.random.default_rng(seed)
    out: list[dict] = []
    while len(out) < n:
        drawn = agile_eye_task(rng, 1 + len(out) % 2)
        if drawn is not None:
            out.append(drawn)
    return out
