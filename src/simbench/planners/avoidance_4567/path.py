"""The 4-5-6-7 joint path (eqs. 8-10) and the smooth bumps (windows) that bend it."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from simbench.maths.timing import TimeLaw
from simbench.planners.avoidance_4567.task import Task
from simbench.robots import agile_eye


def bump(tau: np.ndarray, order: int = 0) -> np.ndarray:
    """b(tau) = 256 tau^4 (1 - tau)^4 on [0, 1], zero outside, or its derivative of the given order (in tau)."""
    coef = 256 * np.polynomial.polynomial.polypow([0.0, 1.0, -1.0], 4)  # 256 (tau - tau^2)^4
    inside = (tau > 0) & (tau < 1)
    return np.where(inside, np.polynomial.polynomial.polyval(tau, np.polynomial.polynomial.polyder(coef, order)), 0.0)


@dataclass(frozen=True)
class Window:
    """One bump: start time, length T*, direction (alpha, beta, gamma), amplitude L (rad)."""

    t0: float
    length: float
    direction: np.ndarray
    amplitude: float

    def offset(self, t: np.ndarray, order: int = 0) -> np.ndarray:
        """Its contribution (N, 3) to the joint angles, or their derivative of the given order in t."""
        tau = (t - self.t0) / self.length
        return (self.amplitude * bump(tau, order) / self.length**order)[:, None] * self.direction


@dataclass(frozen=True)
class Plan:
    """The base 4-5-6-7 path plus its windows."""

    theta_init: np.ndarray
    theta_final: np.ndarray
    law: TimeLaw
    windows: tuple[Window, ...] = ()

    def theta(self, t: np.ndarray, order: int = 0) -> np.ndarray:
        """Joint angles (N, 3) at times t, or their time derivative of the given order (up to 3)."""
        out = self.law(t, order=order)[order][:, None] * (self.theta_final - self.theta_init)
        if order == 0:
            out = out + self.theta_init
        for w in self.windows:
            out = out + w.offset(t, order)
        return out

    def with_window(self, window: Window) -> Plan:
        """This plan with one more window."""
        return replace(self, windows=self.windows + (window,))


def plain_plan(task: Task, law: TimeLaw) -> Plan:
    """The 4-5-6-7 joint path (eqs. 8-10) between the IK of start and goal, each joint the shorter way round."""
    theta_init = agile_eye.ik(task.start.matrix(), task.working_mode)[0]
    theta_goal = agile_eye.ik(task.goal.matrix(), task.working_mode)[0]
    theta_final = theta_init + np.angle(np.exp(1j * (theta_goal - theta_init)))  # the shorter way round
    return Plan(theta_init, theta_final, law)
