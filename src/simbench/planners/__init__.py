"""The shipped planners (simbench.api.Planner), one module each, and what they share.

A planner is a task schema (the `task:` section of a scenario), a `plan` method and, optionally, a `check`
that rejects a valid-looking task that means nothing (a zero-length path) before anything runs, and
`decorations`: what of the task the video should show (obstacle regions, say).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np



def rate(evaluate: Callable[[np.ndarray], np.ndarray], s: np.ndarray, revolute: np.ndarray,
         step: float = 1e-6) -> np.ndarray:
    """dq/ds (N, n) of a joint-space method q(s) by central differences (one-sided at s = 0 and 1).

    `evaluate` maps an array of s to configurations, sample by sample, so a caller can pin each sample's
    branch; differences of revolute joints are taken modulo one turn.
    """
    hi = np.clip(s + step, 0.0, 1.0)
    lo = np.clip(s - step, 0.0, 1.0)
    dq = evaluate(hi) - evaluate(lo)
    dq[:, revolute] = np.angle(np.exp(1j * dq[:, revolute]))
    return dq / (hi - lo)[:, None]
