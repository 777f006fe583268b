"""What a robot is to simbench (`simbench.api.Robot`): its joints and kinds, its singular sets, and what it adds to
a run's analysis."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from simbench.api.events import Event, Violation
from simbench.api.recording import Recording
from simbench.api.trajectory import JointTrajectory
from simbench.core.errors import RegistryError
from simbench.core.plant import Plant, compiled_scene

if TYPE_CHECKING:
    import mujoco
    from matplotlib.figure import Figure


REVOLUTE = "revolute"
"""A joint kind (`Robot.kinds`): a hinge, its values in radians."""
PRISMATIC = "prismatic"
"""A joint kind (`Robot.kinds`): a slide, its values in metres."""
Array = NDArray[np.float64]
"""A NumPy array of floats: what joint values, tool points and per-sample series are."""


@dataclass(frozen=True)
class Tolerance:
    """How near counts as near: radians for revolute joints, metres for prismatic ones.

    Attributes:
        angle: The tolerance of a revolute joint (rad).
        length: The tolerance of a prismatic joint (m).
    """

    angle: float
    length: float

    def of(self, kind: str) -> float:
        """The tolerance for a joint of this kind.

        Args:
            kind: `REVOLUTE` or `PRISMATIC`.

        Returns:
            `angle` for a revolute joint, else `length`.
        """
        return self.angle if kind == REVOLUTE else self.length


@dataclass(frozen=True)
class SingularSet:
    """One singular set evaluated along a run (`Robot.singular_sets`).

    Attributes:
        name: The set's name, as events and report.json give it.
        family: The kind of singularity, for the reader.
        condition: What holds on the set, in words.
        distance: (N,) the largest over its conditions of |gap| / tolerance: at most 1 is near.
        gaps: Each condition's gap (N,), SI units.
        detail: `detail(i)`: extra event entries of sample i (which direction is lost there), called only at an
            event's closest sample.
        closest: `closest(a, b)`: where the robot times the closest sample by more than the least distance, that
            sample among the near samples a..b (inclusive).
    """

    name: str
    family: str
    condition: str
    distance: Array
    gaps: dict[str, Array]
    detail: Callable[[int], dict[str, Any]] | None = None
    closest: Callable[[int, int], int] | None = None


@dataclass(frozen=True)
class PlantFit:
    """What a robot's plant needs for one plan before it is simulated (`Robot.plant_fit`).

    Attributes:
        kp: Position-servo stiffness designed for the plan, by joint name (SI); joints not named keep the scene's.
        kv: Their damping, by joint name (SI).
        design: report.json's entries of the design, one per joint designed (`derived_arm.servos`).
        start_contacts: The contacts at the plan's first sample, in words: the start is refused (bad input).
        violations: What the plan breaks that the plant shows before any physics (a contact along it, a force it
            needs beyond a limit): the run cannot end `ok`.
    """

    kp: dict[str, float] = field(default_factory=dict)
    kv: dict[str, float] = field(default_factory=dict)
    design: tuple[dict, ...] = ()
    start_contacts: tuple[str, ...] = ()
    violations: tuple[Violation, ...] = ()


class Summary(NamedTuple):
    """What a robot adds to a run's analysis.

    Attributes:
        entries: Report entries (report.json).
        events: Events of the run.
        series: Per-sample series by name (timeseries.npz).
    """

    entries: dict[str, Any]
    events: list[Event]
    series: dict[str, Array]


class Summariser(ABC):
    """`Robot.summary` found a window of samples at a time: `add` each window, then `finish`.

    Analysing a long run then holds a window, not the run.
    """

    @abstractmethod
    def add(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> dict[str, Array]:
        """Take the next window.

        Args:
            traj: The plan at the window's rows.
            rec: The recording there (its t does not start at 0; it may have one sample: the control period is
                `rec.timestep`).
            series: The analysis's per-sample series there.

        Returns:
            This mechanism's per-sample series there (`Summary.series`).
        """

    @abstractmethod
    def finish(self) -> tuple[dict[str, Any], list[Event]]:
        """The whole run's report entries and events.

        Returns:
            `Summary.entries` and `Summary.events` of the whole run.
        """

    def whole(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> Summary:
        """The Summary of a whole run taken as one window.

        Args:
            traj: The plan.
            rec: The recording.
            series: The analysis's per-sample series.

        Returns:
            The whole run's summary.
        """
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



class Robot(ABC):
    """A mechanism: its MJCF scene, actuated joints, tool and the analytic kinematics simbench checks the physics
    against.

    Override `fk` where the tool point follows from the joints alone, and the closed-chain hooks (`assemble`,
    `summary`, `paint`, `plots`) where the mechanism has passive joints.

    Args:
        name: The name scenarios give (`robot:`).
        description: One line for `simbench list`.
        scene: The MJCF scene; its position servos are named after their joints.
        joints: The actuated joints, in order.
        kinds: Each joint's kind, `REVOLUTE` or `PRISMATIC`.
        lower: Each joint's lower limit (rad or m).
        upper: Each joint's upper limit (rad or m).
        qd_max: Each joint's speed limit (rad/s or m/s).
        tool_site: The scene's site at the tool point.
        tool_sensor: The scene's position sensor of that site.
        paper: The paper the robot comes from, if any.
        sensors: Further sensors to record.
        orientation_error: The series of the tool's orientation error, if the robot has one: the verdict holds
            it to `analysis.orientation_tolerance`.
        breaking: Kinds of this robot's events that break a promise (an assembly-mode change, say): a run with
            one is not `ok`.

    Raises:
        RegistryError: The description does not hold together (a list of the wrong length, lower >= upper).
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
        """The cameras the scene defines.

        Returns:
            Their names.
        """
        model = compiled_scene(str(self.scene))
        return tuple(model.camera(i).name for i in range(model.ncam))

    def fk(self, q: Array) -> Array:
        """The tool point of joint values: override it where the joints alone set it.

        Args:
            q: Joint values (N, dof).

        Returns:
            The tool points (N, 3), metres.
        """
        raise NotImplementedError(f"robot '{self.name}' has no forward kinematics of its joint values")

    @abstractmethod
    def measures(self, rec: Recording) -> dict[str, Array]:
        """Per-sample singularity measures, each sample's from that sample alone (runs come in windows).

        Args:
            rec: The recording (or a window of it).

        Returns:
            Each measure's series (N,) by name.
        """

    @abstractmethod
    def singular_sets(self, rec: Recording, tol: Tolerance) -> list[SingularSet]:
        """The singular sets along a run, each sample's distances from that sample alone.

        Args:
            rec: The recording (or a window of it).
            tol: What counts as near: the distances are normalised by it.

        Returns:
            One SingularSet per set the robot has.
        """

    def singular_sets_from(self, rec: Recording, tol: Tolerance, measures: dict[str, Array]) -> list[SingularSet]:
        """`singular_sets(rec, tol)` given `measures(rec)`: override it so as not to compute them twice.

        Args:
            rec: The recording (or a window of it).
            tol: What counts as near.
            measures: `measures(rec)`.

        Returns:
            As `singular_sets`'s.
        """
        return self.singular_sets(rec, tol)

    def plant_fit(self, plant: Plant, trajectory: JointTrajectory, analysis: Any) -> PlantFit | None:
        """What the plant needs for this plan, before it is simulated: servo gains designed for it, the contacts
        at its start (refused) and along it, the forces it needs beyond the limits. An arm derived from its model
        has it (simbench.robots.servo_design, robots.contacts).

        Args:
            plant: The plant as loaded for the scenario.
            trajectory: The plan.
            analysis: The scenario's `analysis:` settings (its tolerances).

        Returns:
            The fit; None (the default): the scene runs as it is.
        """
        return None

    def judges_orientation(self, trajectory: JointTrajectory) -> bool:
        """Whether the tool's orientation error (`orientation_error`) is a promise of this plan, held to
        `analysis.orientation_tolerance`; where not, it is reported only.

        Args:
            trajectory: The plan.

        Returns:
            True (the default): always, where the robot has the series.
        """
        return True

    def assemble(self, q: Array) -> dict[str, float]:
        """The passive joints' values that close the chain.

        Args:
            q: The actuated joints' values (dof,).

        Returns:
            Each passive joint's value by joint name (none for a serial arm).
        """
        return {}

    def summary(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> Summary:
        """What this mechanism adds to a run's analysis.

        Args:
            traj: The plan.
            rec: The recording.
            series: The analysis's per-sample series so far.

        Returns:
            Report entries, events and per-sample series.
        """
        return Summary({}, [], {})

    @property
    def streams(self) -> bool:
        """Whether this robot's summary comes a window at a time: `summary` not overridden, or `summariser`
        overridden in the same class or below (a parent's Summariser would not give a child's summary)."""
        summary, summariser = _defined(type(self), "summary"), _defined(type(self), "summariser")
        return summary is Robot or (summariser is not Robot and issubclass(summariser, summary))

    def summariser(self, traj: JointTrajectory) -> Summariser | None:
        """`summary` a window at a time: override it with `summary`.

        Args:
            traj: The plan of the run.

        Returns:
            A fresh Summariser; by default one that adds nothing where `summary` is not overridden either, else
            None (the analysis then calls `summary` on the whole run).
        """
        return _NoSummary() if type(self).summary is Robot.summary else None

    def paint(self, model: mujoco.MjModel, rec: Recording, row: int) -> None:
        """Change the model's colours for a video frame (a magnet on or off).

        Args:
            model: The model the frame renders.
            rec: The recording.
            row: The recorded row the frame shows.
        """

    def plots(self, traj: JointTrajectory, rec: Recording, analysis: Any) -> dict[str, Figure]:
        """This mechanism's own plots, laid out as simbench's own with `simbench.api.panels.time_panels`, say.

        Args:
            traj: The plan.
            rec: The recording.
            analysis: The run's analysis.

        Returns:
            matplotlib Figures by file stem: simbench saves them into plots/ in the run's plot format.
        """
        return {}



def _check_robot(robot: Robot) -> None:
    """A robot whose description does not hold together: RegistryError naming the field."""
    n = len(robot.joints)
    for name, value in (("kinds", robot.kinds), ("lower", robot.lower), ("upper", robot.upper),
                        ("qd_max", robot.qd_max)):
        if len(value) != n:
            raise RegistryError(f"robot '{robot.name}': {name} has {len(value)} items, one per joint expected ({n})")
    if not set(robot.kinds) <= {REVOLUTE, PRISMATIC}:
        raise RegistryError(f"robot '{robot.name}': kinds must be '{REVOLUTE}' or '{PRISMATIC}', got {robot.kinds}")
    if not (robot.lower < robot.upper).all() or not (robot.qd_max > 0).all():
        raise RegistryError(f"robot '{robot.name}': expected lower < upper and qd_max > 0 for every joint")
