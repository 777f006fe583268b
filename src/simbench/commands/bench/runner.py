"""Running a suite: every task of every robot by every method that applies, through the sweep's machinery (its
folder store, so that the same command resumes, worker processes or Ray, crash isolation), each run the real
pipeline (simbench.commands.sweep.execute.run_variant) of the scenario file written for it first, the bench's results
beside (simbench.commands.bench.outputs).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

from simbench.commands.bench import board, kept_tasks, outputs
from simbench.commands.bench.methods import METHODS
from simbench.commands.bench.suite import Suite
from simbench.commands.bench.tasks import Task, draw_all
from simbench.commands.sweep import cluster, execute, run_remaining, table
from simbench.commands.sweep.spec import Sweep, Variant
from simbench.commands.sweep.store import Store, check_early
from simbench.core import destination
from simbench.core.errors import ScenarioError
from simbench.core.version import __version__
from simbench.scenario.schema import SimbenchModel


class BenchSpec(SimbenchModel):
    """What decides a bench's runs, as its folder's manifest records it (a resume into a folder whose manifest holds
    another is refused: simbench.commands.sweep.store): the version of the benchmark's definition and each robot's
    model hash
    (bench.robots.BenchRobot.model_hash) among them; `outputs` and `video` as a sweep's spec has them (a bench keeps
    no run's own outputs)."""

    suite: str
    version: str
    tasks: int
    seed: int
    methods: list[str]
    robots: list[str]
    models: dict[str, str]
    max_slowdown: float
    plan_seconds: float
    outputs: ClassVar[str] = "none"
    video: ClassVar[bool] = False


@dataclass(frozen=True)
class Bench(Sweep):
    """A suite drawn into runs, which simbench.commands.sweep stores and runs as a sweep's."""

    spec: BenchSpec  # type: ignore[assignment]
    _SPEC_KEY: ClassVar[str] = "bench"

    @property
    def params(self) -> list[str]:
        return list(board.PARAMS)


@dataclass(frozen=True)
class BenchResult:
    """A finished bench: its folder, its runs and leaderboard as columns, and its summary."""

    out: Path
    runs: dict[str, list]
    leaderboard: dict[str, list]
    summary: dict


def plan_bench(suite: Suite, workers: int = 1, tasks: list[list[Task]] | None = None,
               spec: BenchSpec | None = None) -> Bench:
    """Every run of the suite: its tasks per robot (`tasks`, one list a robot; else drawn by `workers` processes:
    bench.tasks), each by every method that applies; `spec`: bench_spec(suite), where the caller has it."""
    if tasks is None:
        tasks = draw_all(suite.robots, suite.tasks, suite.seed, suite.version, workers)
    variants: list[Variant] = []
    for robot, own in zip(suite.robots, tasks):
        for task in own:
            for name in suite.methods:
                method = METHODS[name]
                document = method.document(task, robot)
                if document is None:
                    continue
                params = {"robot": robot.name, "task": task.id, "kind": task.kind, "shape": task.shape,
                          "method": name, "planner": document["planner"], "anchor_gap": task.anchor_gap,
                          "length_mm": task.length * 1e3, "duration": round(task.duration, 6)}
                variants.append(Variant(len(variants), f"{task.id}-{name}", params, document))
    return Bench(suite.name, suite.source, spec or bench_spec(suite), Path(suite.source), tuple(variants))


def bench_spec(suite: Suite) -> BenchSpec:
    """What decides the suite's runs, as its folder's manifest records it (BenchSpec)."""
    return BenchSpec(suite=suite.name, version=suite.version, tasks=suite.tasks, seed=suite.seed,
                     methods=list(suite.methods), robots=[r.name for r in suite.robots],
                     models={r.name: r.model_hash() for r in suite.robots}, max_slowdown=suite.max_slowdown,
                     plan_seconds=suite.plan_seconds)


def run_bench(suite: Suite, out: str | Path | None = None, *, workers: int | None = None, ray: str | None = None,
              force: bool = False, progress: bool = False) -> BenchResult:
    """Write the suite's tasks and every run's scenario file, run every run of the suite that has no row yet in
    `out`, then write its tables, plots and page. A resume takes the tasks `out` keeps where they are the suite's
    (bench.kept_tasks); otherwise they are drawn here (on Ray too).

    Args:
        suite: The suite, from `load_suite` (`suite.with_options(tasks=..., methods=...)` to change it).
        out: Its folder; default `renders/bench/<name>/`.
        workers: Processes at once, as `simbench.commands.sweep.run_sweep`'s.
        ray: `"local"` or a Ray cluster's address (the `ray` extra).
        force: Replace a folder that holds another bench's outputs (only files simbench wrote).
        progress: Show a progress bar.

    Returns:
        Its folder, runs.csv and leaderboard.csv as columns, and summary.json's content.

    Raises:
        ScenarioError: a bad argument, destination or Ray address, before any run.
    """
    out = destination.followed(Path(out) if out is not None else Path("renders") / "bench" / suite.name)
    source, spec = Path(suite.source), bench_spec(suite)  # (the models' hashes read once)
    check_early(out, [source] if source.is_file() else [], spec.model_dump(mode="json"), force)
    tasks = kept_tasks.tasks_for(out, suite, spec.models, execute.processes_here(workers), force)
    bench = plan_bench(suite, tasks=tasks, spec=spec)
    if not bench.variants:
        raise ScenarioError(suite.source, "methods", f"no run: no robot of the suite "
                                                     f"({', '.join(r.name for r in suite.robots)}) takes one of its "
                                                     f"methods ({', '.join(suite.methods)})")
    if ray is not None:
        cluster.reach(ray)
    with Store(out, bench, force=force) as store:
        kept_tasks.keep(store, out, suite, spec.models, tasks)
        outputs.write_scenarios(store, out, bench)
        ran = run_remaining(store, workers, ray, progress, lambda v: {
            "document": v.document, "source": f"{bench.source} {v.id}", "outputs": "none",
            "limits": {"plan": suite.plan_seconds}})
        runs = board.runs_table(list(ran.rows.values()), suite.max_slowdown)
        leaderboard = board.leaderboard(runs, suite.seed)
        by_kind = board.leaderboard(runs, suite.seed, ("robot", "method", "kind"))
        summary = {"suite": suite.name, "version": suite.version, "simbench": __version__, "source": suite.source,
                   "tasks": suite.tasks, "seed": suite.seed, "methods": list(suite.methods),
                   "robots": [r.name for r in suite.robots], "models": dict(bench.spec.models),
                   "max_slowdown": suite.max_slowdown, "plan_seconds": suite.plan_seconds,
                   "runs": len(bench.variants),
                   "status": table.status_counts(runs["status"]), "resumed": ran.resumed,
                   "backend": ran.backend, "wall_time": round(time.perf_counter() - ran.start, 3)}
        outputs.write(store, out, runs, (leaderboard, by_kind), summary, ran.workers)
    return BenchResult(out, runs, leaderboard, summary)

