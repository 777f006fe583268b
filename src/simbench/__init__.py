"""simbench: published path-generation and singularity-avoidance methods as runnable MuJoCo experiments.

    scenario = simbench.load_scenario("scenarios/spherical_arm/case1.yaml")
    result = simbench.run(scenario, out="renders/case1", video=False)
    result.report["tracking"]["tool_rms"]

The pipeline (MuJoCo, SciPy, Matplotlib) is imported on first use, so that `python -m simbench` answers Ctrl-C
cleanly from its first moment.
"""

import importlib

from simbench.core import moved
from simbench.core.errors import OutputError, PhysicsError, RunError, ScenarioError
from simbench.core.version import __version__

moved.install()  # the module paths before the stage folders, for one release

_PIPELINE = "simbench.commands.pipeline"
_LAZY = {"Evaluation": _PIPELINE, "Result": _PIPELINE, "evaluate": _PIPELINE, "run": _PIPELINE,
         "Scenario": "simbench.scenario", "load_scenario": "simbench.scenario",
         **{name: "simbench.api.registry" for name in ("register_robot", "register_planner", "register_controller",
                                                    "register_policy", "register_metric")}}

__all__ = ["Evaluation", "OutputError", "PhysicsError", "Result", "RunError", "Scenario", "ScenarioError",
           "__version__", "evaluate", "load_scenario", "register_controller", "register_metric", "register_planner",
           "register_policy", "register_robot", "run"]


def __getattr__(name: str):
    """The pipeline's public names, imported when first asked for."""
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'simbench' has no attribute {name!r}")
