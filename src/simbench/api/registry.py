"""The registries: every robot, planner, controller, policy and metric by name, with where each came from.

simbench's own are entry points of its package, as an outside package's are, and are read first. One of
simbench's own that fails to load raises; an outside one that fails (sys.exit too) is kept in `broken`, so that
one broken package does not stop the others (the user's Ctrl-C still stops the loading).
"""

from __future__ import annotations

import dataclasses
import importlib.metadata
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

from simbench.api import Controller, JointTrajectory, Metric, Planner, PolicyFactory, Robot
from simbench.core import interrupts
from simbench.core.errors import RegistryError, described

if TYPE_CHECKING:
    from simbench.scenario import Scenario

SHIPPED = "simbench"  # the distribution whose entry points are simbench's own
Kind = Literal["robot", "planner", "controller", "policy", "metric"]


@dataclass
class _Registry:
    """The objects of one kind by name, each with where it came from; entry points are read on first use."""

    group: str
    kind: type
    classes: bool = False  # holds subclasses of `kind` (a run makes its own instance), not instances
    objects: dict[str, Any] = dataclasses.field(default_factory=dict)
    origins: dict[str, str] = dataclasses.field(default_factory=dict)
    broken: dict[str, str] = dataclasses.field(default_factory=dict)  # entry point name -> why it did not load
    shipped: bool = False  # simbench's own entry points read
    loaded: bool = False  # every entry point read

    def add(self, obj: Any, origin: str) -> None:
        if not (isinstance(obj, type) and issubclass(obj, self.kind) if self.classes else isinstance(obj, self.kind)):
            expected = "subclass" if self.classes else "instance"
            raise RegistryError(f"{origin}: expected a simbench.api.{self.kind.__name__} {expected}, got "
                                f"{obj!r:.80}")
        name = getattr(obj, "name", None)
        if not isinstance(name, str) or not name:
            raise RegistryError(f"{origin}: a {self.kind.__name__} needs a name")
        if name in self.objects and self.objects[name] is not obj:
            raise RegistryError(f"{origin}: a {self.kind.__name__.lower()} called '{name}' is already registered "
                                f"(from {self.origins[name]})")
        self.objects[name] = obj
        self.origins[name] = origin

    def register(self, obj: Any, origin: str) -> None:
        """Add `obj` from Python, after the entry points (so that a name they hold is not taken from them)."""
        self.all()
        self.add(obj, origin)

    def load_shipped(self) -> None:
        """simbench's own entry points of this group, registered with origin 'simbench'."""
        if self.shipped:
            return
        for ep in _own(self.group):
            try:
                obj = ep.load()
            except Exception as err:
                raise RegistryError(f"simbench's own {ep.name} ({ep.value}) cannot be loaded: {described(err)} (a "
                                    "bug in simbench: please report it)") from err
            self.add(obj, SHIPPED)
        self.shipped = True

    def all(self) -> dict[str, Any]:
        """Every object by name, the installed packages' entry points read the first time."""
        if not self.loaded:
            self.load_shipped()
            for ep in importlib.metadata.entry_points(group=self.group):
                if _is_own(ep):
                    continue
                origin = f"entry point {ep.value} ({ep.dist.name if ep.dist else 'unknown package'})"
                try:
                    self.add(ep.load(), origin)
                except BaseException as err:  # an outside package's failure, whatever it is: named, then skipped
                    if interrupts.is_press(err):
                        raise
                    self.broken[ep.name] = f"{origin} cannot be used: {described(err)}"
            self.loaded = True
        return self.objects


def _is_own(ep: importlib.metadata.EntryPoint) -> bool:
    return ep.dist is not None and ep.dist.name == SHIPPED


def _own(group: str) -> list[importlib.metadata.EntryPoint]:
    """simbench's own entry points of `group`; RegistryError if simbench is not installed (no metadata)."""
    try:
        importlib.metadata.distribution(SHIPPED)
    except importlib.metadata.PackageNotFoundError:
        raise RegistryError("simbench is not installed, so its robots, planners and controllers cannot be found "
                            "(they are entry points of its package): pip install -e . in its folder") from None
    return [ep for ep in importlib.metadata.entry_points(group=group) if _is_own(ep)]


