"""The public API: the base classes of what a user adds to simbench (Robot, Planner, Controller, Metric,
PolicyFactory), on which the shipped plugins are built too.

    scenario.yaml --> Scenario --Planner.plan--> JointTrajectory --Controller + physics--> Recording --> Analysis

A leaf of simbench's imports: it imports no plugin. Plugins are registered at run time (simbench.register_robot)
or by entry points (groups simbench.robots, .planners, .controllers, .policies, .metrics). `Scenario` is named
for annotations only: the scenario schema is built from the registries, which import this module.

Holds the contract's types, the registry of plugins and the plot layout plugins draw with; imports only simbench.core.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from simbench.api.control import Commands, Controller, ControlSettings, PolicyFactory, State
from simbench.api.events import Event, Violation
from simbench.api.metric import Figures, Metric
from simbench.api.planner import Decoration, Planner
from simbench.api.recording import Recording
from simbench.api.robot import PRISMATIC, REVOLUTE, Array, PlantFit, Robot, SingularSet, Summariser, Summary, Tolerance
from simbench.api.trajectory import JointTrajectory, Switch
from simbench.core.errors import RunError
from simbench.core.plant import Plant

if TYPE_CHECKING:
    from simbench.scenario import Scenario

__all__ = ["PRISMATIC", "REVOLUTE", "Array", "Commands", "ControlSettings", "Controller", "Decoration", "Event",
           "Figures", "JointTrajectory", "Metric", "Plant", "PlantFit", "Planner", "PolicyFactory", "Recording",
           "Robot", "RunError", "SingularSet", "State", "Summariser", "Summary", "Switch", "Tolerance", "Violation"]


def __getattr__(name: str) -> Any:
    """Scenario, asked for at run time: where it is (this module names it for annotations only)."""
    if name == "Scenario":
        raise AttributeError("simbench.api.Scenario is for annotations (under typing.TYPE_CHECKING); at run time "
                             "use simbench.Scenario")
    raise AttributeError(f"module 'simbench.api' has no attribute {name!r}")
