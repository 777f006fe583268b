"""Row-wise 3-vector products over the last axis, for the kinematics' per-sample arrays: NumPy's `np.cross`
without its overhead (it checks and moves axes on every call), which the planners' inner loops pay for."""

from __future__ import annotations

import numpy as np


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b over the last axis, broadcast."""
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def triple(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """a . (b x c) row by row (N,): the determinant of the 3 x 3 matrices with rows a, b, c."""
    return np.einsum("ni,ni->n", a, cross(b, c))