_ROBOTS = _Registry("simbench.robots", Robot)
_PLANNERS = _Registry("simbench.planners", Planner)
_CONTROLLERS = _Registry("simbench.controllers", Controller, classes=True)
_POLICIES = _Registry("simbench.policies", PolicyFactory)
_METRICS = _Registry("simbench.metrics", Metric, classes=True)
_REGISTRIES: dict[str, _Registry] = {"robot": _ROBOTS, "planner": _PLANNERS, "controller": _CONTROLLERS,
                                     "policy": _POLICIES, "metric": _METRICS}


def load_shipped() -> None:
    """Load simbench's own plugins of every kind."""
    for registry in _REGISTRIES.values():
        registry.load_shipped()


def register_robot(robot: Robot, origin: str = "registered from Python") -> None:
    """Make `robot` known to scenarios by its name.

    Args:
        robot: the Robot instance; scenarios name it by `robot.name`.
        origin: where it comes from, as `simbench list` shows it.

    Raises:
        RegistryError: it is not of the expected type, has no name, or its name is taken.
    """
    _ROBOTS.register(robot, origin)


def register_planner(planner: Planner, origin: str = "registered from Python") -> None:
    """Make `planner` known to scenarios by its name.

    Args:
        planner: the Planner instance; scenarios name it by `planner.name`.
        origin: where it comes from, as `simbench list` shows it.

    Raises:
        RegistryError: it is not of the expected type, has no name, or its name is taken.
    """
    _PLANNERS.register(planner, origin)


def register_controller(controller: type[Controller], origin: str = "registered from Python") -> None:
    """Make a Controller subclass known to scenarios by its name (a run makes its own instance).

    Args:
        controller: the Controller subclass; scenarios name it by its `name`.
        origin: where it comes from, as `simbench list` shows it.

    Raises:
        RegistryError: it is not of the expected type, has no name, or its name is taken.
    """
    _CONTROLLERS.register(controller, origin)


def register_policy(policy: PolicyFactory, origin: str = "registered from Python") -> None:
    """Make `policy` known to scenarios by its name (`control.policy`).

    Args:
        policy: the PolicyFactory; a scenario's `control.policy` names it.
        origin: where it comes from, as `simbench list` shows it.

    Raises:
        RegistryError: it is not of the expected type, has no name, or its name is taken.
    """
    _POLICIES.register(policy, origin)


def register_metric(metric: type[Metric], origin: str = "registered from Python") -> None:
    """Make a Metric subclass measure every run from now on (each run makes its own: Metric.for_run).

    Args:
        metric: the Metric subclass; its figures appear under `metrics.<name>`.
        origin: where it comes from, as `simbench list` shows it.

    Raises:
        RegistryError: it is not of the expected type, has no name, or its name is taken.
    """
    _METRICS.register(metric, origin)


def robots() -> dict[str, Robot]:
    """Every robot: the shipped ones, those of installed packages' entry points, those registered.

    Returns:
        Each Robot by its name.
    """
    return _ROBOTS.all()


def planners() -> dict[str, Planner]:
    """Every planner, from the same three sources.

    Returns:
        Each Planner by its name.
    """
    return _PLANNERS.all()


def controllers() -> dict[str, type[Controller]]:
    """Every controller class, from the same three sources.

    Returns:
        Each Controller subclass by its name.
    """
    return _CONTROLLERS.all()


def policies() -> dict[str, PolicyFactory]:
    """Every policy: those of installed packages' entry points and those registered (none ship with simbench).

    Returns:
        Each PolicyFactory by its name.
    """
    return _POLICIES.all()


def metrics() -> dict[str, type[Metric]]:
    """Every metric class: the shipped ones, installed packages' and those registered.

    Returns:
        Each Metric subclass by its name.
    """
    return _METRICS.all()


def metrics_for(robot: Robot, traj: JointTrajectory, scenario: Scenario | None) -> list[Metric]:
    """Every metric of a run (Metric.for_run), in the registry's order, but those that do not apply to it."""
    made = (cls.for_run(robot, traj, scenario) for cls in metrics().values())
    return [metric for metric in made if metric is not None]


def broken(kind: Kind) -> dict[str, str]:
    """Entry points of this kind that failed to load or register, by name, with why."""
    return _REGISTRIES[kind].broken


def origin(kind: Kind, name: str) -> str:
    """Where the robot, planner, controller, policy or metric called `name` comes from."""
    return _REGISTRIES[kind].origins[name]
