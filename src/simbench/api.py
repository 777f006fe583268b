"""The public API: the types of what a user adds to simbench (a mechanism, a planner, a controller or a policy).

    scenario.yaml --> Scenario --Planner.plan--> JointTrajectory --Controller + physics--> Recording --> Analysis

A **Robot** is an MJCF scene and the analytic kinematics simbench checks it with; a **Planner** turns a
scenario's `task:` into joint references for the robots it supports; a **Controller** turns those references
and the measured state into actuator commands every control step. Each is a small abstract base class: override
the abstract methods, and the optional ones where the mechanism or method needs them. The four shipped robots,
the shipped planners and the servo are built on these classes exactly as an outside package's are. A
**PolicyFactory** names a factory of callables from observations to actions, for the `policy` controller.

This module is a leaf of simbench's imports: every plugin imports it, and it imports no plugin and nothing that
imports it back. The registries are `simbench.registry`; an outside package makes its objects known in one of
two ways, as simbench's own are (its pyproject.toml declares them so):

    simbench.register_robot(MyArm())                       # at run time, from Python

    [project.entry-points."simbench.robots"]               # in its pyproject.toml: found on first use
    myarm = "mypackage.robot:ROBOT"                        # (groups simbench.robots, .planners, .controllers,
                                                           # .policies)

`Scenario` is named here for annotations only (under typing.TYPE_CHECKING): the scenario schema is built from
the registries, which import this module; at run time it is `simbench.Scenario` (simbench.scenario).
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
    """One singular set evaluated along a run.

    `distance` is normalised: the largest over the set's conditions of |gap| / tolerance, so that a sample with
    distance <= 1 lies near the set. `gaps` holds each condition's gap in SI units (rad or m). `detail`, where the
    robot can say more of a sample than its gaps (which direction is lost there), gives the entries of sample i
    (of this window) that the set's event adds at its closest sample; it is called for those samples alone.
    """

    name: str
    family: str
    condition: str
    distance: Array
    gaps: dict[str, Array]
    detail: Callable[[int], dict[str, Any]] | None = None


class Summary(NamedTuple):
    """What a robot adds to a run's analysis: report entries, events, and per-sample series written to
    timeseries.npz."""

    entries: dict[str, Any]
    events: list[Event]
    series: dict[str, Array]


class Summariser(ABC):
    """A mechanism's summary of a run (Robot.summary) found a window of samples at a time (Robot.summariser), so
    that analysing a long run holds a window's samples, not the run's. The analysis calls `add` with each window
    in turn, then `finish`; together they give what `summary` gives of the whole run. Robot.summariser is given
    the whole plan before the run; later, read the plan `add` is given: in a run analysed as it is simulated, the
    plan's rows of windows gone by may have been handed back (pages.releasable) and read as zeros."""

    @abstractmethod
    def add(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> dict[str, Array]:
        """The next window: the plan and the recording at its samples (JointTrajectory.rows, Recording.rows: its t
        does not start at 0, and a window may have one sample, whose plan has no dt: the control period is
        rec.timestep) and the analysis's series there so far; this mechanism's per-sample series at those samples
        (Summary.series)."""

    @abstractmethod
    def finish(self) -> tuple[dict[str, Any], list[Event]]:
        """The whole run's report entries and events (Summary.entries, Summary.events)."""

    def whole(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> Summary:
        """The Summary of a whole run as one window: what Robot.summary gives, for a robot that has this."""
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


Figures = dict[str, float | list[float] | dict[str, float]]  # a metric's figures by name, SI units


class Metric(ABC):
    """A figure of merit of a run, found a window of samples at a time as the analysis is (simbench.analysis), so
    that a long run streamed through it gives the figures of the whole run at once. A run makes its own with
    `for_run`, then calls `add` with each window in turn and `finish` once. Registered as the Controller subclasses
    are, as a class: `simbench.register_metric(MyMetric)`, or an entry point of group `simbench.metrics`. Its
    figures are written to report.json under metrics.<name>, shown on the run's page and as columns
    <name>.<figure> of a sweep's results.csv. simbench's tracking figures are the shipped metric `tracking`."""

    name: ClassVar[str]
    description: ClassVar[str]

    @classmethod
    def for_run(cls, robot: Robot, traj: JointTrajectory, scenario: Scenario | None) -> Metric | None:
        """The metric of a run of plan `traj` by `robot` (`scenario` None where a script analyses a recording
        without one), or None where it does not apply to this run. By default cls()."""
        return cls()

    @abstractmethod
    def add(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> None:
        """The next window, as Summariser.add gets it: the plan and the recording at its samples (Recording.rows:
        with a recording stride, qpos, qd and ctrl at its kept rows only), and the analysis' per-sample series there
        (joint_error, path_deviation, path_lag, tool_error, the robot's measures and its summary's series). Keep
        what the figures need, not the window's arrays."""

    @abstractmethod
    def finish(self) -> Figures:
        """The whole run's figures: names to numbers, short lists of numbers, or numbers by name (a joint's)."""


class Decoration(NamedTuple):
    """A shape a planner asks the video to draw in every frame: a cone of directions from the world origin
    (an Agile Eye obstacle), `axis` (3,) unit, `half_angle` rad, `length` m, `rgba` (4,)."""

    kind: Literal["cone"]
    axis: tuple[float, float, float]
    half_angle: float
    length: float
    rgba: tuple[float, float, float, float]


class Robot(ABC):
    """A mechanism: its MJCF scene, its actuated joints, its tool and the analytic kinematics simbench checks the
    physics against.

    The scene's actuators are named after the joints they drive (a position servo per joint: the `servo`
    controller sets its gains), and it has a site `tool_site` and a position sensor `tool_sensor` on it.
    `joints` are in the planner's order; `lower`/`upper` their ranges and `qd_max` their speed limits (SI).
    Override `fk` if the tool point follows from the joint values alone (planners that follow a Cartesian path
    need it), `measures` and `singular_sets` always (an empty result is allowed, and says the mechanism has
    none), and the closed-chain hooks where the mechanism has passive joints.
    """

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
        """Per-sample singularity measures of a run (name -> (N,)), written to the report and timeseries. Each
        sample's from that sample alone: a long run is analysed a window of samples at a time (Recording.rows)."""

    @abstractmethod
    def singular_sets(self, rec: Recording, tol: Tolerance) -> list[SingularSet]:
        """The mechanism's singular sets along a run, each with its distance normalised by `tol`; each sample's from
        that sample alone, as `measures`."""

    def singular_sets_from(self, rec: Recording, tol: Tolerance, measures: dict[str, Array]) -> list[SingularSet]:
        """`singular_sets(rec, tol)` where this robot's `measures(rec)` are already computed: the analysis computes
        them first. The default ignores them; a robot whose sets are made of its measures (a gap, a determinant)
        overrides it so as not to compute them twice. Its sets must be those `singular_sets` gives."""
        return self.singular_sets(rec, tol)

    def assemble(self, q: Array) -> dict[str, float]:
        """The passive joints' values (by joint name) that close the chain at actuated joint values q (dof,)."""
        return {}

    def summary(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> Summary:
        """What this mechanism adds to a run's analysis (closure error, grips, ...); `series` holds the
        analysis's per-sample series so far (the tool error, say)."""
        return Summary({}, [], {})

    @property
    def streams(self) -> bool:
        """Whether this robot's summary comes a window at a time: `summary` not overridden, or `summariser`
        overridden in the same class as `summary` or below it (a subclass that overrides `summary` alone does not
        stream: its parent's Summariser would not give its summary). A run of it with a recording stride is then
        analysed as it is simulated (simbench.sim) and holds a window of every step's readings (simbench.budget
        estimates it so)."""
        summary, summariser = _defined(type(self), "summary"), _defined(type(self), "summariser")
        return summary is Robot or (summariser is not Robot and issubclass(summariser, summary))

    def summariser(self, traj: JointTrajectory) -> Summariser | None:
        """`summary` found a window of samples at a time, for a run of the plan `traj` (whose references may still
        be revised, by its feedback, for samples after each window): override it with `summary` where the mechanism
        adds series or figures, so that a long run's analysis holds a window's samples; it must then return a
        Summariser. The default: one that adds nothing where `summary` is not overridden either, else None: the
        analysis then keeps every sample's series and calls `summary` once, on the whole run."""
        return _NoSummary() if type(self).summary is Robot.summary else None

    def paint(self, model: mujoco.MjModel, rec: Recording, row: int) -> None:
        """Change the model's colours for the video frame of recorded row `row` (a magnet on or off)."""

    def plots(self, traj: JointTrajectory, rec: Recording, analysis: Any) -> dict[str, Figure]:
        """This mechanism's own plots, by file stem: matplotlib Figures (e.g. `simbench.plots.time_panels`'s, whose
        Axes take any matplotlib call), which simbench saves into plots/ in the run's plot format."""
        return {}


TaskT = TypeVar("TaskT", bound=BaseModel)


class Planner(ABC, Generic[TaskT]):
    """A path-generation method: a task schema (the scenario's `task:` section, a pydantic model built from
    simbench.schema's types so that units are converted at load time) and `plan`.

    `robots` names the robots it is written for (None: any robot that offers what `needs` lists, e.g. "fk").
    """

    name: ClassVar[str]
    description: ClassVar[str]
    task: ClassVar[type[BaseModel]]
    robots: ClassVar[tuple[str, ...] | None] = None
    needs: ClassVar[tuple[Literal["fk"], ...]] = ()
    seconds_per_sample: ClassVar[float] = 0.0  # planning time a control sample beyond a few us (budget.py)

    @abstractmethod
    def plan(self, scenario: Scenario, robot: Robot, dt: float) -> JointTrajectory:
        """Joint references on the control grid of period dt (simbench.trajectory.control_grid). A plan whose
        `feedback` revises it during the run has its q_ref and qd_ref changed in place by the pipeline
        (simbench.run, evaluate): return arrays of this plan's own, not ones a cache keeps for the next call."""

    def check(self, scenario: Scenario, robot: Robot) -> tuple[str, str] | None:
        """A task that is well-formed but means nothing (a zero-length path): (field, what is wrong), or None."""
        return None

    def decorations(self, scenario: Scenario) -> list[Decoration]:
        """Shapes the video draws in every frame (obstacles, say)."""
        return []

    def refuses(self, robot: Robot) -> str | None:
        """Why this planner cannot plan for `robot`, or None if it can."""
        if self.robots is not None and robot.name not in self.robots:
            return f"'{self.name}' works with {', '.join(self.robots)}, not '{robot.name}'"
        if "fk" in self.needs and not robot.has_fk:
            return f"'{self.name}' needs the robot's forward kinematics of its joints, which '{robot.name}' has not"
        return None


@dataclass(frozen=True)
class State:
    """What a controller measures at a control step k: time (s, 0 at the plan's start, negative while settling
    at sample 0), the actuated joints' positions and speeds, the whole MuJoCo state, and the live MjData with
    everything that depends on positions and speeds computed for this state (`mj_step1`: the mass matrix (mj_fullM),
    the bias forces qfrc_bias, qfrc_passive, site poses, position sensors), for controllers that need more. The
    data is the simulator's own: read it, do not change it."""

    k: int
    t: float
    q: Array
    qd: Array
    qpos: Array
    qvel: Array
    data: mujoco.MjData | None = None


class ControlSettings(SimbenchModel):
    """The scenario's `control:` section: which controller, and (in a controller's subclass of this model) its
    own fields, built from simbench.schema's types so that units are converted at load time."""

    controller: str = "servo"


class Commands(ABC):
    """An open-loop controller's commands for every step, shape (N, nu), found a few rows at a time as the run
    asks for them rather than held all at once: what `Controller.open_loop` may return in place of an array (the
    servo's, on the ten-minute RSMG soak, would hold 37 MB through the run). Indexed as an (N, nu) array is, by
    rows (an int, a slice or row numbers) and then any columns; np.asarray gives them all."""

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
        """As NumPy indexes an (N, nu) array: rows (an int, a slice, row numbers of any shape or a mask), then
        columns; the rows asked for are found, then indexed where they stand."""
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
    per step. `reads_past`: whether the controller may read the plan's references of samples more than
    windowed.NEAR_REFERENCE (2 s) before the step at hand; the run then keeps them. Where it does not, a long
    strided run hands back the plan's rows it has passed where they are on pages of their own (pages.releasable).
    `actuation` says what the commands are: position targets of the scene's position servos, or forces and
    torques ("torque": the plant's joint actuators are made motors, their force limits kept).
    """

    name: ClassVar[str]
    description: ClassVar[str]
    settings: ClassVar[type[ControlSettings]] = ControlSettings
    actuation: Literal["position", "torque"] = "position"
    reads_past: ClassVar[bool] = True  # may read references more than 2 s behind the step (the plan is then kept)

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
    """A policy a scenario names by `name` (`control: {controller: policy, policy: name}`): `make(scenario)`
    returns the callable that gets each control step's observation (simbench.observation) and returns one action
    per joint. Registered as the other plugins are, so that a scenario names code already installed rather than
    a module to import (simbench.policy)."""

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
