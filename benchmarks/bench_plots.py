"""The plots by matplotlib (project issue 34): what drawing the demo's plots costs in each format, and what they
add to the default run's wall time now that they are drawn while the video renders.

Plots: `plots.write_plots` of `spherical_arm/demo` (simbench's five and the robot's own) into a fresh folder in each
format, in this process, PLOT_REPEATS times after one that loads matplotlib and its fonts: the medians. No target
(issue 34 retired issue 14's "plots at most 0.3 s"): a run draws them in a forked process beside its video.

The run: `simbench run scenarios/spherical_arm/demo.yaml` with its video, each a fresh process, its wall time,
REPEATS times. Given the source tree of the code before (`git archive <commit> src scenarios models | tar -x -C
TREE`, then `python -m benchmarks.bench_plots TREE`), that tree's runs alternate with these, so that a busy machine
slows both alike. Target: the run's median at most 0.5 s more than before's.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.common import shipped
from simbench.outputs.plot_formats import FORMATS
from simbench.outputs.plots import write_plots

REPEATS = 6
PLOT_REPEATS = 5
SCENARIO = "spherical_arm/demo"
ROOT = Path(__file__).resolve().parents[1]
# Commit 68b17da (simbench.chart: the plots by Pillow, before the video), in the same rounds as the figures now of
# 2026-11-28 in BENCHMARKS.md (AMD EPYC, 2 cores shared with other work): the run's median and range, s.
BEFORE = {"median": 2.58, "min": 2.25, "max": 3.15}


def measure_plots() -> dict[str, float]:
    """Median seconds of the demo's plots in each format, drawn as `simbench.run` draws them."""
    from simbench import evaluate

    sc = shipped(SCENARIO)
    ev = evaluate(sc)
    seconds = {}
    with tempfile.TemporaryDirectory() as tmp:
        for plot_format in FORMATS:
            times = []
            for i in range(PLOT_REPEATS + 1):
                start = time.perf_counter()
                write_plots(sc.robot_def, ev.trajectory, ev.recording, ev.analysis, Path(tmp) / f"{plot_format}{i}",
                            plot_format)
                times.append(time.perf_counter() - start)
            seconds[plot_format] = float(np.median(times[1:]))
    return seconds


def _run(tree: Path, out: Path) -> float:
    """Wall seconds of one `simbench run` of the demo, with video, by the simbench of `tree` in a fresh process."""
    env = {**os.environ, "PYTHONPATH": str(tree / "src")}
    start = time.perf_counter()
    subprocess.run([sys.executable, "-P", "-m", "simbench", "run", f"scenarios/{SCENARIO}.yaml", "--out", str(out),
                    "--quiet"], cwd=tree, env=env, check=True)
    return time.perf_counter() - start


def _spread(times: list[float]) -> dict[str, float]:
    return {"median": float(np.median(times)), "min": min(times), "max": max(times)}


def measure(before_tree: str | None = None) -> dict:
    """The plots' seconds by format, and the run's wall times (with `before_tree`, that tree's in turn)."""
    trees = {"now": ROOT, **({"before": Path(before_tree).resolve()} if before_tree else {})}
    times: dict[str, list[float]] = {name: [] for name in trees}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(REPEATS):
            for name, tree in trees.items():
                times[name].append(_run(tree, Path(tmp) / f"{name}{i}"))
    return {"plots": measure_plots(), "runs": {name: _spread(t) for name, t in times.items()},
            "pairs": [float(a - b) for a, b in zip(times["now"], times.get("before", []))]}


def markdown(r: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    now, before = r["runs"]["now"], r["runs"].get("before", BEFORE)
    growth = now["median"] - before["median"]
    pairs = f" (pairs, now - before: {', '.join(f'{x:+.2f}' for x in r['pairs'])})" if r["pairs"] else ""
    return "\n".join([
        f"### Plots by matplotlib, drawn while the video renders: `{SCENARIO}`",
        "",
        "`python -m benchmarks.bench_plots [TREE]`. Before: commit 68b17da (the plots drawn by Pillow, before the "
        "video)" + (", run in turn with these." if r["pairs"] else ", the figures of its last run in turn with these."),
        "",
        "| `simbench run` with video, fresh process | median s | min s | max s |",
        "|---|---|---|---|",
        f"| now ({REPEATS} runs) | {now['median']:.2f} | {now['min']:.2f} | {now['max']:.2f} |",
        f"| before | {before['median']:.2f} | {before['min']:.2f} | {before['max']:.2f} |",
        "",
        f"The run's median grew by {growth:+.2f} s{pairs}. Target: at most +0.5 s.",
        "",
        f"The demo's plots alone, in this process (median of {PLOT_REPEATS}): "
        + ", ".join(f"{fmt.upper()} {s:.3f} s" for fmt, s in r["plots"].items()) + ". No target: drawn beside the "
        "video.",
    ])


if __name__ == "__main__":
    print(markdown(measure(*sys.argv[1:2])))
