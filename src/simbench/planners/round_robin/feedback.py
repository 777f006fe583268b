"""Closing the loop at each grip (regrip_feedback): the gripping arm's references re-solved for the point it
really holds (see simbench.planners.round_robin's docstring)."""

from __future__ import annotations

import numpy as np

from simbench.api.trajectory import Switch
from simbench.maths.timing import TimeLaw
from simbench.planners.round_robin.paths import BLOCK, Orientations
from simbench.planners.round_robin.search import Hold
from simbench.planners.round_robin.task import Motion
from simbench.robots import rsmg

EASE = 0.1  # s: a grip's revised hold blends in from the old one over this time
_QUINTIC = TimeLaw("quintic", 1.0)  # a 0-to-1 blend: 0 before 0, 1 after 1, zero rate and acceleration at both


class RegripFeedback:
    """At a grip during the run, the arm's references up to its next grip re-solved for the point it really gripped.
    A change ends by the arm's next grip, so none touches the rows a later one reads."""

    def __init__(self, motion: Motion, s: np.ndarray, q_ref: np.ndarray, holds: list[Hold], grid: np.ndarray,
                 dt: float, n_swing: int):
        self.rot, self.q_ref, self.dt, self.n_swing = Orientations(motion, s), q_ref, dt, n_swing
        rows = len(q_ref)

        def row(step: int) -> int:  # a schedule step's control row (the end of the reference past the schedule)
            return min(int(round(grid[step] / dt)), rows) if step < grid.size else rows

        # (arm, grip row) -> its release row and the arm's next grip row (the end of the reference if none)
        self.release: dict[tuple[int, int], tuple[int, int]] = {}
        for arm in {h.arm for h in holds}:
            own = sorted((h for h in holds if h.arm == arm), key=lambda h: h.start)
            for h, after in zip(own, own[1:] + [None]):
                if h.start > 0:
                    self.release[arm, row(h.start)] = row(h.end), rows if after is None else row(after.start)

    def __call__(self, switch: Switch, model, data, k: int):
        if not switch.active:
            return None
        arm = switch.detail["arm"] - 1
        k_release, k_next = self.release[arm, k]
        tip = data.site(f"em{arm + 1}_tip").xpos
        point = data.body("rotor").xmat.reshape(3, 3).T @ (tip / np.linalg.norm(tip))  # in the rotor's frame
        theta, gamma = self._ik(arm, point, k, k_release)
        if not (np.isfinite(theta).all() and np.isfinite(gamma).all()):
            return None  # the point leaves the arm's reach before its release: keep the plan
        columns = [arm, rsmg.ARMS + arm]
        old = self.q_ref[k:k_release][:, columns]
        theta = np.unwrap(theta)
        theta += 2 * np.pi * np.round((old[0, 0] - theta[0]) / (2 * np.pi))
        change = np.stack([theta, gamma], axis=1) - old
        ease = _QUINTIC(np.arange(k_release - k) * self.dt / EASE, order=0)[0]
        swing = self.q_ref[k_release:min(k_release + self.n_swing, k_next)][:, columns]
        out = _QUINTIC(1 - np.arange(len(swing)) / max(self.n_swing, 1), order=0)[0]
        q = np.concatenate([old + ease[:, None] * change, swing + out[:, None] * change[-1:]])
        return k, columns, q

    def _ik(self, arm: int, point: np.ndarray, a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
        """rsmg.ik of the arm holding `point` (rotor frame) at rows a..b-1, BLOCK rows at a time: the same numbers
        (each row's own), without a long hold's orientations and the IK's temporaries for all its rows at once."""
        parts = [rsmg.ik(arm, self.rot.rows(lo, min(lo + BLOCK, b)) @ point) for lo in range(a, b, BLOCK)]
        parts = parts or [rsmg.ik(arm, np.zeros((0, 3)))]
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
