"""A sweep on 2 worker processes against the same sweep in 1 process, in one run.

The sweep is 100 variants of paper 000's case 1 with random durations (outputs: none, so each run's work is
planning, simulation and analysis), timed whole through `simbench.sweep.run_sweep`: the table, summary and
plots included. Target (issue 6): at least 1.8.

The ceiling is measured in the same run: the same two-against-one speed-up for pure CPU work (a Python loop,
nothing shared, in forked processes), because this machine's two cores do not make two of one. A lone busy
thread often runs up to twice as fast as each of two (the host's boost, or a sibling's idle time): the sweep's
ratio is only as good as the machine's. The four timings are taken in turn, REPEATS times.
"""

from __future__ import annotations

import multiprocessing
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

from simbench.sweep import load_sweep, run_sweep

REPEATS = 5
_BURN = 20_000_000  # loop iterations of one unit of pure CPU work (about a second)
RUNS = 100
SPEC = {"base": "spherical_arm/case1", "outputs": "none",
        "random": {"samples": RUNS, "seed": 0, "params": {"timing.duration": {"uniform": [2.0, 6.0]}}}}


def _burn(n: int = _BURN) -> int:
    total = 0
    for i in range(n):
        total += i
    return total


def _cpu_work(workers: int) -> None:
    """Two units of pure CPU work, in this process or in two forked ones."""
    if workers == 1:
        _burn(), _burn()
    else:
        with multiprocessing.get_context("fork").Pool(2) as pool:
            pool.map(_burn, [_BURN, _BURN])


def _seconds(fn) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def measure() -> dict:
    """Median seconds of the sweep with 1 and 2 workers, and the median pairwise speed-ups of the sweep and of
    pure CPU work."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.yaml"
        path.write_text(yaml.safe_dump(SPEC))
        sweep = load_sweep(path)
        count = iter(range(1_000_000))

        def sweep_on(workers: int):
            return lambda: run_sweep(sweep, Path(tmp) / f"out{next(count)}", workers=workers)

        jobs = {"sweep1": sweep_on(1), "sweep2": sweep_on(2), "cpu1": lambda: _cpu_work(1),
                "cpu2": lambda: _cpu_work(2)}
        for fn in jobs.values():  # warm-up
            fn()
        times = {name: [] for name in jobs}
        for _ in range(REPEATS):
            for name, fn in jobs.items():
                times[name].append(_seconds(fn))
    t = {name: np.array(v) for name, v in times.items()}
    return {"runs": RUNS, "one_s": float(np.median(t["sweep1"])), "two_s": float(np.median(t["sweep2"])),
            "speedup": float(np.median(t["sweep1"] / t["sweep2"])),
            "cpu_speedup": float(np.median(t["cpu1"] / t["cpu2"]))}


def markdown(r: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    return "\n".join([
        f"### Sweep: 2 processes against 1 ({r['runs']} runs of `spherical_arm/case1`, {REPEATS} rounds in turn)",
        "",
        "| workers | seconds (median) | runs/s |",
        "|---|---|---|",
        f"| 1 (in this process) | {r['one_s']:.2f} | {r['runs'] / r['one_s']:.1f} |",
        f"| 2 (forked worker processes) | {r['two_s']:.2f} | {r['runs'] / r['two_s']:.1f} |",
        "",
        f"Speed-up (median of pairwise ratios): {r['speedup']:.2f}. Target: at least 1.8.  ",
        f"The machine's own ceiling, pure CPU work on 2 processes against 1 in the same run: "
        f"{r['cpu_speedup']:.2f}; the sweep reaches {r['speedup'] / r['cpu_speedup']:.0%} of it.",
    ])


if __name__ == "__main__":
    print(markdown(measure()))
