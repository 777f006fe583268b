"""Random tasks nobody tuned for, as plain scenario documents (SI units): what the tests and benchmarks draw
(fixed seeds) to check the planners beyond the papers' own cases, through the same loading as a user's file."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from simbench.robots import puma600

# A box around the PUMA 600's reach (its wrist centre reaches up to a2 + d4 + a3 ~ 0.88 m from the shoulder).
_PUMA_BOX = (np.array([-0.7, -0.7, -0.6]), np.array([0.7, 0.7, 0.5]))
_PUMA_SPEED = 0.2  # m/s: the tool's mean speed along a random line (the shipped seams run at 0.1-0.25)


def _puma_reaches(points: np.ndarray, rot: np.ndarray) -> bool:
    """Whether the wrist centre of every tool point, at orientation rot, is within the arm's reach (Craig's
    IK in any one configuration: the reach does not depend on it)."""
    q = puma600.ik(points, np.broadcast_to(rot, (len(points), 3, 3)), np.array([-1.0, 1.0, 1.0]))
    return not np.isnan(q).any()


def _torch(rng: np.random.Generator, cone: float | None) -> Rotation:
    """A uniform random orientation; with `cone` (rad), one whose torch axis (z of the tool) is within that angle
    of straight down, uniform on the cap, turned uniformly about the axis."""
    if cone is None:
        return Rotation.random(random_state=rng)
    tilt = np.arccos(rng.uniform(np.cos(cone), 1.0))  # uniform on the spherical cap
    axis = Rotation.from_euler("z", rng.uniform(0, 2 * np.pi)).apply([1.0, 0.0, 0.0])
    down = Rotation.from_euler("x", np.pi)  # z of the tool along -z of the world
    return Rotation.from_rotvec(tilt * axis) * down * Rotation.from_euler("z", rng.uniform(0, 2 * np.pi))


def puma_lines(n: int, seed: int, cone: float | None = None) -> list[dict]:
    """n `decoupled_path` scenarios: a line between two uniform points of a box around the PUMA's reach, the
    torch at a uniform random orientation (or within `cone` rad of straight down, as a welding torch is held),
    every point of the line reachable (by its wrist centre), the configuration left to the planner (`auto`);
    quintic time law at a mean tool speed of 0.2 m/s (at least 1 s)."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        a, b = rng.uniform(*_PUMA_BOX, size=(2, 3))
        rot = _torch(rng, cone)
        length = float(np.linalg.norm(b - a))
        if length < 0.05 or not _puma_reaches(a + np.linspace(0, 1, 101)[:, None] * (b - a), rot.as_matrix()):
            continue
        w, x, y, z = np.roll(rot.as_quat(), 1)
        out.append({
            "name": f"puma_line_{seed}_{len(out)}",
            "robot": "puma600", "planner": "decoupled_path",
            "task": {"path": [{"line": {"start": a.tolist(), "end": b.tolist()}}],
                     "orientation": {"convention": "quat", "value": [float(w), float(x), float(y), float(z)]}},
            "timing": {"law": "quintic", "duration": round(max(1.0, length / _PUMA_SPEED), 3), "hold": 0.3},
        })
    return out
