"""Running a sweep's variants: one function per run, called in this process, in forked worker processes or on a
Ray cluster (simbench.commands.sweep.cluster), with the same outcomes. A run never raises: every failure is an outcome
with
a status and a one-line error, a run that kills its worker a `crashed` one (on Ray, after one more attempt), so
that the table has a row for every run.
"""

from __future__ import annotations

import functools
import multiprocessing
import os
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from multiprocessing import connection
from typing import Any, NamedTuple

from simbench.core.errors import RunError, ScenarioError, TooSlow
from simbench.core.forked import as_worker, die_with, parents_heap_frozen
from simbench.core.plant import reused_plants
from simbench.outputs.figures import columns

# Report keys that describe the run rather than measure it.
_NOT_METRICS = {"scenario", "robot", "planner", "versions", "timestep", "duration", "hold", "settle", "time_law",
                "samples", "plan", "waypoints", "wall_time", "outputs", "config"}

Task = tuple[int, dict]  # (run index, keyword arguments of run_variant)
OnStage = Callable[[int, str], None]  # told (run index, stage) as a run enters a stage (pipeline.watched)


class Stage(NamedTuple):
    """A worker's word that its run entered a stage, sent before its outcome."""

    name: str


def run_variant(document: dict, source: str, outputs: str = "none", out: str | None = None,
                video: bool = False, allow_code: bool = False, limits: dict[str, float] | None = None) -> dict:
    """Plan, simulate and analyse one scenario document (with outputs='full' writing every output into `out`; a
    stage named in `limits` cut past its seconds, `too_slow`); its outcome: `status`, `error`, `metrics`,
    `wall_time` (s) and, with outputs='report', the `report`."""
    start = time.perf_counter()
    report, status, error = _attempt(document, source, outputs, out, video, allow_code, limits)
    return {"status": status, "error": error, "metrics": metrics(report) if report else {},
            "wall_time": time.perf_counter() - start, "report": report if outputs == "report" else None}


def _attempt(document: dict, source: str, outputs: str, out: str | None, video: bool,
             allow_code: bool, limits: dict[str, float] | None) -> tuple[dict | None, str, str]:
    """One run as (its report if it got that far, status, one-line error); every failure caught."""
    from simbench.commands import pipeline
    from simbench.scenario import parse_scenario

    report = None
    try:
        scenario = parse_scenario(document, source)
        with pipeline.limited(limits):
            if outputs == "full":
                report = pipeline.run(scenario, out=out, video=video, force=True, allow_code=allow_code).report
            else:
                report = pipeline.evaluate_report(scenario, allow_code)
        return report, report["status"], "; ".join(f"{v['kind']}: {v['message']}" for v in report["violations"])
    except ScenarioError as err:
        return report, "bad_input", err.detail
    except TooSlow as err:
        return report, "too_slow", str(err)
    except RunError as err:
        return report, "run_failed", str(err)
    except Exception as err:  # any other failure is this run's row, not the end of the sweep
        return report, "crashed", f"{type(err).__name__}: {err}"


def metrics(report: dict) -> dict[str, Any]:
    """The report's measurements as flat columns (`tool_rms`, `joint_rms.q1`, <metric>.<figure>, `kci.mean`),
    and each list of events as its count and its kinds (`singularity_events.kinds`)."""
    flat: dict[str, Any] = {}
    for key, value in report.items():
        if key in _NOT_METRICS:
            continue
        if isinstance(value, list):
            flat[key] = len(value)
            flat[f"{key}.kinds"] = ",".join(sorted({str(e["kind"]) for e in value if isinstance(e, dict)
                                                    and "kind" in e}))
        elif key == "metrics":
            for name, figures in value.items():
                flat.update(columns(name, figures))
        else:
            _flatten("" if key == "tracking" else key, value, flat)
    return flat


def _flatten(prefix: str, value: Any, into: dict) -> None:
    if isinstance(value, dict):
        for k, v in value.items():
            _flatten(f"{prefix}.{k}" if prefix else str(k), v, into)
    elif isinstance(value, (bool, int, float)) or value is None:
        into[prefix] = value


