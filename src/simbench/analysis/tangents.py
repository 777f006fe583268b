"""The unit tangent of a sampled path, whole or a window of rows at a time: the direction the tool's lag is
measured along."""

from __future__ import annotations

import numpy as np

from simbench.api.trajectory import gradient_rows
from simbench.core import windowed
from simbench.core.windowed import norms


def along_path(points: np.ndarray) -> np.ndarray:
    """Unit tangent (N, 3) of a sampled path; where it rests, the direction it last moved in (or first will)."""
    return Tangents(points).rows(0, len(points))


class Tangents:
    """`along_path` of a planned path, a window of rows at a time: each row's step from the rows either side of
    it (np.gradient's, the same numbers as over the whole path), and where the path rests the direction it last
    moved in, carried from the windows before, or the one it first will, found ahead."""

    def __init__(self, points: np.ndarray):
        self.points = points
        self.floor = 1e-12 * max(1.0, max(float(points.max(initial=0.0)), -float(points.min(initial=0.0))))
        self.last: np.ndarray | None = None  # the unit step where the path last moved, in the windows before
        self.first: np.ndarray | None = None  # where it first moves, once looked for

    def _steps(self, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The steps of rows lo..hi-1, their lengths, and whether the path moves there."""
        step = gradient_rows(self.points, lo, hi)
        norm = norms(step)
        return step, norm, norm > self.floor

    def rows(self, lo: int, hi: int) -> np.ndarray:
        """The unit tangents at rows lo..hi-1 (windows asked for in order)."""
        step, norm, moving = self._steps(lo, hi)
        index = np.maximum.accumulate(np.where(moving, np.arange(len(moving)), -1))
        before = self.last
        if index[-1] >= 0:
            self.last = step[index[-1]] / norm[index[-1]]
        if index[0] >= 0:  # the window moves at its first row: every row has a step of its own or before it
            return step[index] / norm[index][:, None]
        seen = index >= 0  # the rows before the window's first move take the last before it, or the first after
        out = np.empty_like(step)
        out[seen] = step[index[seen]] / norm[index[seen]][:, None]
        out[~seen] = before if before is not None else self._first_move(lo)
        return out

    def _first_move(self, lo: int) -> np.ndarray:
        """The unit step where the path first moves at or after row lo (no move before it), zero if it never
        does."""
        if self.first is None:
            self.first = np.zeros(3)
            for a in range(lo, len(self.points), windowed.LONG):
                step, norm, moving = self._steps(a, min(a + windowed.LONG, len(self.points)))
                if moving.any():
                    k = int(np.argmax(moving))
                    self.first = step[k] / norm[k]
                    break
        return self.first
