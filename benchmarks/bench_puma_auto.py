"""`configuration: auto` on random reachable PUMA 600 lines (project issue 17): how many it runs within limits, how
many it refuses and why, and how many the fixed default configuration would have run beyond a limit.

Two sets of 50 lines (random_tasks.puma_lines, fixed seeds): the torch at a uniform random orientation, and the
torch within 60 deg of straight down (as a welding torch is held). Each accepted plan is simulated and its
status read from the run's own verdict; each refusal is sorted by the joint and the limit it names.
"""

from __future__ import annotations

import re
from collections import Counter

import numpy as np

from simbench.commands.pipeline import check_plan, evaluate
from simbench.core.errors import RunError
from simbench.planners.random_tasks import puma_lines
from simbench.scenario import parse_scenario

DRAWS = 50
SETS = {"uniform torch orientation": None, "torch within 60 deg of straight down": np.deg2rad(60.0)}
_REASON = re.compile(r"(q\d) is asked for [-\d.]+ (deg/s|deg)")


def _fixed(doc: dict) -> str:
    """The plan's status in the fixed configuration righty/up/noflip (the one a task got before `auto`)."""
    task = {**doc["task"], "configuration": {"arm": "righty", "elbow": "up", "wrist": "noflip"}}
    return check_plan(parse_scenario({**doc, "task": task}, doc["name"]))[1].status


def measure_set(cone: float | None, seed: int) -> dict:
    """Counts of one set: run statuses of the accepted, reasons of the refused, configurations chosen."""
    runs, refused, chosen, fixed = Counter(), Counter(), Counter(), Counter()
    for doc in puma_lines(DRAWS, seed, cone):
        fixed[_fixed(doc)] += 1
        scenario = parse_scenario(doc, doc["name"])
        try:
            traj, _ = check_plan(scenario)
        except RunError as err:
            joint, unit = _REASON.search(str(err)).groups()
            refused[f"{joint} {'speed' if unit == 'deg/s' else 'range'}"] += 1
            continue
        chosen[traj.info["configuration"]["chosen"]] += 1
        runs[evaluate(scenario).verdict.status] += 1
    return {"runs": dict(runs), "refused": dict(refused), "chosen": dict(chosen), "fixed": dict(fixed)}


def measure() -> dict:
    return {name: measure_set(cone, seed) for seed, (name, cone) in enumerate(SETS.items(), start=17)}


def markdown(r: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    rows = []
    for name, c in r.items():
        refused = sum(c["refused"].values())
        why = ", ".join(f"{k}: {v}" for k, v in sorted(c["refused"].items(), key=lambda kv: -kv[1]))
        runs = ", ".join(f"{k} {v}" for k, v in sorted(c["runs"].items()))
        rows.append(f"| {name} | {sum(c['runs'].values())} ({runs}) | {refused} ({why}) | "
                    f"{c['fixed'].get('limits', 0)} of {DRAWS} |")
    return "\n".join([
        f"### PUMA 600 `configuration: auto` on {DRAWS} random reachable lines a set (fixed seeds)",
        "",
        "| torch | planned and run (run status) | refused (the nearest configuration's worst joint and limit) | "
        "beyond a limit in righty/up/noflip |",
        "|---|---|---|---|",
        *rows,
        "",
        "Lines between uniform points of a box around the reach, every point reachable by the wrist centre, 0.2 m/s "
        "mean tool speed. A refusal means no configuration of the 8 keeps the whole line inside the joint ranges "
        "(PUMA 560 ranges) and speed limits; the commonest cause is q5 beyond +-100 deg.",
    ])


if __name__ == "__main__":
    print(markdown(measure()))
