"""A simulated run as recorded: the leaf type the public API, the simulation and the analysis share."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np


@dataclass(frozen=True)
class Recording:
    """The simulated run on the plan's time grid: row k is the state at t[k] (t = 0 after settling).

    With a recording stride, qpos, qd and ctrl hold only the rows `kept`, the other columns every row (the
    analysis reads them).

    Attributes:
        t: Time of each row (N,), s.
        qpos: MuJoCo's qpos at each kept row.
        q: The actuated joints' values (N, dof).
        qd: Their speeds at each kept row.
        ctrl: The actuator commands at each kept row.
        tool: The tool point (N, 3), m, as the scene's tool sensor measures it.
        timestep: The control period (s).
        force: Each joint's actuator force as MuJoCo applied it, after clamping (N, dof).
        force_limit: Each actuator's force bound (dof,); inf where unlimited.
        warnings: MuJoCo's warnings during the run.
        sensors: The robot's further sensors' readings by name (`Robot.sensors`).
        eq_active: Each equality constraint's state (on or off) at each row, by name.
        q_ref: The position references as commanded, where the plan's feedback revised them; else None.
        qd_ref: The speed references likewise.
        kept: The rows qpos, qd and ctrl hold; None: every row.
        qd_peak: Each joint's largest |qd| over every row, kept or not (dof,); None: unknown.
    """

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
        """A window of the analysis: rows lo to hi - 1 as views, without qd_peak.

        Args:
            lo: The first row.
            hi: The row after the last.

        Returns:
            The window (qpos, qd and ctrl at the kept rows among them, `kept` counted from lo).
        """
        whole = slice(lo, hi)
        if self.kept is None:
            kept, stored = None, whole
        else:
            stored = slice(*np.searchsorted(self.kept, [lo, hi]))
            kept = self.kept[stored] - lo
        return replace(self, **self._every_row(whole), qpos=self.qpos[stored], qd=self.qd[stored],
                       ctrl=self.ctrl[stored], kept=kept, qd_peak=None)

    def thinned(self) -> Recording:
        """The recording at its kept rows only, every column: what the outputs of a strided run show.

        Returns:
            The thinned recording (itself where every row is kept).
        """
        return self if self.kept is None else replace(self, **self._every_row(self.kept), kept=None)

    def _every_row(self, index: slice | np.ndarray) -> dict:
        """The fields held at every row, whatever the stride, at rows `index`."""
        return {"t": self.t[index], "q": self.q[index], "tool": self.tool[index], "force": self.force[index],
                "sensors": {name: v[index] for name, v in self.sensors.items()},
                "eq_active": {name: v[index] for name, v in self.eq_active.items()},
                "q_ref": None if self.q_ref is None else self.q_ref[index],
                "qd_ref": None if self.qd_ref is None else self.qd_ref[index]}
