"""What a planner hands to the simulator: joint references on the control grid, and what the plan means."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from simbench.api.events import Violation


@dataclass(frozen=True)
class Switch:
    """At time t, turn the equality constraint `equality` on or off. Turning one on first sets its reference to
    the bodies' current relative pose (so they do not snap together). `servo_group`: the actuator group that holds
    the released part, on while the constraint is off and off while it is on. `detail` goes to the report."""

    t: float
    equality: str
    active: bool
    servo_group: int | None = None
    detail: dict = field(default_factory=dict)


PER_SAMPLE = ("t", "s", "q_ref", "qd_ref", "tool_ref")  # JointTrajectory's arrays of a row a sample, but `series`
# The series (N, 4) of the tool orientations a plan asks for, unit quaternions w x y z: where a plan has it, the
# tool's orientation is a promise, held to analysis.orientation_tolerance (a derived arm's tool_orientation_error).
ORIENTATION_REF = "tool_orientation_ref"


@dataclass(frozen=True)
class JointTrajectory:
    """Joint references sampled at every control step, t = 0, dt, ..., T + hold.

    `s` is the path parameter behind each sample, `tool_ref` the tool point the plan means to be at (on the
    commanded path), `waypoints` the method's own points (paper 000's nd points, say), `info` the choices the
    planner made, for the report, and `series` any further per-sample references (the platform orientation a
    parallel mechanism should reach, say), written to timeseries.npz. `switches` are the equality constraints the
    plan turns on and off (an electromagnet's grip), and `initial` the qpos of joints the robot cannot assemble
    from its actuated joints alone (a free rotor), by joint name. `feedback`, where the method closes a loop, is
    called by the simulator after each switch it applies during the run, as feedback(switch, model, data, k) at
    row k (reading the references from row k on); it returns None, or (k0, columns, q): new references q for those
    joints from row k0 on (an RSMG arm re-solving its hold for the point it really gripped). `violations` are the
    promises the planner knows its plan breaks (it ends away from the task's goal, say), each a
    simbench.api.Violation (or the dict {"kind", "message", ...} it reads as): the run cannot end `ok`.
    """

    t: np.ndarray
    s: np.ndarray
    q_ref: np.ndarray
    qd_ref: np.ndarray
    tool_ref: np.ndarray
    waypoints: tuple[dict, ...] = ()
    info: dict = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    series: dict = field(default_factory=dict)
    switches: tuple[Switch, ...] = ()
    initial: dict = field(default_factory=dict)
    feedback: Callable | None = None
    violations: tuple[Violation | dict, ...] = ()

    @property
    def dt(self) -> float:
        """Control period (s)."""
        return float(self.t[1] - self.t[0])

    def rows(self, index: slice | np.ndarray) -> JointTrajectory:
        """The plan at rows `index` (a slice or row numbers): every per-sample array taken there."""
        return replace(self, **{name: getattr(self, name)[index] for name in PER_SAMPLE},
                       series={name: v[index] for name, v in self.series.items()})


def joined(pieces: list[JointTrajectory]) -> JointTrajectory:
    """Plans of consecutive rows (JointTrajectory.rows of one plan, in order) as one: every per-sample array
    concatenated, the rest the first piece's."""
    first = pieces[0]
    if len(pieces) == 1:
        return first
    arrays: dict[str, Any] = {name: np.concatenate([getattr(p, name) for p in pieces]) for name in PER_SAMPLE}
    series = {name: np.concatenate([p.series[name] for p in pieces]) for name in first.series}
    return replace(first, **arrays, series=series)


def gradient_rows(x: np.ndarray, lo: int, hi: int, spacing: float = 1.0) -> np.ndarray:
    """np.gradient(x, spacing, axis=0)[lo:hi] from rows lo - 1 .. hi of x alone: the same numbers, without the whole
    array's temporaries."""
    a, b = max(lo - 1, 0), min(hi + 1, len(x))
    return np.gradient(x[a:b], spacing, axis=0)[lo - a:hi - a]


def revise(q_ref: np.ndarray, qd_ref: np.ndarray, change: tuple, dt: float) -> tuple[int, int]:
    """Apply a plan feedback's change (k0, columns, q) to references in place: q from row k0 on, and the rates
    np.gradient gives up to the row after them, whose rate moves too. Returns the rows [k0, hi) changed."""
    k0, columns, q = change
    k1 = k0 + len(q)
    q_ref[k0:k1, columns] = q
    hi = min(k1 + 1, len(q_ref))
    qd_ref[k0:hi, columns] = np.gradient(q_ref[k0:hi, columns], dt, axis=0)
    return k0, hi


def control_grid(duration: float, hold: float, dt: float) -> np.ndarray:
    """Sample times 0, dt, ..., covering the motion and the hold after it."""
    n = int(round((duration + hold) / dt))
    return np.arange(n + 1) * dt
