"""Time laws s(t): how the path parameter s goes from 0 to 1 over a duration T, with its derivatives.

Each law starts and ends at rest. The polynomial laws are written in tau = t / T:

    cubic        3 tau^2 - 2 tau^3                          (paper 002, eqs. 24-25 as its page's Errata fix)
    quintic      10 tau^3 - 15 tau^4 + 6 tau^5              (zero velocity and acceleration at both ends)
    4567         35 tau^4 - 84 tau^5 + 70 tau^6 - 20 tau^7  (paper 003: zero velocity, acceleration and jerk)
    trapezoidal  constant acceleration for a fraction f of T, cruise, constant deceleration for f of T
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.polynomial import polynomial as P

_POLYNOMIALS = {
    "cubic": np.array([0, 0, 3, -2], float),
    "quintic": np.array([0, 0, 0, 10, -15, 6], float),
    "4567": np.array([0, 0, 0, 0, 35, -84, 70, -20], float),
}
LAWS = (*_POLYNOMIALS, "trapezoidal")


@dataclass(frozen=True)
class TimeLaw:
    """s(t) on [0, duration], constant (s = 0 before, s = 1 after) outside it."""

    name: str
    duration: float
    accel_fraction: float = 0.25

    def __post_init__(self):
        if self.name not in LAWS:
            raise ValueError(f"unknown time law {self.name!r}: expected one of {', '.join(LAWS)}")
        if not self.duration > 0:
            raise ValueError("duration must be positive")
        if not 0 < self.accel_fraction <= 0.5:
            raise ValueError("accel_fraction must lie in (0, 0.5]")

    def __call__(self, t: np.ndarray, order: int = 2) -> np.ndarray:
        """Rows s, ds/dt, ..., d^order s/dt^order at times t: shape (order + 1, N)."""
        t = np.asarray(t, float)
        tau = np.clip(t / self.duration, 0.0, 1.0)
        inside = (t > 0) & (t < self.duration)
        if self.name == "trapezoidal":
            rows = self._trapezoid(tau, order)
        else:
            coef = _POLYNOMIALS[self.name]
            rows = np.array([P.polyval(tau, P.polyder(coef, k)) for k in range(order + 1)])
        scale = self.duration ** -np.arange(order + 1.0)
        out = rows * scale[:, None]
        out[1:, ~inside] = 0.0
        return out

    def _trapezoid(self, tau: np.ndarray, order: int) -> np.ndarray:
        """The trapezoidal law in tau; peak rate 1 / (1 - f) and acceleration 1 / (f (1 - f))."""
        f = self.accel_fraction
        v = 1.0 / (1.0 - f)
        a = v / f
        rising, falling = tau < f, tau > 1.0 - f
        rest = 1.0 - tau
        s = np.where(rising, 0.5 * a * tau**2, np.where(falling, 1.0 - 0.5 * a * rest**2, v * (tau - 0.5 * f)))
        ds = np.where(rising, a * tau, np.where(falling, a * rest, v))
        dds = np.where(rising, a, np.where(falling, -a, 0.0))
        return np.array([s, ds, dds, np.zeros_like(tau)][: order + 1])
