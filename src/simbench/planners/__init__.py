"""The shipped planners (simbench.api.Planner), one module each, what they share, and random tasks for them.

Imports the stages before it: core, maths, api, robots and scenario."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def rate(evaluate: Callable[[np.ndarray], np.ndarray], s: np.ndarray, revolute: np.ndarray,
         step: float = 1e-6) -> np.ndarray:
    """dq/ds (N, n) of q(s) = evaluate(s) by central differences (one-sided at s = 0 and 1); revolute joints'
    differences modulo one turn. `evaluate` works sample by sample, so a caller can pin each sample's branch."""
    hi = np.clip(s + step, 0.0, 1.0)
    lo = np.clip(s - step, 0.0, 1.0)
    dq = evaluate(hi) - evaluate(lo)
    dq[:, revolute] = np.angle(np.exp(1j * dq[:, revolute]))
    return dq / (hi - lo)[:, None]
