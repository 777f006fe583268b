"""What importing simbench costs: the heavy libraries (matplotlib, scipy's optimiser and spatial package, OMPL)
are imported by the stage that uses them, not by `import simbench`, so that the CLI starts in a fraction of a
second and a run without plots (a sweep's, simbench.evaluate) does not hold their memory (issue 14)."""

import subprocess
import sys

from tests.conftest import scenario_file

HEAVY = ("matplotlib", "scipy", "scipy.optimize", "scipy.spatial", "ompl")

_PROBE = """
import sys
import simbench, simbench.cli, simbench.commands.pipeline
loaded = lambda: sorted(m for m in {heavy!r} if m in sys.modules)
print(loaded())
simbench.evaluate({scenario!r})
print(loaded())
"""


def _loaded(scenario) -> list[str]:
    """The heavy modules loaded after import, then after evaluating `scenario`, in a fresh interpreter."""
    done = subprocess.run([sys.executable, "-c", _PROBE.format(heavy=HEAVY, scenario=str(scenario))],
                          capture_output=True, text=True, check=True)
    return done.stdout.strip().splitlines()


def test_import_loads_no_heavy_library():
    """`import simbench` (and its CLI and pipeline) loads none of them; a spherical-arm run without outputs
    neither: the registry holds the shipped planners without importing what they plan with."""
    after_import, after_run = _loaded(scenario_file("spherical_arm", "case1"))
    assert after_import == "[]"
    assert after_run == "[]"


def test_a_planner_imports_what_it_uses_when_it_plans():
    """The Agile Eye's planner imports scipy's spatial package (through the scenario's orientations) when the
    scenario is planned, and still neither the optimiser nor OMPL on a task that needs no avoidance."""
    after_import, after_run = _loaded(scenario_file("agile_eye", "through_singularity"))
    assert after_import == "[]"
    assert after_run == "['scipy', 'scipy.spatial']"
