"""simbench: published path-generation and singularity-avoidance methods as runnable MuJoCo experiments.

    scenario = simbench.load_scenario("scenarios/spherical_arm/case1.yaml")
    result = simbench.run(scenario, out="renders/case1", video=False)
    result.report["tracking"]["tool_rms"]
"""

import os

# Headless rendering: EGL works without a display (Mesa's llvmpipe on a CPU). It must be chosen before MuJoCo
# is first imported; a user's own MUJOCO_GL wins.
os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"

from simbench.errors import RunError, ScenarioError  # noqa: E402
from simbench.pipeline import Evaluation, Result, evaluate, run  # noqa: E402
from simbench.scenario import Scenario, load_scenario  # noqa: E402

__all__ = ["Evaluation", "Result", "RunError", "Scenario", "ScenarioError", "evaluate", "load_scenario", "run",
           "__version__"]
