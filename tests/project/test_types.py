"""The public API is typed so that a type checker catches a wrong plugin: mypy passes on simbench.api, the
shipped controller, the shipped metric and the example package, and fails on a plugin that breaks the contract."""

import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MYPY = [sys.executable, "-m", "mypy", "--ignore-missing-imports", "--follow-imports=silent", "--no-incremental"]


def test_the_public_api_and_the_example_type_check():
    files = [ROOT / "src/simbench/api", ROOT / "src/simbench/physics/controllers.py",
             ROOT / "src/simbench/analysis/tracking.py", ROOT / "src/simbench/analysis/singularity_handling.py",
             ROOT / "src/simbench/physics/computed_torque.py", ROOT / "src/simbench/physics/policy.py",
             ROOT / "examples/planar3r/src/simbench_planar3r"]
    done = subprocess.run(MYPY + [str(f) for f in files], capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr


def test_a_wrong_plugin_is_caught_by_the_type_checker(tmp_path):
    bad = tmp_path / "bad_plugin.py"
    bad.write_text(textwrap.dedent('''
        import numpy as np
        from simbench import api
        from simbench.api import registry

        class Arm(api.Robot):
            def fk(self, q: np.ndarray) -> str:                  # a string where points are due
                return "here"

            def measures(self, rec) -> dict[str, np.ndarray]:
                return {}

            def singular_sets(self, rec, tol: api.Tolerance) -> list[api.SingularSet]:
                return []

        class Lines(api.Planner):
            name = "lines"
            description = "wrong"
            task = int                                          # not a task schema

            def plan(self, scenario) -> api.JointTrajectory:    # dt and robot forgotten
                raise NotImplementedError

        registry.register_planner(Arm)                          # a robot class where a planner is due
    '''))
    done = subprocess.run(MYPY + [str(bad)], capture_output=True, text=True)
    out = done.stdout
    assert done.returncode == 1
    for line in (":7: error: Return type \"str\" of \"fk\" incompatible", ":19: error: Incompatible types in "
                 "assignment", ":21: error: Signature of \"plan\" incompatible", ":24: error: Argument 1 to "
                 "\"register_planner\" has incompatible type"):
        assert line in out, out
