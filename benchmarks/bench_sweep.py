"""A sweep on 2 worker processes against the same sweep in 1 process, in one run.

The sweep is 100 variants of paper 000's case 1 with random durations (outputs: none, so each run's work is
planning, simulation and analysis), timed whole through `simbench.sweep.run_sweep`: the table, summary and
plots included. Target (issue 6): at least 1.8.

Two figures say what limits the ratio, both measured in the same run:
- the sweep's serial part: writing the table, summary and plots after the last run, timed as the rerun of a
  finished sweep (nothing left to run); by Amdahl's law it caps the speed-up on two free cores;
- the same two-against-one speed-up for a reference workload, pure CPU work (a Python loop, nothing shared, in
  forked processes): this virtual machine's two cores do not make two of one, and how far they fall short
  changes from minute to minute.
The timings are taken in turn, REPEATS times, and each figure is the median.
"""

from __future__ import annotations

import multiprocessing
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

from simbench.sweep import load_sweep, run_sweep

REPEATS = 7
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
    """Median seconds of the sweep with 1 and 2 workers and of its serial part, and the median pairwise
    speed-ups of the sweep and of the reference workload."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.yaml"
        path.write_text(yaml.safe_dump(SPEC))
        sweep = load_sweep(path)
        count = iter(range(1_000_000))
        last = Path(tmp) / "unset"

        def sweep_on(workers: int):
            def run() -> None:
                nonlocal last
                last = Path(tmp) / f"out{next(count)}"
                run_sweep(sweep, last, workers=workers)
            return run

        jobs = {"sweep1": sweep_on(1), "sweep2": sweep_on(2), "serial": lambda: run_sweep(sweep, last, workers=1),
                "cpu1": lambda: _cpu_work(1), "cpu2": lambda: _cpu_work(2)}
        for fn in jobs.values():  # warm-up
            fn()
        times = {name: [] for name in jobs}
        for _ in range(REPEATS):
            for name, fn in jobs.items():
                times[name].append(_seconds(fn))
    t = {name: np.array(v) for name, v in times.items()}
    one, serial = np.median(t["sweep1"]), np.median(t["serial"])
    return {"runs": RUNS, "one_s": float(one), "two_s": float(np.median(t["sweep2"])), "serial_s": float(serial),
            "speedup": float(np.median(t["sweep1"] / t["sweep2"])),
            "amdahl": float(one / ((one - serial) / 2 + serial)),
            "reference_speedup": float(np.median(t["cpu1"] / t["cpu2"]))}


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
        f"The sweep's serial part (table, summary and plots after the last run): {r['serial_s']:.2f} s, which caps "
        f"the speed-up on two free cores at {r['amdahl']:.2f}.  ",
        f"The reference workload (pure CPU work, nothing shared) on 2 processes against 1 in the same rounds: "
        f"{r['reference_speedup']:.2f}: the machine's two cores are not two of one.",
    ])


if __name__ == "__main__":
    print(markdown(measure()))
