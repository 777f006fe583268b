"""A bench run's plan against its simulation, per method, and runs per second on one core (issue 47's target: the
median run's plan at most 3 times its simulation).

Each run is a bench task's scenario (simbench.commands.bench.methods' document of a suite's task, seed SEED) evaluated
as
`simbench run` evaluates it, in this process, one after the other: the stages' wall times as report.json splits
them (load, plan, simulate, analyse). Per robot and method: the median of the runs' plan / simulate, the median
plan and simulate seconds, and the runs per second (runs over their summed wall time: one core, nothing else).
"""

from __future__ import annotations

import time

import numpy as np

from simbench.commands import pipeline
from simbench.commands.bench import load_suite
from simbench.commands.bench.methods import METHODS
from simbench.commands.bench.tasks import draw
from simbench.scenario import parse_scenario

ROBOTS = ("puma600", "jaco")
TASKS = 6
SEED = 0


def measure(robots: tuple[str, ...] = ROBOTS, tasks: int = TASKS) -> list[dict]:
    """A row per robot and method: runs, median plan / simulate, median plan and simulate seconds, runs/s; then a
    row per robot over all its methods' runs (`all`: the median bench run, the issue's target)."""
    rows = []
    for name in robots:
        suite = load_suite(name)
        robot = suite.robots[0]
        drawn = draw(robot, tasks, SEED)
        robot_rows = len(rows)
        for method in suite.methods:
            stages = []
            started = time.perf_counter()
            for task in drawn:
                document = METHODS[method].document(task, robot)
                if document is None:
                    continue
                watch = pipeline._Stopwatch()
                try:
                    pipeline._evaluate(parse_scenario(document, f"{task.id}-{method}"), watch=watch)
                except Exception:  # a failed run (no plan) still counts its wall time, not its ratio
                    continue
                stages.append(watch.summary())
            wall = time.perf_counter() - started
            if not stages:
                continue
            rows.append(_row(name, method, [s["plan"] for s in stages], [s["simulate"] for s in stages], wall))
        mine = rows[robot_rows:]
        rows.append(_row(name, "all", sum((r["plans"] for r in mine), []), sum((r["simulates"] for r in mine), []),
                         sum(r["wall"] for r in mine)))
    return rows


def _row(robot: str, method: str, plans: list[float], simulates: list[float], wall: float) -> dict:
    """A table row of runs' plan and simulate seconds, and the wall time they took in all."""
    plan, sim = np.array(plans), np.array(simulates)
    return {"robot": robot, "method": method, "runs": len(plan), "ratio": float(np.median(plan / sim)),
            "plan_s": float(np.median(plan)), "simulate_s": float(np.median(sim)), "runs_per_s": len(plan) / wall,
            "plans": plans, "simulates": simulates, "wall": wall}


def markdown(rows: list[dict]) -> str:
    """The results as a BENCHMARKS.md section."""
    lines = [f"### A bench run's plan against its simulation, one core ({TASKS} tasks a robot at seed {SEED})", "",
             "| robot | method | runs | plan / simulate (median) | plan s (median) | simulate s (median) | runs/s |",
             "|---|---|---|---|---|---|---|"]
    lines += [f"| {r['robot']} | {r['method']} | {r['runs']} | {r['ratio']:.1f} | {r['plan_s']:.3f} | "
              f"{r['simulate_s']:.3f} | {r['runs_per_s']:.2f} |" for r in rows]
    return "\n".join(lines + ["", "`all`: every run of the robot's methods (the median bench run). Target: the median "
                                   "run's plan at most 3 times its simulation."])


if __name__ == "__main__":
    print(markdown(measure()))
