"""What the shipped serial arms share as simbench.api.Robot: kinematics of the joint values alone, a tool site
`tool` with its sensor `tool_pos`, and the scene models/<name>/scene.xml."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from simbench.robots import Robot, SingularSet, Tolerance, scene

Fk = Callable[[np.ndarray], np.ndarray]
Measures = Callable[[np.ndarray], dict[str, np.ndarray]]
SingularSets = Callable[[np.ndarray, Tolerance], list[SingularSet]]
SetsOfMeasures = Callable[[dict[str, np.ndarray], Tolerance], list[SingularSet]]


class SerialArm(Robot):
    """A shipped serial arm from its kinematics module's functions of q (N, dof); `sets_of_measures`, if given,
    makes the sets from `measures`' result. Each arm subclasses it with a constructor of no arguments (tests make
    a fresh one that way)."""

    def __init__(self, *, name: str, description: str, paper: str, joints: Sequence[str], kinds: Sequence[str],
                 lower: np.ndarray, upper: np.ndarray, qd_max: np.ndarray, fk: Fk, measures: Measures,
                 singular_sets: SingularSets, sets_of_measures: SetsOfMeasures | None = None):
        super().__init__(name=name, description=description, paper=paper, joints=joints, kinds=kinds, lower=lower,
                         upper=upper, qd_max=qd_max, tool_site="tool", tool_sensor="tool_pos", scene=scene(name))
        self._fk, self._measures, self._singular_sets = fk, measures, singular_sets
        self._sets_of_measures = sets_of_measures

    def fk(self, q: np.ndarray) -> np.ndarray:
        return self._fk(q)

    def measures(self, rec) -> dict[str, np.ndarray]:
        return self._measures(rec.q)

    def singular_sets(self, rec, tol: Tolerance) -> list[SingularSet]:
        return self._singular_sets(rec.q, tol)

    def singular_sets_from(self, rec, tol: Tolerance, measures: dict[str, np.ndarray]) -> list[SingularSet]:
        if self._sets_of_measures is None:
            return self.singular_sets(rec, tol)
        return self._sets_of_measures(measures, tol)
