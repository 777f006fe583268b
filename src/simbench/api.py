"""The public API: the base classes of what a user adds to simbench (Robot, Planner, Controller, Metric,
PolicyFactory), on which the shipped plugins are built too.

    scenario.yaml --> Scenario --Planner.plan--> JointTrajectory --Controller + physics--> Recording --> Analysis

A leaf of simbench's imports: it imports no plugin. Plugins are registered at run time (simbench.register_robot)
or by entry points (groups simbench.robots, .planners, .controllers, .policies, .metrics). `Scenario` is named
for annotations only: the scenario schema is built from the registries, which import this module.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Generic, Literal, NamedTuple, TypeVar

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel

from simbench.errors import RegistryError, RunError
from simbench.events import Event, Violation
from simbench.frozen import SimbenchModel
from simbench.plant import Plant, compiled_scene
from simbench.recording import Recording
from simbench.trajectory import JointTrajectory, Switch

if TYPE_CHECKING:
    import mujoco
    from matplotlib.figure import Figure

    from simbench.scenario import Scenario

__all__ = ["PRISMATIC", "REVOLUTE", "Array", "Commands", "ControlSettings", "Controller", "Decoration", "Event",
           "Figures", "JointTrajectory", "Metric", "Plant", "Planner", "PolicyFactory", "Recording", "Robot",
           "RunError", "SingularSet", "State", "Summariser", "Summary", "Switch", "Tolerance", "Violation"]



def __getattr__(name: str) -> Any:
    """Scenario, asked for at run time: where it is (this module names it for annotations only)."""
    if name == "Scenario":
        raise AttributeError("simbench.api.Scenario is for annotations (under typing.TYPE_CHECKING); at run time "
                             "use simbench.Scenario")
    raise AttributeError(f"module 'simbench.api' has no attribute {name!r}")


REVOLUTE = "revolute"
PRISMATIC = "prismatic"
Array = NDArray[np.float64]


@dataclass(frozen=True)
class Tolerance:
    """How near counts as near: radians for revolute joints, metres for prismatic ones."""

    angle: float
    length: float

    def of(self, kind: str) -> float:
        """The tolerance for a joint of this kind."""
        return self.angle if kind == REVOLUTE else self.length


@dataclass(frozen=True)
class SingularSet:
    """One singular set evaluated along a run. `distance`: the largest over its conditions of |gap| / tolerance
    (<= 1: near); `gaps`: each condition's gap, SI units; `detail(i)`: extra event entries of sample i (which
    direction is lost there), called only at an event's closest sample; `closest(a, b)`: where the robot times the
    closest sample by more than the least distance, that sample among the near samples a..b (inclusive)."""

    name: str
    family: str
    condition: str
    distance: Array
    gaps: dict[str, Array]
    detail: Callable[[int], dict[str, Any]] | None = None
    closest: Callable[[int, int], int] | None = None


class Summary(NamedTuple):
    """What a robot adds to a run's analysis: report entries, events, and per-sample series (timeseries.npz)."""

    entries: dict[str, Any]
    events: list[Event]
    series: dict[str, Array]


