"""Cartesian paths evaluated at a parameter s in [0, 1] proportional to arc length.

A path is a line, a circle arc or a composite of both (a weld seam, say). Each gives its points, its derivative
dp/ds and its length; planners pair a path with a time law s(t).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Line:
    """The straight segment from p0 to p1 (paper 000, eqs. 21-22: X = X_init + (X_goal - X_init) s)."""

    p0: np.ndarray
    p1: np.ndarray

    @property
    def length(self) -> float:
        """Arc length (m)."""
        return float(np.linalg.norm(np.asarray(self.p1) - np.asarray(self.p0)))

    def point(self, s: np.ndarray) -> np.ndarray:
        """Points (N, 3) at parameters s (N,)."""
        s = np.asarray(s, float)[:, None]
        return np.asarray(self.p0) + s * (np.asarray(self.p1) - np.asarray(self.p0))

    def tangent(self, s: np.ndarray) -> np.ndarray:
        """dp/ds (N, 3)."""
        s = np.asarray(s, float)
        return np.broadcast_to(np.asarray(self.p1) - np.asarray(self.p0), (s.size, 3)).copy()


@dataclass(frozen=True)
class Arc:
    """A circle arc: centre, radius, unit normal n, from angle theta0 to theta1 (rad) about n, measured from the
    unit vector `ref` in the circle's plane. Paper 002, eqs. 28-37."""

    center: np.ndarray
    radius: float
    normal: np.ndarray
    theta0: float
    theta1: float
    ref: np.ndarray

    @classmethod
    def from_plane(cls, center, radius: float, normal, theta0: float, theta1: float, ref=None) -> "Arc":
        """Build an arc, choosing `ref` perpendicular to the normal when it is not given."""
        n = np.asarray(normal, float)
        n = n / np.linalg.norm(n)
        if ref is None:
            seed = np.eye(3)[np.argmin(np.abs(n))]
            ref = np.cross(n, np.cross(seed, n))
        ref = np.asarray(ref, float) - np.dot(ref, n) * n
        ref = ref / np.linalg.norm(ref)
        return cls(np.asarray(center, float), float(radius), n, float(theta0), float(theta1), ref)

    @property
    def length(self) -> float:
        """Arc length (m)."""
        return self.radius * abs(self.theta1 - self.theta0)

    def _basis(self) -> tuple[np.ndarray, np.ndarray]:
        return self.ref, np.cross(self.normal, self.ref)

    def point(self, s: np.ndarray) -> np.ndarray:
        """Points (N, 3) at parameters s (N,)."""
        theta = self.theta0 + np.asarray(s, float) * (self.theta1 - self.theta0)
        e1, e2 = self._basis()
        return self.center + self.radius * (np.cos(theta)[:, None] * e1 + np.sin(theta)[:, None] * e2)

    def tangent(self, s: np.ndarray) -> np.ndarray:
        """dp/ds (N, 3)."""
        span = self.theta1 - self.theta0
        theta = self.theta0 + np.asarray(s, float) * span
        e1, e2 = self._basis()
        return self.radius * span * (-np.sin(theta)[:, None] * e1 + np.cos(theta)[:, None] * e2)


@dataclass(frozen=True)
class Composite:
    """Segments traversed in order, s shared out by arc length."""

    segments: tuple

    @property
    def length(self) -> float:
        """Arc length (m)."""
        return float(sum(seg.length for seg in self.segments))

    @property
    def bounds(self) -> np.ndarray:
        """The global s at which each segment starts, and 1 (len(segments) + 1,)."""
        lengths = np.array([seg.length for seg in self.segments])
        return np.concatenate([[0.0], np.cumsum(lengths)]) / lengths.sum()

    def _locate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Segment index and local parameter of each global s."""
        bounds = self.bounds
        s = np.clip(np.asarray(s, float), 0.0, 1.0)
        index = np.clip(np.searchsorted(bounds, s, side="right") - 1, 0, len(self.segments) - 1)
        local = (s - bounds[index]) / (bounds[index + 1] - bounds[index])
        return index, local

    def point(self, s: np.ndarray) -> np.ndarray:
        """Points (N, 3) at parameters s (N,)."""
        return self._gather(s, "point", scale=False)

    def tangent(self, s: np.ndarray) -> np.ndarray:
        """dp/ds (N, 3)."""
        return self._gather(s, "tangent", scale=True)

    def _gather(self, s: np.ndarray, method: str, scale: bool) -> np.ndarray:
        index, local = self._locate(s)
        out = np.empty((local.size, 3))
        total = self.length
        for i, seg in enumerate(self.segments):
            mask = index == i
            if mask.any():
                values = getattr(seg, method)(local[mask])
                out[mask] = values * (total / seg.length) if scale else values
        return out