def crashed(reason: str) -> dict:
    """The outcome of a run whose process or worker died before it could answer."""
    return {"status": "crashed", "error": reason, "metrics": {}, "wall_time": None, "report": None}


def in_this_process(tasks: Iterable[Task], on_stage: OnStage | None = None) -> Iterator[tuple[int, dict]]:
    """Each run in turn, here, reusing the Plant of the run before when it is the same; `on_stage` told of each
    stage each run enters."""
    from simbench.commands import pipeline

    with reused_plants():
        for index, kwargs in tasks:
            with pipeline.told(functools.partial(on_stage or _ignore, index)):
                outcome = run_variant(**kwargs)
            yield index, outcome


def _ignore(*told) -> None:
    """A listener that does nothing with what it is told."""


def in_processes(tasks: Iterable[Task], workers: int, on_stage: OnStage | None = None) -> Iterator[tuple[int, dict]]:
    """Up to `workers` runs at a time in forked worker processes; outcomes as they finish, `on_stage` told of each
    stage a run enters as its worker says. A worker that dies takes only its own run with it (`crashed`) and is
    replaced; one that answers gets its next run at once."""
    ctx = multiprocessing.get_context("fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn")
    todo = deque(tasks)
    idle = [_Worker(ctx) for _ in range(min(workers, len(todo)))]
    busy: dict[Any, _Worker] = {}
    try:
        _dispatch(todo, idle, busy)
        while busy:
            for conn in connection.wait(list(busy)):
                worker = busy[conn]
                index = worker.index
                try:
                    outcome = conn.recv()
                except EOFError:  # the worker died in the middle of its run
                    outcome = crashed(f"its worker process died (exit code {worker.stop()})")
                    worker = _Worker(ctx)
                if isinstance(outcome, Stage):  # the run goes on
                    (on_stage or _ignore)(index, outcome.name)
                    continue
                del busy[conn]
                idle.append(worker)
                _dispatch(todo, idle, busy)
                yield index, outcome
    finally:
        for worker in idle + list(busy.values()):
            worker.stop()


def _dispatch(todo: deque, idle: list, busy: dict) -> None:
    """Give the next runs to idle workers, in run order, while there are both."""
    while todo and idle:
        worker = idle.pop()
        worker.give(*todo.popleft())
        busy[worker.conn] = worker


class _Worker:
    """A process that runs one variant at a time, sent over a pipe."""

    def __init__(self, ctx):
        self.conn, theirs = ctx.Pipe()
        self.process = ctx.Process(target=_serve, args=(theirs, os.getpid()),
                                   name="simbench-sweep-worker", daemon=True)
        with parents_heap_frozen():
            self.process.start()
        theirs.close()
        self.index = -1

    def give(self, index: int, kwargs: dict) -> None:
        """Start a run."""
        self.index = index
        self.conn.send(kwargs)

    def stop(self) -> int | None:
        """End the process (at once, mid-run or not); its exit code. SIGKILL, not SIGTERM: a worker stopped as soon
        as it is forked may not yet have reset the SIGTERM handler it inherits (as_worker), which would swallow it
        and leave this join waiting for ever."""
        self.conn.close()
        if self.process.is_alive():
            self.process.kill()
        self.process.join()
        return self.process.exitcode


def _serve(conn, parent: int) -> None:
    """A worker's loop: run each variant received until the pipe closes, reusing the Plant of the run before; each
    stage a run enters sent before its outcome."""
    die_with(parent)
    as_worker()
    from simbench.commands import pipeline

    with reused_plants(), pipeline.told(lambda name: conn.send(Stage(name))):
        while True:
            try:
                kwargs = conn.recv()
            except EOFError:
                return
            conn.send(run_variant(**kwargs))


def cpu_count() -> int:
    """CPUs this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def processes_here(workers: int | None) -> int:
    """Processes this machine runs at once for `workers` asked (None: one a CPU), at most its CPUs."""
    return min(workers or cpu_count(), cpu_count())
