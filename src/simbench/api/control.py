"""What a controller is to simbench (`simbench.api.Controller`): actuator commands from the plan and the
measured state, and the policies a scenario may name."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray

from simbench.api.robot import Array
from simbench.api.trajectory import JointTrajectory
from simbench.core.frozen import SimbenchModel
from simbench.core.plant import Plant

if TYPE_CHECKING:
    import mujoco

    from simbench.scenario import Scenario


@dataclass(frozen=True)
class State:
    """What a controller measures at a control step.

    Attributes:
        k: The step's row of the plan.
        t: Time (s), negative while settling.
        q: The actuated joints' positions (dof,).
        qd: Their speeds (dof,).
        qpos: MuJoCo's qpos.
        qvel: MuJoCo's qvel.
        data: The live MjData after `mj_step1` (mass matrix, bias forces, site poses): read it, do not change it.
    """

    k: int
    t: float
    q: Array
    qd: Array
    qpos: Array
    qvel: Array
    data: mujoco.MjData | None = None


class ControlSettings(SimbenchModel):
    """The scenario's `control:` section: which controller, and (in a subclass) its own fields.

    Attributes:
        controller: The controller's registered name.
    """

    controller: str = "servo"


class Commands(ABC):
    """An open-loop controller's commands (N, nu), found a few rows at a time as the run asks (`Controller.open_loop`).

    A long run then does not hold them all. Indexed as an (N, nu) array; `np.asarray` gives them all.
    """

    @property
    @abstractmethod
    def shape(self) -> tuple[int, int]:
        """(N, nu): the rows (one per control sample) and the commands of each."""

    @abstractmethod
    def rows(self, k: slice | NDArray[np.intp]) -> Array:
        """The commands of some rows.

        Args:
            k: A slice, or row numbers (negative ones counted from the end).

        Returns:
            Their commands (len, nu).
        """

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, index: Any) -> Array:
        """As NumPy indexes an (N, nu) array: rows (an int, a slice, row numbers or a mask), then columns."""
        rows, columns = (index[0], index[1:]) if isinstance(index, tuple) else (index, ())
        if isinstance(rows, slice):
            return self.rows(rows)[(slice(None), *columns)]
        rows = np.asarray(rows)
        if rows.dtype == bool and rows.ndim == 1:
            rows = np.flatnonzero(rows)
        if rows.dtype.kind not in "iu":
            raise IndexError(f"Commands are indexed by rows (an int, a slice, row numbers or a mask), got {index!r}")
        found = self.rows(rows.reshape(-1))
        return found[(np.arange(rows.size).reshape(rows.shape), *columns)]

    def __array__(self, dtype: Any = None, copy: bool | None = None) -> Array:
        return np.asarray(self.rows(slice(None)), dtype)


class Controller(ABC):
    """Turns the plan and the measured state into actuator commands (the model's `ctrl`, one row a step).

    A run makes one with `from_scenario`, calls `bind` once with the plant and the plan, then `commands` every
    step. A controller whose commands do not depend on the measured state returns them from `open_loop`: the
    physics then runs in C through `mujoco.rollout`, without a Python call per step.

    Attributes:
        name: The name scenarios give (`control: {controller: name}`).
        description: One line for `simbench list`.
        settings: The schema of its `control:` section.
        actuation: What the commands are: `"position"` targets of the scene's position servos, or `"torque"`
            (forces and torques: the plant's joint actuators are made motors, their force limits kept).
    """

    name: ClassVar[str]
    description: ClassVar[str]
    settings: ClassVar[type[ControlSettings]] = ControlSettings
    actuation: Literal["position", "torque"] = "position"

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> Controller:
        """The controller a scenario asks for.

        Args:
            scenario: The scenario; its `control:` section is an instance of `settings`.

        Returns:
            A controller.
        """
        return cls(scenario.control)  # type: ignore[call-arg]

    def bind(self, plant: Plant, trajectory: JointTrajectory) -> None:
        """Prepare for a run (gains, references, indices).

        Args:
            plant: The compiled robot.
            trajectory: The plan.
        """

    def open_loop(self) -> Array | Commands | None:
        """Every step's commands, if they do not depend on the measured state.

        Returns:
            The commands (N, nu), as an array or as Commands that find them a few rows at a time (a long run
            then does not hold them all); None where they depend on the state.
        """
        return None

    @abstractmethod
    def commands(self, state: State) -> Array:
        """The step's commands.

        Args:
            state: What is measured at the step.

        Returns:
            The actuator commands (nu,).
        """

    def revise(self, k0: int, q_ref: Array, qd_ref: Array) -> None:
        """Take references the plan's feedback changed (an RSMG arm re-solving its hold).

        Args:
            k0: The first row changed.
            q_ref: The whole revised position references.
            qd_ref: The whole revised speed references.
        """

    def revise_rows(self, k0: int, k1: int, q_ref: Array, qd_ref: Array) -> None:
        """As `revise`, told which rows changed: what the simulation calls.

        A controller holding commands computed ahead then redoes only those rows (a long run re-grips hundreds of
        times). By default `revise(k0, q_ref, qd_ref)`.

        Args:
            k0: The first row changed.
            k1: The row after the last one changed: rows from k1 on are as they were.
            q_ref: The whole revised position references.
            qd_ref: The whole revised speed references.
        """
        self.revise(k0, q_ref, qd_ref)

    def gains(self) -> dict[str, Any]:
        """What report.json says of this controller after `bind`.

        Returns:
            Its gains and choices, SI units.
        """
        return {}


@dataclass(frozen=True)
class PolicyFactory:
    """A policy a scenario names (`control: {controller: policy, policy: name}`).

    Attributes:
        name: Its name.
        description: One line for `simbench list`.
        make: `make(scenario)` returns the callable from each step's observation (`simbench.physics.observation`) to
            one action per joint.
    """

    name: str
    description: str
    make: Callable[[Scenario], Callable[[dict], Any]]
