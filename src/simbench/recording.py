"""A simulated run as recorded: the leaf type the public API, the simulation and the analysis share."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np


@dataclass(frozen=True)
class Recording:
    """The simulated run on the trajectory's time grid: row k is the state at t[k] (t = 0 after settling). With a
    recording stride, qpos, qd and ctrl hold only the rows `kept`, the other columns every row (the analysis reads
    them); `qd_peak` is of every row."""

    t: np.ndarray
    qpos: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    ctrl: np.ndarray
    tool: np.ndarray
    timestep: float
    force: np.ndarray  # (N, dof): each joint's actuator force as MuJoCo applied it (after clamping)
    force_limit: np.ndarray  # (dof,): each actuator's force bound, inf where unlimited
    warnings: tuple[dict, ...] = ()
    sensors: dict = field(default_factory=dict)
    eq_active: dict = field(default_factory=dict)
    q_ref: np.ndarray | None = None  # the references as commanded, where the plan's feedback revised them
    qd_ref: np.ndarray | None = None
    kept: np.ndarray | None = None  # the rows of qpos, qd and ctrl; None: every row
    qd_peak: np.ndarray | None = None  # (dof,): each joint's largest |qd| over every row, kept or not (None: unknown)

    def rows(self, lo: int, hi: int) -> Recording:
        """Samples lo..hi-1 as views (qpos, qd and ctrl at the kept rows among them, `kept` counted from lo), without
        qd_peak: a window of the analysis."""
        whole = slice(lo, hi)
        if self.kept is None:
            kept, stored = None, whole
        else:
            stored = slice(*np.searchsorted(self.kept, [lo, hi]))
            kept = self.kept[stored] - lo
        return replace(self, t=self.t[whole], qpos=self.qpos[stored], q=self.q[whole], qd=self.qd[stored],
                       ctrl=self.ctrl[stored], tool=self.tool[whole], force=self.force[whole],
                       sensors={name: v[whole] for name, v in self.sensors.items()},
                       eq_active={name: v[whole] for name, v in self.eq_active.items()},
                       q_ref=None if self.q_ref is None else self.q_ref[whole],
                       qd_ref=None if self.qd_ref is None else self.qd_ref[whole], kept=kept, qd_peak=None)

    def thinned(self) -> Recording:
        """The recording at its kept rows only, every column: what the outputs of a strided run show."""
        if self.kept is None:
            return self
        k = self.kept
        return replace(self, t=self.t[k], q=self.q[k], tool=self.tool[k], force=self.force[k],
                       sensors={name: v[k] for name, v in self.sensors.items()},
                       eq_active={name: v[k] for name, v in self.eq_active.items()},
                       q_ref=None if self.q_ref is None else self.q_ref[k],
                       qd_ref=None if self.qd_ref is None else self.qd_ref[k], kept=None)
