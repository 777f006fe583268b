"""`simbench bench` on 2 worker processes against the same bench on 1, in one run (issue 36's target: at least
1.6 times as fast).

The bench is the shipped `puma600` suite at seed 0, TASKS tasks by each of its methods, timed whole through
`simbench.commands.bench.run_bench` (the runs, then runs.csv, the leaderboards, the plots and index.html), each time
into
a fresh folder so that nothing resumes. The two are timed in turn, REPEATS rounds after one warm-up of each; the
speed-up is the median of the rounds' ratios. Beside it, the same two-against-one speed-up of pure CPU work
(bench_sweep's reference: forked processes, nothing shared), measured in the same rounds: how far this machine's
two cores fall short of two of one at the time. The PUMA's runs take a similar time each; a suite with one run
much longer than the rest (the planar 3R's, whose time_scaling of a line ending at full stretch simulates 50 s)
is bounded by that run, however many workers.

Also in the same rounds: the draw of DRAW_TASKS tasks of the UR3's suite (whose singular set each `through` and
`near` task searches by minimising its gap: the slowest draw of the shipped arms) by 1 process and by 2
(`simbench.commands.bench.tasks.draw_all`, as a bench of 2 workers draws them before its runs), the same tasks. A
task's draws run one after another, so its longest task bounds the speed-up. And a finished bench of those
tasks by pinv alone (2 workers) run again in its folder, a resume with every run's row on disk: taking the tasks
its folder keeps (`simbench.commands.bench.kept_tasks`), and with that record removed first, drawing them again
(as every resume did before the folder kept them).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.bench_sweep import _cpu_work
from simbench.commands.bench import load_suite, run_bench
from simbench.commands.bench.kept_tasks import KEPT
from simbench.commands.bench.tasks import bands, draw_all

SUITE = "puma600"
TASKS = 10
SEED = 0
REPEATS = 3
DRAW_SUITE = "ur3"
DRAW_TASKS = 20


def _seconds(fn) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def measure(tasks: int = TASKS, repeats: int = REPEATS, draw_tasks: int = DRAW_TASKS) -> dict:
    """Median seconds of the bench on 1 and 2 workers, the median pairwise speed-up, and the reference's; the same
    for the draw of `draw_tasks` tasks of DRAW_SUITE."""
    suite = load_suite(SUITE).with_options(tasks=tasks, seed=SEED)
    drawn = load_suite(DRAW_SUITE).robots
    runs = 0
    tasks_by: dict[int, list] = {}

    def draw_on(workers: int):
        def run() -> None:
            tasks_by[workers] = draw_all(drawn, draw_tasks, SEED, workers=workers)
        return run
    with tempfile.TemporaryDirectory() as tmp:
        count = iter(range(1_000_000))

        def bench_on(workers: int):
            def run() -> None:
                nonlocal runs
                runs = run_bench(suite, Path(tmp) / f"out{next(count)}", workers=workers).summary["runs"]
            return run

        resumed, finished = load_suite(DRAW_SUITE).with_options(draw_tasks, SEED, ["pinv"]), Path(tmp) / "finished"

        def resume(kept: bool):
            def run() -> None:
                if not kept:
                    (finished / KEPT).unlink()
                run_bench(resumed, finished, workers=2)
            return run

        jobs = {"one": bench_on(1), "two": bench_on(2), "cpu1": lambda: _cpu_work(1), "cpu2": lambda: _cpu_work(2),
                "draw1": draw_on(1), "draw2": draw_on(2), "resume_kept": resume(True), "resume_drawn": resume(False)}
        for name, fn in jobs.items():  # warm-up (the draws: what every draw reads, made once, as a bench makes it)
            if not name.startswith(("draw", "resume")):
                fn()
        run_bench(resumed, finished, workers=2)  # the bench the resumes find finished
        for robot in drawn:
            robot.model_arm().contacts()
            bands(robot)
        times: dict[str, list[float]] = {name: [] for name in jobs}
        for _ in range(repeats):
            for name, fn in jobs.items():
                times[name].append(_seconds(fn))
    if tasks_by[1] != tasks_by[2]:
        raise AssertionError("the tasks drawn by 2 processes are not those drawn by 1")
    t = {name: np.array(v) for name, v in times.items()}
    return {"suite": SUITE, "tasks": tasks, "methods": list(suite.methods), "runs": runs, "repeats": repeats,
            "one_s": float(np.median(t["one"])), "two_s": float(np.median(t["two"])),
            "speedup": float(np.median(t["one"] / t["two"])),
            "reference_speedup": float(np.median(t["cpu1"] / t["cpu2"])),
            "draw_suite": DRAW_SUITE, "draw_tasks": draw_tasks, "draw_one_s": float(np.median(t["draw1"])),
            "draw_two_s": float(np.median(t["draw2"])), "draw_speedup": float(np.median(t["draw1"] / t["draw2"])),
            "resume_kept_s": float(np.median(t["resume_kept"])), "resume_drawn_s": float(np.median(t["resume_drawn"]))}


def markdown(r: dict) -> str:
    """The results as a BENCHMARKS.md section."""
    return "\n".join([
        f"### Bench: 2 processes against 1 (`simbench bench {r['suite']}`, {r['tasks']} tasks at seed {SEED} by "
        f"{', '.join(r['methods'])}: {r['runs']} runs; {r['repeats']} rounds in turn)",
        "",
        "| workers | seconds (median) | runs/s |",
        "|---|---|---|",
        f"| 1 (in this process) | {r['one_s']:.2f} | {r['runs'] / r['one_s']:.2f} |",
        f"| 2 (worker processes) | {r['two_s']:.2f} | {r['runs'] / r['two_s']:.2f} |",
        "",
        f"Speed-up (median of the rounds' ratios): **{r['speedup']:.2f}** (target: at least 1.6). Pure CPU work in "
        f"forked processes, the same rounds: {r['reference_speedup']:.2f}.",
        "",
        f"The draw of {r['draw_tasks']} tasks of `{r['draw_suite']}` (seed {SEED}), the same tasks by either: "
        f"{r['draw_one_s']:.2f} s by 1 process ({r['draw_one_s'] / r['draw_tasks']:.2f} s a task), "
        f"{r['draw_two_s']:.2f} s by 2 (medians); speed-up (median of the rounds' ratios) "
        f"{r['draw_speedup']:.2f}.",
        "",
        f"That bench by pinv alone ({r['draw_tasks']} runs, 2 workers), finished, run again in its folder (every run's "
        f"row on disk; its tables, plots and page written again): {r['resume_kept_s']:.2f} s taking the tasks the "
        f"folder keeps, {r['resume_drawn_s']:.2f} s drawing them again (medians).",
    ])


if __name__ == "__main__":
    result = measure()
    print(markdown(result))
