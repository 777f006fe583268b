"""Platform orientations along a joint path: the exact FK followed from a known orientation, or the learnt FK."""

from __future__ import annotations

import numpy as np

from simbench.planners import learnt_fk
from simbench.robots import agile_eye


def platform(theta: np.ndarray, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The exact FK followed from the start orientation (N, 3, 3), and where it is undetermined (N,): on the type 2
    singular surface, where the orientation before is held."""
    rot = agile_eye.fk_track(theta, start)
    undetermined = ~np.isfinite(rot).all(axis=(1, 2))
    for k in np.flatnonzero(undetermined):
        rot[k] = rot[k - 1] if k else start
    return rot, undetermined


class Estimator:
    """Platform orientations along a stretch of joint path: the learnt FK of the working mode, or the exact FK
    followed continuously from the orientation `anchor` at the stretch's first sample."""

    def __init__(self, kind: str, mode: int):
        self.kind, self.mode = kind, mode
        self.network = learnt_fk.load() if kind == "network" else None

    def __call__(self, theta: np.ndarray, anchor: np.ndarray) -> np.ndarray:
        if self.network is not None:
            return self.network(theta, self.mode)
        return platform(theta, anchor)[0]

    def estimate(self, theta: np.ndarray, anchor: np.ndarray) -> tuple[np.ndarray, list | None]:
        """The orientations, as calling this gives them, and what `pull` reuses (the network's layers)."""
        if self.network is not None:
            return self.network.forward(theta, self.mode)
        return self(theta, anchor), None

    def pull(self, theta: np.ndarray, rot: np.ndarray, layers: list | None, torque: np.ndarray) -> np.ndarray:
        """torque^T (d omega / d theta) (N, 3) of the estimate, each at its own sample: the network's by reverse
        mode, or the exact FK's (A^-1 B, zero where A is singular)."""
        if self.network is not None:
            return self.network.rates_vjp(theta, self.mode, torque, layers, rot)
        rates = np.nan_to_num(agile_eye.platform_rates(theta, rot), nan=0.0, posinf=0.0, neginf=0.0)
        return np.einsum("nc,ncj->nj", torque, rates)
