"""Global search for an orientation path in SO(3), for when bending a joint path around a constraint fails:
RRT-Connect in OMPL's SO3StateSpace, shortcut, then every corner rounded so that the timed path is smooth to the
third derivative.

`slack(rot)` gives, for orientations (N, 3, 3), the worst margin of each (>= 0: all kept). OMPL checks states
`step` apart, so a 1-Lipschitz clearance can dip by step / 2 between them: the caller pads its margins by that.

Corners: near inner waypoint R_k, over |x| <= d_k of the summed geodesic angle, the path is
R_k Exp(x ((1 - h) e_{k-1} + h e_k)), h = S((x + d_k) / (2 d_k)) with S the 4-5-6-7 polynomial (paper 003, eq. 8):
it meets both geodesics with equal derivatives up to the third and passes through R_k.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, replace

import numpy as np
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou
from scipy.spatial.transform import Rotation

from simbench.maths.rotations import axis_rotation, matrix_to_quat, quat_to_matrix
from simbench.maths.timing import TimeLaw

Slack = Callable[[np.ndarray], np.ndarray]
_SEED = 1  # OMPL's random seed, set before every search: the same task gives the same path, run after run
_SHORTCUTS = 5  # rounds of OMPL's vertex reduction after the rope shortcut
_HALVINGS = 10  # a corner's blend is tried at half the shorter segment, then halved up to this many times
_S = TimeLaw("4567", 1.0)  # S(tau) = 35 tau^4 - 84 tau^5 + 70 tau^6 - 20 tau^7 (paper 003, eq. 8)


@dataclass(frozen=True)
class OrientationPath:
    """Geodesics between waypoints (n + 1, 3, 3) with rounded corners: each segment's unit axis e_k (n, 3) in its
    first waypoint's frame, its angle a_k (n,), each inner corner's half-width d_k (n - 1,) in rad of sigma."""

    waypoints: np.ndarray
    axes: np.ndarray
    angles: np.ndarray
    blends: np.ndarray

    @classmethod
    def through(cls, waypoints: np.ndarray, blends: np.ndarray | None = None) -> OrientationPath:
        """The path through the waypoints, with these blends (default: none, sharp corners)."""
        vec = Rotation.from_matrix(np.swapaxes(waypoints[:-1], 1, 2) @ waypoints[1:]).as_rotvec()
        angles = np.linalg.norm(vec, axis=1)
        blends = np.zeros(len(waypoints) - 2) if blends is None else np.asarray(blends, float)
        return cls(waypoints, vec / angles[:, None], angles, blends)

    @property
    def length(self) -> float:
        """The summed geodesic angle of the segments (rad): the range of sigma."""
        return float(self.angles.sum())

    def __call__(self, sigma: np.ndarray) -> np.ndarray:
        """Orientations (N, 3, 3) at sigma (N,) in [0, length]."""
        axes, knots = self.axes, np.concatenate([[0.0], np.cumsum(self.angles)])
        sigma = np.clip(np.asarray(sigma, float), 0.0, knots[-1])
        k = np.clip(np.searchsorted(knots, sigma, side="right") - 1, 0, len(axes) - 1)
        anchor, vec = k, (sigma - knots[k])[:, None] * axes[k]
        for j, d in enumerate(self.blends, start=1):  # inner corner j, at knots[j]
            x = sigma - knots[j]
            near = np.abs(x) < d
            h = _S(x[near] / (2 * d) + 0.5, order=0)[0][:, None]
            anchor = np.where(near, j, anchor)
            vec[near] = x[near][:, None] * ((1 - h) * axes[j - 1] + h * axes[j])
        return self.waypoints[anchor] @ _exp(vec)


def _exp(vec: np.ndarray) -> np.ndarray:
    """Exp of rotation vectors (N, 3): rotation matrices (N, 3, 3)."""
    angle = np.linalg.norm(vec, axis=1)
    axis = np.where(angle[:, None] > 0, vec / np.maximum(angle, 1e-300)[:, None], [1.0, 0.0, 0.0])
    return axis_rotation(axis, angle)


class _Checker(ob.StateValidityChecker):
    """OMPL's validity test: the orientation keeps every (padded) margin."""

    def __init__(self, si: ob.SpaceInformation, slack: Slack):
        super().__init__(si)
        self.slack = slack

    def isValid(self, state) -> bool:  # noqa: N802 (OMPL's name)
        rot = quat_to_matrix(np.array([state.w, state.x, state.y, state.z]))
        return bool(self.slack(rot)[0] >= 0.0)


