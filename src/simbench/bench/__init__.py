"""Benchmarks of singularity handling, method against method: `simbench bench SUITE`.

    suite = load_suite("puma600")                     # a shipped suite by robot name, or a suite file
    result = run_bench(suite.with_options(tasks=20), workers=2)
    result.leaderboard["ok_share"]

A suite (simbench.bench.suite) is robots, random tasks per robot drawn through, near and far from each one's singular
set (simbench.bench.tasks), and methods (simbench.bench.methods); every run is simbench's pipeline, run by the
sweep's machinery (simbench.bench.runner), into runs.csv and leaderboard.csv (simbench.bench.board), plots and a
page (simbench.bench.outputs).
"""

from __future__ import annotations

import importlib

__all__ = ["BenchResult", "Suite", "load_suite", "plan_bench", "run_bench"]
_HOMES = {"BenchResult": "runner", "plan_bench": "runner", "run_bench": "runner", "Suite": "suite",
          "load_suite": "suite"}


def __getattr__(name: str):
    """The public names, imported on first use: the CLI's parser imports simbench.bench.command alone."""
    if name in _HOMES:
        return getattr(importlib.import_module(f"simbench.bench.{_HOMES[name]}"), name)
    raise AttributeError(f"module 'simbench.bench' has no attribute {name!r}")
