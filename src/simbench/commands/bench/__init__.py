"""Benchmarks of singularity handling, method against method: `simbench bench SUITE`.

    suite = load_suite("puma600")                     # a shipped suite by robot name, or a suite file
    result = run_bench(suite.with_options(tasks=20), workers=2)
    result.leaderboard["ok_share"]

A suite (bench.suite) is robots, random tasks per robot through, near and far from its singular set (bench.tasks),
and methods (bench.methods); the runs (bench.runner) go into tables (bench.board), plots and a page (bench.outputs).
"""

from __future__ import annotations

import importlib

__all__ = ["BenchResult", "Suite", "load_suite", "plan_bench", "run_bench"]
_HOMES = {"BenchResult": "runner", "plan_bench": "runner", "run_bench": "runner", "Suite": "suite",
          "load_suite": "suite"}


def __getattr__(name: str):
    """The public names, imported on first use: the CLI's parser imports simbench.commands.bench.command alone."""
    if name in _HOMES:
        return getattr(importlib.import_module(f"simbench.commands.bench.{_HOMES[name]}"), name)
    raise AttributeError(f"module 'simbench.commands.bench' has no attribute {name!r}")
