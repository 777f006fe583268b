"""What touches what in a derived arm's scene at a configuration, as MuJoCo's own collision detection finds it
(mj_kinematics, then mj_collision): the pairs MuJoCo leaves out (a body and its parent, excluded body pairs,
contype/conaffinity) are left out as it leaves them. Only pairs with at least one geom on the arm (a body of the
trees its joints move) count: a part resting on a table is the scene's business, not the arm's.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np


@dataclass(frozen=True)
class Touch:
    """Two geoms in contact: their bodies and names (a geom's index where it has no name), how deep they overlap
    (m; 0 where they only touch), and whether both are the arm's (`within`: not the floor or the scene's)."""

    body1: str
    geom1: str
    body2: str
    geom2: str
    depth: float
    within: bool = True

    @property
    def bodies(self) -> tuple[str, str]:
        return self.body1, self.body2

    def describe(self) -> str:
        return (f"{self.body1} (geom {self.geom1}) and {self.body2} (geom {self.geom2}), "
                f"{self.depth * 1e3:.1f} mm deep")


class Contacts:
    """Contact queries on a compiled scene: the arm is the trees of `joints` (names)."""

    def __init__(self, model: mujoco.MjModel, joints: tuple[str, ...]):
        self.model, self.data = model, mujoco.MjData(model)
        roots = [model.body_rootid[model.joint(name).bodyid[0]] for name in joints]
        self.ours = np.isin(model.body_rootid[model.geom_bodyid], roots)
        self.adr = np.array([model.joint(name).qposadr[0] for name in joints])

    def at(self, q: np.ndarray) -> list[Touch]:
        """The arm's contacts with the joints at q (dof,), every other joint at its reference position (qpos0):
        one Touch per pair of geoms, the deepest."""
        qpos = self.model.qpos0.copy()
        qpos[self.adr] = q
        return self.at_qpos(qpos)

    def at_qpos(self, qpos: np.ndarray) -> list[Touch]:
        """The arm's contacts at the whole scene's qpos (one Touch per pair of geoms, the deepest)."""
        model, data = self.model, self.data
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        mujoco.mj_collision(model, data)
        deepest: dict[tuple[int, int], float] = {}
        for g1, g2, dist in zip(data.contact.geom1[:data.ncon].tolist(), data.contact.geom2[:data.ncon].tolist(),
                                data.contact.dist[:data.ncon].tolist()):
            if self.ours[g1] or self.ours[g2]:
                pair = (min(g1, g2), max(g1, g2))
                deepest[pair] = max(deepest.get(pair, 0.0), -dist)
        return [self._touch(g1, g2, depth) for (g1, g2), depth in sorted(deepest.items())]

    def along(self, q: np.ndarray, step: np.ndarray) -> list[tuple[int, Touch]]:
        """The contacts along q (N, dof), (row, Touch) each: at the first and last rows and wherever a joint has
        moved by its `step` (dof,) since the last row checked (a configuration costs up to a quarter of a millisecond
        on mesh arms; a plan holds thousands)."""
        return [(k, touch) for k in checked_rows(q, step) for touch in self.at(q[k])]

    def _touch(self, g1: int, g2: int, depth: float) -> Touch:
        model = self.model
        return Touch(model.body(model.geom_bodyid[g1]).name, model.geom(g1).name or str(g1),
                     model.body(model.geom_bodyid[g2]).name, model.geom(g2).name or str(g2), max(depth, 0.0),
                     bool(self.ours[g1] and self.ours[g2]))


WINDOW = 64  # rows checked_rows compares with the last row read at once (a few joint steps' motion, at 1 kHz)


def checked_rows(q: np.ndarray, step: np.ndarray) -> list[int]:
    """The rows of q (N, dof) a contact check reads: the first, the last, and each where some joint has moved by its
    step since the row read before."""
    rows, k = [0], 1
    while k < len(q):  # the next row that has moved, looked for WINDOW rows at a time (not one by one)
        moved = np.flatnonzero((np.abs(q[k:k + WINDOW] - q[rows[-1]]) >= step).any(axis=1))
        if len(moved):
            rows.append(k + int(moved[0]))
            k = rows[-1] + 1
        else:
            k += WINDOW
    if rows[-1] != len(q) - 1:
        rows.append(len(q) - 1)
    return rows
