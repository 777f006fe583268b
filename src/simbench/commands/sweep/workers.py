"""How many runs of a sweep go at once: as asked (default: one per CPU), but no more than the CPUs, the runs to
do, or what the memory budget affords for the largest run plus a worker's own WORKER_BYTES (BENCHMARKS.md, the
sweep's notes). A cut is said in one line on stderr.
"""

from __future__ import annotations

import sys

from simbench.commands.sweep import execute
from simbench.commands.sweep.spec import Sweep, Variant
from simbench.core import budget

WORKER_BYTES = 64 * 10**6


def count(sweep: Sweep, todo: list[Variant], asked: int | None, stream=None) -> int:
    """Runs at once for `todo`; a line on `stream` says why where fewer than asked (or than the CPUs)."""
    cpus = execute.cpu_count()
    reasons = []
    if asked and asked > cpus:
        reasons.append(f"more than the {cpus} CPUs this process may use")
    workers = min(asked or cpus, cpus, max(1, len(todo)))
    if workers > 1:
        limits = budget.machine_limits()
        need = _largest_run(sweep, todo) + WORKER_BYTES
        afforded = max(1, int(limits.memory // need))
        if afforded < workers:
            reasons.append(f"each may need about {budget.size(need)} (its largest run and its worker) of the "
                           f"{budget.size(limits.memory)} memory budget ({limits.memory_basis})")
            workers = afforded
    if reasons:
        what = f"{asked} workers asked for" if asked else f"one worker per CPU ({cpus})"
        print(f"warning: {what}, {'; '.join(reasons)}: running {workers} at once", file=stream or sys.stderr)
    return workers


def _largest_run(sweep: Sweep, todo: list[Variant]) -> int:
    """The budget's estimate of the largest run (one the schema refuses takes none)."""
    from simbench.scenario import parse_scenario

    largest = 0
    for variant in todo:
        try:
            ask = budget.Ask.of(parse_scenario(variant.document, variant.id), video=sweep.spec.video,
                                outputs=sweep.spec.outputs == "full")
        except Exception:  # noqa: BLE001  a run that cannot be estimated fails as its own row, not here
            continue
        largest = max(largest, budget.estimate(ask).memory)
    return largest