@contextmanager
def _silent():
    """Hold back OMPL's messages (it logs each search, and an error when its seed is set again)."""
    level = ou.getLogLevel()
    ou.setLogLevel(ou.LogLevel.LOG_NONE)
    try:
        yield
    finally:
        ou.setLogLevel(level)


def _space_information(slack: Slack, step: float) -> tuple[ob.SO3StateSpace, ob.SpaceInformation]:
    """OMPL's SO(3) with `slack` as its validity test, checked along a motion at states `step` apart."""
    space = ob.SO3StateSpace()
    si = ob.SpaceInformation(space)
    si.setStateValidityChecker(_Checker(si, slack))
    # OMPL's SO(3) distance is half the rotation angle and its extent pi / 2: step / pi of it is `step`.
    si.setStateValidityCheckingResolution(step / np.pi)
    si.setup()
    return space, si


def _state(space: ob.SO3StateSpace, rot: np.ndarray):
    """An OMPL state of `space` at orientation rot (3, 3)."""
    state = space.allocState()
    state.w, state.x, state.y, state.z = matrix_to_quat(rot)[0]
    return state


def _shortened(si: ob.SpaceInformation, path) -> np.ndarray:
    """The quaternions (n + 1, 4) of OMPL's path after its rope shortcut and vertex reduction."""
    simplifier = og.PathSimplifier(si)
    simplifier.ropeShortcutPath(path)
    for _ in range(_SHORTCUTS):
        simplifier.reduceVertices(path)
    return np.array([[s.w, s.x, s.y, s.z] for s in path.getStates()])


def search(slack: Slack, start: np.ndarray, goal: np.ndarray, time_budget: float,
           step: float) -> tuple[np.ndarray | None, str]:
    """Shortened waypoints (n + 1, 3, 3) from start to goal whose geodesics keep slack >= 0 at states `step` apart,
    and OMPL's status; None if RRT-Connect finds none within time_budget seconds."""
    with _silent():
        ou.RNG.setSeed(_SEED)
        space, si = _space_information(slack, step)
        setup = og.SimpleSetup(si)
        ends = [_state(space, rot) for rot in (start, goal)]
        setup.setStartAndGoalStates(*ends)
        setup.setPlanner(og.RRTConnect(si))
        status = setup.solve(time_budget)
        if not setup.haveExactSolutionPath():
            return None, status.asString()
        quat = _shortened(si, setup.getSolutionPath())
    return quat_to_matrix(quat), status.asString()


def smooth(waypoints: np.ndarray, slack: Slack, step: float) -> OrientationPath:
    """The waypoints' path with each corner rounded by the widest blend that keeps slack >= 0; a corner where none
    fits stays a kink, which the caller's check of the timed path reports."""
    path = OrientationPath.through(waypoints)
    knots = np.concatenate([[0.0], np.cumsum(path.angles)])
    blends = path.blends.copy()
    for j in range(1, len(waypoints) - 1):
        widest = min(path.angles[j - 1], path.angles[j]) / 2
        for d in widest * 0.5 ** np.arange(_HALVINGS + 1):
            blends[j - 1] = d
            trial = replace(path, blends=blends)
            sigma = np.linspace(knots[j] - d, knots[j] + d, max(int(np.ceil(8 * d / step)), 2) + 1)
            if slack(trial(sigma)).min() >= 0.0:
                break
        else:
            blends[j - 1] = 0.0
    return replace(path, blends=blends)
