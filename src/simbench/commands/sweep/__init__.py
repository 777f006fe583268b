"""Sweeps: a base scenario run over parameter grids and seeded random samples, on every core of this machine or
on a Ray cluster, into one table of results (file: sweep.spec; folder: sweep.store; table: sweep.table)."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from tqdm import tqdm

from simbench.commands.sweep import cluster, execute, table
from simbench.commands.sweep.spec import Sweep, Variant, load_sweep
from simbench.commands.sweep.store import RESULTS, Store, run_folder
from simbench.commands.sweep.workers import count as worker_count
from simbench.core import destination
from simbench.outputs.page import table_page, write_page
from simbench.outputs.report import write_report

__all__ = ["Sweep", "SweepResult", "load_sweep", "run_sweep"]


@dataclass(frozen=True)
class SweepResult:
    """A finished sweep: where its outputs are, its table as columns, and its summary."""

    out: Path
    table: dict[str, list]
    summary: dict
    resumed: int


def run_sweep(sweep: Sweep, out: str | Path | None = None, *, workers: int | None = None, ray: str | None = None,
              force: bool = False, progress: bool = False, allow_code: bool = False) -> SweepResult:
    """Run every variant that has no row yet in `out`, then write the table, summary and plots.

    A sweep stopped part way resumes where it stopped: the rows already in `out` are kept.

    Args:
        sweep: The sweep, from `load_sweep`.
        out: Its folder; default `renders/sweeps/<name>/`.
        workers: Processes at once (1 runs here); default, and capped by, the sweep's `workers` and the machine.
        ray: `"local"` or a Ray cluster's address, to run the variants there (the `ray` extra).
        force: Replace a folder that holds another sweep's outputs (only files simbench wrote).
        progress: Show a progress bar.
        allow_code: Let a variant's policy name a module to import; without it such a variant is `bad_input`.

    Returns:
        Where the outputs are, the table as columns, the summary and how many rows were resumed.

    Raises:
        ScenarioError: a bad argument, destination or Ray address, before any run.
    """
    out = destination.followed(Path(out) if out is not None else Path("renders") / "sweeps" / sweep.name)
    if ray is not None:
        cluster.reach(ray)  # before the folder is made: an address nobody answers at is one line, not a hang
    kept = sweep.spec.outputs
    with Store(out, sweep, force=force) as store:
        ran = run_remaining(store, workers, ray, progress, lambda v: {
            "document": v.document, "source": f"{sweep.source} {v.id}", "outputs": kept,
            "out": str(run_folder(out, v.id)) if kept == "full" else None, "video": sweep.spec.video,
            "allow_code": allow_code})
        columns = table.columns(list(ran.rows.values()), sweep.params)
        store.claim(RESULTS)
        with store.writing():  # a full disk here keeps the rows: the same command writes the table again
            summary = _write_results(sweep, columns, out, ran)
    return SweepResult(out, columns, summary, summary["resumed"])


@dataclass(frozen=True)
class Ran:
    """A store's rows by run index, how many an earlier start left, and where (`backend`, `workers`) and when the
    rest started."""

    rows: dict[int, dict]
    resumed: int
    backend: str
    workers: int
    start: float


def run_remaining(store: Store, workers: int | None, ray: str | None, progress: bool,
                  arguments: Callable[[Variant], dict]) -> Ran:
    """Run every variant of store.sweep (a sweep's or a bench's) that has no row yet, by
    run_variant(**arguments(variant)), recording each row as it finishes; the progress line names the run in
    progress longest and what it is doing (`run-id: planning`)."""
    sweep = store.sweep
    rows = store.finished()
    todo = [v for v in sweep.variants if v.index not in rows]
    if ray is None or ray == "local":
        workers = worker_count(sweep, todo, workers)
    else:  # a cluster elsewhere has its own CPUs and memory: here the plots are drawn
        workers = execute.processes_here(workers)
    start = time.perf_counter()
    tqdm.monitor_interval = 0  # no monitor thread: the worker processes are forked from this one
    with tqdm(total=len(sweep.variants), initial=len(rows), desc=sweep.name, unit="run", disable=not progress,
              leave=False) as bar:
        doing = _Doing(bar, sweep)
        outcomes, backend = _started([(v.index, arguments(v)) for v in todo], workers, ray, doing.told)
        for index, outcome in outcomes:
            rows[index] = store.record(sweep.variants[index], outcome)
            doing.done(index)
            bar.update()
    return Ran(rows, len(sweep.variants) - len(todo), backend, workers, start)


def _started(tasks: list[execute.Task], workers: int, ray: str | None,
             on_stage: execute.OnStage | None = None) -> tuple[Iterator[tuple[int, dict]], str]:
    """The outcomes of `tasks` as they finish, on a Ray cluster, in this process (one worker) or in worker
    processes, and a description of where they run; `on_stage` told of each stage a run enters (not on Ray)."""
    if ray is not None:
        return cluster.on_ray(tasks, ray, workers), f"ray ({ray})"
    if workers == 1:
        return execute.in_this_process(tasks, on_stage), "this process"
    return execute.in_processes(tasks, workers, on_stage), f"{workers} processes"


class _Doing:
    """What the runs in progress are doing, on the progress line: the one begun first, and how many more."""

    def __init__(self, bar: tqdm, sweep: Sweep):
        self.bar, self.sweep = bar, sweep
        self.stages: dict[int, str] = {}  # by run index, in the order the runs began

    def told(self, index: int, stage: str) -> None:
        """Run `index` entered `stage`."""
        self.stages[index] = stage
        self._show()

    def done(self, index: int) -> None:
        """Run `index` ended."""
        self.stages.pop(index, None)
        self._show()

    def _show(self) -> None:
        from simbench.commands.pipeline import doing  # the parent of worker processes may not have needed it yet

        if not self.stages:
            self.bar.set_postfix_str("", refresh=False)
            return
        index, stage = next(iter(self.stages.items()))
        more = f" (+{len(self.stages) - 1} more)" if len(self.stages) > 1 else ""
        self.bar.set_postfix_str(f"{self.sweep.variants[index].id}: {doing(stage)}{more}")


def _write_results(sweep: Sweep, columns: dict[str, list], out: Path, ran: Ran) -> dict:
    """Write the table, its plots (`ran.workers` figures at once), summary.json and the page; the summary."""
    table.write_csv(columns, out / "results.csv")
    no_parquet = table.write_parquet_where_installed(columns, out / "results.parquet")
    plots, notes = table.write_plots(columns, sweep.params, list(sweep.spec.grid), sweep.spec.plots, out / "plots",
                                     ran.workers)
    notes += [no_parquet] if no_parquet else []
    summary = {**table.summary(columns, sweep.spec.plots), "resumed": ran.resumed, "backend": ran.backend,
               "wall_time": round(time.perf_counter() - ran.start, 3),
               "outputs": {"table": ["results.csv"] + ([] if no_parquet else ["results.parquet"]),
                           "plots": [f"plots/{p}" for p in plots], "page": "index.html"},
               "notes": notes}
    write_report(summary, out / "summary.json")
    counts = ", ".join(f"{n} {status}" for status, n in summary["status"].items() if n)
    write_page(out, table_page(out, f"Sweep: {sweep.name}", f"{summary['runs']} runs of {sweep.base} ({counts}) on "
                                                             f"{ran.backend}.\n\n" + "\n".join(notes),
                               [("Every run (results.csv)", Path("results.csv"))], [f"plots/{p}" for p in plots],
                               summary))
    return summary
