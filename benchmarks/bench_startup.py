"""What starting simbench costs: `import simbench` (with its CLI and pipeline) and a whole `simbench validate` of a
shipped scenario, each in a fresh interpreter, against a bare interpreter that imports NumPy and MuJoCo.

Each figure is the median of REPEATS fresh processes, the three kinds run in turn so that a busy machine slows
them alike; memory is the process's peak resident size. BEFORE holds the same figures for commit e7ffd6e (before
the heavy libraries were imported by the stage that uses them), measured by this module in the same rounds, given
that revision's tree (`git archive e7ffd6e src scenarios models`) as `python -m benchmarks.bench_startup TREE`.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np

from benchmarks.common import CHILD_PEAK_BYTES
from simbench.core.resources import scenarios_dir

REPEATS = 9
HEAVY = ("matplotlib", "scipy.optimize", "scipy.spatial", "ompl")
SCENARIO = "spherical_arm/case1"
_PROBE = """
import json, sys, time
start = time.perf_counter()
{body}
print(json.dumps({{"seconds": time.perf_counter() - start, "peak_mib": {peak} / 2**20,
                   "heavy": [m for m in {heavy!r} if m in sys.modules]}}))
"""
_KINDS = {
    "bare": "import numpy, mujoco",
    "import": "import simbench, simbench.cli, simbench.commands.pipeline",
    "validate": ("from simbench.cli import main\ntry:\n    main(['validate', {scenario!r}])\n"
                 "except SystemExit:\n    pass"),
}
# Commit e7ffd6e, measured by this module on 2026-11-23 (AMD EPYC, 2 cores, with other work running) in the same
# rounds as the figures now of that day (0.316, 0.618 and 0.801 s; 50, 75 and 94 MiB): seconds and peak MiB.
BEFORE = {"bare": (0.275, 50.0), "import": (1.135, 114.0), "validate": (1.595, 151.0)}


def _once(kind: str, tree: str | None = None) -> dict:
    """One fresh interpreter doing `kind` (with the simbench of `tree`, a source tree, if given): its seconds
    (from the interpreter's start of the work), peak MiB and which heavy libraries it loaded."""
    folder = scenarios_dir() if tree is None else os.path.join(tree, "scenarios")
    body = _KINDS[kind].format(scenario=os.path.join(folder, f"{SCENARIO}.yaml"))
    env = os.environ if tree is None else {**os.environ, "PYTHONPATH": os.path.join(tree, "src")}
    probe = _PROBE.format(body=body, heavy=HEAVY, peak=CHILD_PEAK_BYTES)
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True, env=env)
    return json.loads(done.stdout.strip().splitlines()[-1])


def _medians(runs: list[dict]) -> dict:
    return {"seconds": float(np.median([r["seconds"] for r in runs])),
            "peak_mib": float(np.median([r["peak_mib"] for r in runs])), "heavy": runs[-1]["heavy"]}


def measure(before_tree: str | None = None) -> dict:
    """Median seconds and peak memory of each kind over REPEATS rounds, and what each loaded; with
    `before_tree`, that tree's in the same rounds under "before"."""
    trees = {"now": None, **({"before": before_tree} if before_tree else {})}
    runs: dict[tuple[str, str], list[dict]] = {(t, kind): [] for t in trees for kind in _KINDS}
    for _ in range(REPEATS):
        for kind in _KINDS:
            for t, tree in trees.items():
                runs[t, kind].append(_once(kind, tree))
    result = {kind: _medians(runs["now", kind]) for kind in _KINDS}
    if before_tree:
        result["before"] = {kind: _medians(runs["before", kind]) for kind in _KINDS}
    return result


def markdown(r: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    what = {"bare": "`import numpy, mujoco` (the floor)", "import": "`import simbench` (with its CLI and pipeline)",
            "validate": f"`simbench validate {SCENARIO}` (plan and check, no physics)"}
    before = {kind: (b["seconds"], b["peak_mib"]) for kind, b in r["before"].items()} if "before" in r else BEFORE
    rows = [f"| {what[kind]} | {r[kind]['seconds']:.3f} | {r[kind]['peak_mib']:.0f} | "
            f"{', '.join(r[kind]['heavy']) or 'none'} | {before[kind][0]:.3f} s, {before[kind][1]:.0f} MiB |"
            for kind in _KINDS]
    return "\n".join([
        f"### Start-up: fresh interpreters ({REPEATS} rounds in turn, medians)",
        "",
        "`python -m benchmarks.bench_startup`. Seconds from the interpreter's start of the work; peak resident MiB "
        "of the process. Before: commit e7ffd6e, which imported matplotlib, scipy's optimiser and spatial package "
        "and OMPL with simbench.",
        "",
        "| process | seconds | peak MiB | heavy libraries loaded | before |",
        "|---|---|---|---|---|",
        *rows,
    ])


if __name__ == "__main__":
    print(markdown(measure(*sys.argv[1:2])))
