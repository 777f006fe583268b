"""A sweep on 2 worker processes against the same sweep in 1 process, in one run.

The sweep is 100 variants of paper 000's case 1 with random durations (outputs: none, so each run's work is
planning, simulation and analysis), timed whole through `simbench.commands.sweep.run_sweep`: the table, summary and
plots included. Target (issue 6): at least 1.8.

Two figures say what limits the ratio, both measured in the same run:
- the sweep's serial part: writing the table, summary and plots after the last run, timed as the rerun of a
  finished sweep (nothing left to run); by Amdahl's law it caps the speed-up on two free cores;
- the same two-against-one speed-up for a reference workload, pure CPU work (a Python loop, nothing shared, in
  forked processes): this virtual machine's two cores do not make two of one, and how far they fall short
  changes from minute to minute.
The timings are taken in turn, REPEATS times, and each figure is the median.

Efficiency (issue 14): control steps simulated per second by the same sweep on 2 worker processes (timed whole,
as above) against two cores of raw `mujoco.rollout` on the same model: two forked processes, each stepping half
of the sweep's runs (their plans' commands, settling included, one `rollout` call per run, from the plan's first
pose) for the same total number of steps. Both are timed in turn, EFFICIENCY_REPEATS times; the figure is the
median of the pairwise ratios. Target: at least 0.5.
"""

from __future__ import annotations

import multiprocessing
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np
import yaml
from mujoco import rollout

from benchmarks.common import interleaved
from simbench.commands import pipeline
from simbench.commands.sweep import load_sweep, run_sweep
from simbench.core.plant import Plant
from simbench.scenario import parse_scenario

REPEATS = 7
EFFICIENCY_REPEATS = 5
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
    """Both measurements: the speed-up (measure_speedup) and the efficiency (measure_efficiency)."""
    return {**measure_speedup(), "efficiency": measure_efficiency()}


def measure_speedup() -> dict:
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
    """The results as BENCHMARKS.md sections."""
    return speedup_markdown(r) + "\n\n" + efficiency_markdown(r["efficiency"])


def speedup_markdown(r: dict) -> str:
    """The speed-up as a BENCHMARKS.md section."""
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


def _raw_run(scenario) -> tuple[mujoco.MjModel, np.ndarray, np.ndarray]:
    """One run as raw rollout input: the plant's model, its state at the plan's first pose, and every step's
    command as simbench steps it (the first command held while settling, then the plan's)."""
    ev = pipeline.evaluate(scenario)
    sim = scenario.sim
    plant = Plant.load(scenario.robot_def, sim.timestep, sim.kp, sim.kv, sim.force_limits, sim.gravity_compensation)
    data = mujoco.MjData(plant.model)
    data.qpos[:] = plant.initial_qpos(ev.trajectory.q_ref[0])
    full = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(plant.model, full))
    mujoco.mj_getState(plant.model, data, state, full)
    ctrl = ev.recording.ctrl
    n_settle = int(round(sim.settle / plant.model.opt.timestep))
    return plant.model, state, np.concatenate([np.repeat(ctrl[:1], n_settle, axis=0), ctrl[:-1]])


_RAW: list = []  # the runs' rollout inputs, inherited by the forked raw processes


def _roll(share: int) -> None:
    """Every other run of _RAW from `share`, each in one rollout call."""
    for model, state, ctrl in _RAW[share::2]:
        rollout.rollout(model, mujoco.MjData(model), state[None], ctrl[None],
                        control_spec=int(mujoco.mjtState.mjSTATE_CTRL))


def _raw_two_cores() -> None:
    """Every run of _RAW, half in each of two forked processes."""
    ctx = multiprocessing.get_context("fork")
    procs = [ctx.Process(target=_roll, args=(share,)) for share in (0, 1)]
    for p in procs:
        p.start()
    for p in procs:
        p.join()


def measure_efficiency() -> dict:
    """Median steps per second of the sweep on 2 workers and of raw rollout on two cores (the same steps), and
    the median pairwise ratio of the two."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.yaml"
        path.write_text(yaml.safe_dump(SPEC))
        sweep = load_sweep(path)
        _RAW[:] = [_raw_run(parse_scenario(v.document, v.id)) for v in sweep.variants]
        steps = sum(len(ctrl) for _, _, ctrl in _RAW)
        count = iter(range(1_000_000))
        t_sweep, t_raw = interleaved(lambda: run_sweep(sweep, Path(tmp) / f"out{next(count)}", workers=2),
                                     _raw_two_cores, EFFICIENCY_REPEATS)
    return {"runs": RUNS, "steps": steps, "sweep_steps_s": float(steps / np.median(t_sweep)),
            "raw_steps_s": float(steps / np.median(t_raw)), "ratio": float(np.median(t_raw / t_sweep))}


def efficiency_markdown(r: dict) -> str:
    """The efficiency result as a BENCHMARKS.md section."""
    return "\n".join([
        f"### Sweep efficiency: 2 workers against two cores of raw `mujoco.rollout` ({r['runs']} runs of "
        f"`spherical_arm/case1`, {r['steps']} control steps, {EFFICIENCY_REPEATS} rounds in turn)",
        "",
        "| | steps/s (median) |",
        "|---|---|",
        f"| sweep, 2 worker processes (`run_sweep`, outputs: none, table and plots included) | "
        f"{r['sweep_steps_s']:,.0f} |",
        f"| raw `mujoco.rollout`, 2 forked processes, the same steps | {r['raw_steps_s']:,.0f} |",
        "",
        f"Efficiency (median of pairwise ratios): {r['ratio']:.2f}. Target: at least 0.5.",
    ])


if __name__ == "__main__":
    print(markdown(measure()))