class Summariser(ABC):
    """Robot.summary found a window of samples at a time (`add` each window, then `finish`), so that analysing a
    long run holds a window, not the run."""

    @abstractmethod
    def add(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> dict[str, Array]:
        """The next window's plan, recording (its t does not start at 0; it may have one sample: the control period
        is rec.timestep) and analysis series; this mechanism's per-sample series there (Summary.series)."""

    @abstractmethod
    def finish(self) -> tuple[dict[str, Any], list[Event]]:
        """The whole run's report entries and events (Summary.entries, Summary.events)."""

    def whole(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> Summary:
        """The Summary of a whole run as one window."""
        extra = self.add(traj, rec, series)
        return Summary(*self.finish(), extra)


def _defined(cls: type, name: str) -> type:
    """The class of cls's method resolution order that defines attribute `name`."""
    return next(c for c in cls.__mro__ if name in c.__dict__)


class _NoSummary(Summariser):
    """The summary of a mechanism that adds nothing to a run's analysis (Robot.summary not overridden)."""

    def add(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> dict[str, Array]:
        return {}

    def finish(self) -> tuple[dict[str, Any], list[Event]]:
        return {}, []


Figures = dict[str, float | None | list[float] | dict[str, float]]  # a metric's figures by name, SI; None: not found


class Metric(ABC):
    """A figure of merit of a run, found a window of samples at a time: `for_run`, `add` each window, `finish`.
    Registered as a class; its figures go to report.json under metrics.<name> and to a sweep's results.csv as
    columns <name>.<figure>."""

    name: ClassVar[str]
    description: ClassVar[str]

    @classmethod
    def for_run(cls, robot: Robot, traj: JointTrajectory, scenario: Scenario | None) -> Metric | None:
        """The metric of a run of `traj` by `robot` (`scenario` may be None), or None where it does not apply."""
        return cls()

    @abstractmethod
    def add(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> None:
        """The next window, as Summariser.add gets it (with a recording stride, qpos, qd and ctrl at kept rows
        only). Keep what the figures need, not the window's arrays."""

    @abstractmethod
    def finish(self) -> Figures:
        """The whole run's figures: names to numbers, short lists of numbers, or numbers by name (a joint's)."""


class Decoration(NamedTuple):
    """A cone from the world origin the video draws in every frame: `axis` (3,) unit, `half_angle` rad, `length` m."""

    kind: Literal["cone"]
    axis: tuple[float, float, float]
    half_angle: float
    length: float
    rgba: tuple[float, float, float, float]


class Robot(ABC):
    """A mechanism: its MJCF scene, actuated joints, tool and the analytic kinematics simbench checks the physics
    against. The scene's position servos are named after their joints; it has a site `tool_site` with a position
    sensor `tool_sensor`. `lower`, `upper` and `qd_max` are SI. Override `fk` where the tool point follows from the
    joints alone, and the closed-chain hooks where the mechanism has passive joints."""

    def __init__(self, *, name: str, description: str, scene: str | Path, joints: Sequence[str],
                 kinds: Sequence[str], lower: Sequence[float], upper: Sequence[float], qd_max: Sequence[float],
                 tool_site: str, tool_sensor: str, paper: str = "", sensors: Sequence[str] = (),
                 orientation_error: str | None = None, breaking: Sequence[str] = ()):
        self.name = name
        self.description = description
        self.paper = paper
        self.scene = Path(scene)
        self.joints = tuple(joints)
        self.kinds = tuple(kinds)
        self.lower = np.asarray(lower, float)
        self.upper = np.asarray(upper, float)
        self.qd_max = np.asarray(qd_max, float)
        self.tool_site = tool_site
        self.tool_sensor = tool_sensor
        self.sensors = tuple(sensors)
        self.orientation_error = orientation_error
        self.breaking = tuple(breaking)
        _check_robot(self)

    @property
    def dof(self) -> int:
        """Number of actuated joints."""
        return len(self.joints)

    @property
    def has_fk(self) -> bool:
        """Whether the tool point follows from the joint values alone (`fk` overridden)."""
        return type(self).fk is not Robot.fk

    def cameras(self) -> tuple[str, ...]:
        """Names of the cameras the scene defines."""
        return _camera_names(str(self.scene))

    def fk(self, q: Array) -> Array:
        """The tool point (N, 3) in metres at joint values q (N, dof)."""
        raise NotImplementedError(f"robot '{self.name}' has no forward kinematics of its joint values")

    @abstractmethod
    def measures(self, rec: Recording) -> dict[str, Array]:
        """Per-sample singularity measures (name -> (N,)), each from its sample alone (runs come in windows)."""

    @abstractmethod
    def singular_sets(self, rec: Recording, tol: Tolerance) -> list[SingularSet]:
        """The singular sets along a run, distances normalised by `tol`, each sample's from it alone."""

    def singular_sets_from(self, rec: Recording, tol: Tolerance, measures: dict[str, Array]) -> list[SingularSet]:
        """`singular_sets(rec, tol)` given `measures(rec)`, so as not to compute them twice."""
        return self.singular_sets(rec, tol)

    def assemble(self, q: Array) -> dict[str, float]:
        """The passive joints' values (by joint name) that close the chain at actuated joint values q (dof,)."""
        return {}

    def summary(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> Summary:
        """What this mechanism adds to a run's analysis; `series` holds the analysis's series so far."""
        return Summary({}, [], {})

    @property
    def streams(self) -> bool:
        """Whether this robot's summary comes a window at a time: `summary` not overridden, or `summariser`
        overridden in the same class or below (a parent's Summariser would not give a child's summary)."""
        summary, summariser = _defined(type(self), "summary"), _defined(type(self), "summariser")
        return summary is Robot or (summariser is not Robot and issubclass(summariser, summary))

    def summariser(self, traj: JointTrajectory) -> Summariser | None:
        """`summary` a window at a time for a run of `traj`: override it with `summary`. The default adds nothing
        where `summary` is not overridden either, else None (the analysis then calls `summary` on the whole run)."""
        return _NoSummary() if type(self).summary is Robot.summary else None

    def paint(self, model: mujoco.MjModel, rec: Recording, row: int) -> None:
        """Change the model's colours for the video frame of recorded row `row` (a magnet on or off)."""

    def plots(self, traj: JointTrajectory, rec: Recording, analysis: Any) -> dict[str, Figure]:
        """This mechanism's own plots by file stem, as matplotlib Figures (simbench.plots.time_panels, say)."""
        return {}


TaskT = TypeVar("TaskT", bound=BaseModel)


class Planner(ABC, Generic[TaskT]):
    """A path-generation method: a task schema (the scenario's `task:`, built from simbench.schema's types so
    that units convert at load time) and `plan`. `robots`: those it is written for (None: any with `needs`)."""

    name: ClassVar[str]
    description: ClassVar[str]
    task: ClassVar[type[BaseModel]]
    robots: ClassVar[tuple[str, ...] | None] = None
    needs: ClassVar[tuple[Literal["fk"], ...]] = ()
    seconds_per_sample: ClassVar[float] = 0.0  # planning time a control sample beyond a few us (budget.py)

    @abstractmethod
    def plan(self, scenario: Scenario, robot: Robot, dt: float) -> JointTrajectory:
        """Joint references on the control grid of period dt. A plan's `feedback` may change its q_ref and qd_ref
        in place during the run: return arrays of its own, not cached ones."""

    def check(self, scenario: Scenario, robot: Robot) -> tuple[str, str] | None:
        """A task that is well-formed but means nothing (a zero-length path): (field, what is wrong), or None."""
        return None

    def decorations(self, scenario: Scenario) -> list[Decoration]:
        """Shapes the video draws in every frame (obstacles, say)."""
        return []

    def random_task(self, robot: Robot, random: np.random.RandomState) -> dict[str, Any] | None:
        """A random task for `robot` drawn from `random` alone (an environment's resets with task_kwargs={'random':
        seed}): the scenario sections it sets, as a scenario file writes them in SI units: `task`, and `timing`
        where the task sets its own pace (else the scenario's is kept). None (the default): not offered, and the
        environment draws a joint move instead. A task the planner then refuses is drawn again."""
        return None

    def refuses(self, robot: Robot) -> str | None:
        """Why this planner cannot plan for `robot`, or None if it can."""
        if self.robots is not None and robot.name not in self.robots:
            return f"'{self.name}' works with {', '.join(self.robots)}, not '{robot.name}'"
        if "fk" in self.needs and not robot.has_fk:
            return f"'{self.name}' needs the robot's forward kinematics of its joints, which '{robot.name}' has not"
        return None


@dataclass(frozen=True)
class State:
    """What a controller measures at control step k: time (s, negative while settling), the actuated joints'
    positions and speeds, the MuJoCo state, and the live MjData after `mj_step1` (mass matrix, bias forces,
    site poses): read it, do not change it."""

    k: int
    t: float
    q: Array
    qd: Array
    qpos: Array
    qvel: Array
    data: mujoco.MjData | None = None


class ControlSettings(SimbenchModel):
    """The scenario's `control:` section: which controller, and (in a subclass) its own fields."""

    controller: str = "servo"


class Commands(ABC):
    """An open-loop controller's commands (N, nu) found a few rows at a time as the run asks, rather than held
    all at once (Controller.open_loop). Indexed as an (N, nu) array; np.asarray gives them all."""

    @property
    @abstractmethod
    def shape(self) -> tuple[int, int]:
        """(N, nu): the rows (one per control sample) and the commands of each."""

    @abstractmethod
    def rows(self, k: slice | NDArray[np.intp]) -> Array:
        """The commands (len, nu) of rows k (a slice, or row numbers, negative ones counted from the end)."""

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
    """Turns the plan and the measured state into actuator commands (the model's `ctrl`, one row per control
    step). A run makes one with `from_scenario`, calls `bind` once with the plant and the plan, then
    `commands` every step.

    A controller whose commands do not depend on the measured state returns them from `open_loop` (an array, or
    Commands found a chunk at a time): the physics then runs in C through `mujoco.rollout`, without a Python call
    per step. `actuation` says what the commands are: position targets of the scene's position servos, or forces and
    torques ("torque": the plant's joint actuators are made motors, their force limits kept).
    """

    name: ClassVar[str]
    description: ClassVar[str]
    settings: ClassVar[type[ControlSettings]] = ControlSettings
    actuation: Literal["position", "torque"] = "position"

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> Controller:
        """The controller a scenario asks for, from its `control:` section (an instance of `settings`)."""
        return cls(scenario.control)  # type: ignore[call-arg]

    def bind(self, plant: Plant, trajectory: JointTrajectory) -> None:
        """Prepare for a run of `trajectory` on `plant` (gains, references, indices)."""

    def open_loop(self) -> Array | Commands | None:
        """Every step's commands (N, nu), if they do not depend on the measured state, as an array or as Commands
        that find them a few rows at a time (a long run then does not hold them all); else None."""
        return None

    @abstractmethod
    def commands(self, state: State) -> Array:
        """The actuator commands (nu,) for the step from `state`."""

    def revise(self, k0: int, q_ref: Array, qd_ref: Array) -> None:
        """The plan's feedback changed the references from row k0 on (an RSMG arm re-solving its hold):
        q_ref and qd_ref are the whole revised references."""

    def revise_rows(self, k0: int, k1: int, q_ref: Array, qd_ref: Array) -> None:
        """As `revise`, told that only rows k0 to k1 - 1 changed, the rows after as they were: what the
        simulation calls, so that a controller holding commands computed ahead redoes only those rows (a long
        run re-grips hundreds of times). By default `revise(k0, q_ref, qd_ref)`."""
        self.revise(k0, q_ref, qd_ref)

    def gains(self) -> dict[str, Any]:
        """What report.json says of this controller after `bind`: its gains and choices, SI units."""
        return {}


@dataclass(frozen=True)
class PolicyFactory:
    """A policy a scenario names (`control: {controller: policy, policy: name}`): `make(scenario)` returns the
    callable from each step's observation (simbench.observation) to one action per joint."""

    name: str
    description: str
    make: Callable[[Scenario], Callable[[dict], Any]]


def _check_robot(robot: Robot) -> None:
    """A robot whose description does not hold together: RegistryError naming the field."""
    n = len(robot.joints)
    for field, value in (("kinds", robot.kinds), ("lower", robot.lower), ("upper", robot.upper),
                         ("qd_max", robot.qd_max)):
        if len(value) != n:
            raise RegistryError(f"robot '{robot.name}': {field} has {len(value)} items, one per joint expected ({n})")
    if not set(robot.kinds) <= {REVOLUTE, PRISMATIC}:
        raise RegistryError(f"robot '{robot.name}': kinds must be '{REVOLUTE}' or '{PRISMATIC}', got {robot.kinds}")
    if not (robot.lower < robot.upper).all() or not (robot.qd_max > 0).all():
        raise RegistryError(f"robot '{robot.name}': expected lower < upper and qd_max > 0 for every joint")


def _camera_names(scene: str) -> tuple[str, ...]:
    model = compiled_scene(scene)
    return tuple(model.camera(i).name for i in range(model.ncam))
