"""The soak: ten simulated minutes of RSMG tumbling (benchmarks/soak_rsmg.yaml), hundreds of re-grips.

Bounded means: the rotor's error, the closure error (how far a gripping EM has slid on the rotor since it
gripped: the weld's violation) and the mechanism's kinetic energy are no larger in the last minute than in the
first, and memory grows only with what is recorded. Measured:
  - each run in a fresh process (`simbench.run`, no video): wall time and peak resident memory, for the soak
    and for its first minute alone (the same motion, 60 s), so that the memory a recorded sample costs is
    (peak_600 - peak_60) / (samples_600 - samples_60); and the soak's resident size at its peak in each stage;
  - the soak at its recording stride (`sim.record_every` in the yaml) and recorded whole (stride 1): peak
    memory, the time to write the outputs (plots and timeseries), and whether the report's errors and events
    are the same;
  - per minute of the soak recorded whole: the largest rotor error and closure error, and the largest and mean
    kinetic energy (MuJoCo's, at every 10th recorded state, with velocities from consecutive recorded positions);
  - the same soak open loop (`regrip_feedback: false`, the paper's scheme without the grip feedback), per minute
    of its strided timeseries (maxima over every k-th sample).
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import mujoco
import numpy as np
import yaml

from benchmarks.common import CHILD_PEAK_BYTES

SOAK = Path(__file__).with_name("soak_rsmg.yaml")
MINUTE = 60.0
_STRIDE = 10  # recorded samples between kinetic energy evaluations
# What the report says of the run's errors and events: the same at any recording stride.
FOUND = ("status", "samples", "tracking", "singularity_events", "limit_events", "switch_events", "warnings",
         "rotor_error_max", "closure_error_max", "fewest_gripping", "gripping_gamma")

_CHILD = """
import json, os, sys, threading, time
import simbench
PAGE = os.sysconf("SC_PAGE_SIZE")
resident = []  # (s since the run's start, bytes), every 2 ms


def sample():
    while True:
        with open("/proc/self/statm") as f:
            resident.append((time.perf_counter() - start, int(f.read().split()[1]) * PAGE))
        time.sleep(0.002)


sc = simbench.load_scenario(sys.argv[1])
start = time.perf_counter()
threading.Thread(target=sample, daemon=True).start()
simbench.run(sc, out=sys.argv[2], video=False)
print(json.dumps({"wall": time.perf_counter() - start, "resident": resident, "peak_rss": PEAK}))
""".replace("PEAK", CHILD_PEAK_BYTES)
_STAGES = ("plan", "simulate", "analyse", "plots", "write")  # report.json's wall_time, in the order they run


def _variant(folder: Path, name: str, minutes: float | None = None, feedback: bool = True,
             every: int | None = None) -> Path:
    """The soak scenario, cut to `minutes` (the same rates), open loop, or at another recording stride, written
    into folder."""
    doc = yaml.safe_load(SOAK.read_text())
    if every is not None:
        doc["sim"] = {**doc.get("sim", {}), "record_every": every}
    if minutes is not None:
        scale = minutes * MINUTE / doc["timing"]["duration"]
        doc["timing"]["duration"] *= scale
        for key in ("spin_turns", "precession_turns"):
            doc["task"]["motion"][key] *= scale
    doc["task"]["regrip_feedback"] = feedback
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def _run(scenario: Path, out: Path) -> dict:
    """simbench.run in a fresh process: its wall time and peak memory, and the report it wrote."""
    done = subprocess.run([sys.executable, "-c", _CHILD, str(scenario), str(out)], capture_output=True, text=True,
                          check=True)
    result = json.loads(done.stdout.strip().splitlines()[-1])
    result["report"] = json.loads((out / "report.json").read_text())
    return result


def stage_peaks(resident: list, stages: dict) -> dict[str, float]:
    """The largest resident size (bytes) sampled during each stage of a run, the stages placed end to end from
    the run's start by report.json's wall times (the untimed work between them, checking the output folder say,
    is a few ms)."""
    t, rss = np.array(resident).T
    ends = np.cumsum([stages.get(name, 0.0) for name in ("load", *_STAGES)])
    return {name: float(rss[(t >= lo) & (t < hi)].max(initial=0.0))
            for name, lo, hi in zip(_STAGES, ends[:-1], ends[1:])}


def kinetic_energy(qpos: np.ndarray, dt: float) -> np.ndarray:
    """MuJoCo's kinetic energy of the RSMG at every _STRIDE-th recorded state (velocities from each state and
    the one before it, by mj_differentiatePos, since the recording keeps only the actuated joints' rates)."""
    from simbench.core.plant import Plant
    from simbench.robots import rsmg

    model = Plant.load(rsmg.ROBOT).model
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    data = mujoco.MjData(model)
    rows = np.arange(1, len(qpos), _STRIDE)
    energy = np.empty(rows.size)
    for i, k in enumerate(rows):
        mujoco.mj_differentiatePos(model, data.qvel, dt, qpos[k - 1], qpos[k])
        data.qpos[:] = qpos[k]
        mujoco.mj_forward(model, data)
        energy[i] = data.energy[1]
    return energy


def _per_minute(t: np.ndarray, values: np.ndarray, reduce=np.max) -> list[float]:
    """reduce(values) over each whole minute of t."""
    return [float(reduce(values[(t >= m * MINUTE) & (t < (m + 1) * MINUTE)])) for m in range(int(t[-1] // MINUTE))]


def measure() -> dict:
    """The soak at its stride and whole, its first minute alone and its open-loop twin; per-minute maxima and
    memory."""
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        soak = _run(SOAK, tmp / "soak")
        whole = _run(_variant(tmp, "whole", every=1), tmp / "whole")
        short = _run(_variant(tmp, "first_minute", minutes=1.0), tmp / "short")
        open_loop = _run(_variant(tmp, "open_loop", feedback=False), tmp / "open")
        with np.load(tmp / "whole" / "timeseries.npz") as ts:
            t, qpos = ts["t"], ts["qpos"]
            rotor, closure = ts["rotor_error"], ts["closure_error"]
            energy = kinetic_energy(qpos, float(t[1] - t[0]))
        with np.load(tmp / "open" / "timeseries.npz") as ts:
            open_rotor = _per_minute(ts["t"], ts["rotor_error"])
            open_closure = _per_minute(ts["t"], ts["closure_error"])
    report = soak["report"]
    return {
        "status": report["status"], "samples": report["samples"], "duration": report["duration"],
        "record_every": report["record_every"],
        "switches": 2 * len(report["switch_events"]), "grips": len(report["switch_events"]),
        "singularity_events": len(report["singularity_events"]), "warnings": len(report["warnings"]),
        "wall": soak["wall"], "stages": report["wall_time"], "whole_wall": whole["wall"],
        "whole_stages": whole["report"]["wall_time"], "peak_rss_whole": whole["peak_rss"],
        "differ": [key for key in FOUND if report.get(key) != whole["report"].get(key)],
        "peak_rss": soak["peak_rss"], "peak_rss_short": short["peak_rss"], "samples_short": short["report"]["samples"],
        "stage_peaks": stage_peaks(soak["resident"], report["wall_time"]),
        "rotor": _per_minute(t, rotor), "closure": _per_minute(t, closure),
        "energy": _per_minute(t[1::_STRIDE], energy), "energy_mean": _per_minute(t[1::_STRIDE], energy, np.mean),
        "open_rotor": open_rotor, "open_closure": open_closure, "open_status": open_loop["report"]["status"],
    }


def _outputs(stages: dict) -> float:
    """Seconds spent writing the outputs: the plots and the timeseries."""
    return stages["plots"] + stages["write"]


def markdown(r: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    per_sample = (r["peak_rss"] - r["peak_rss_short"]) / (r["samples"] - r["samples_short"])
    rows = [f"| {m + 1} | {np.rad2deg(a):.3f} | {1e6 * c:.0f} | {1e3 * e:.1f} | {1e3 * em:.2f} | "
            f"{np.rad2deg(oa):.2f} | {1e6 * oc:.0f} |"
            for m, (a, c, e, em, oa, oc) in enumerate(zip(r["rotor"], r["closure"], r["energy"], r["energy_mean"],
                                                          r["open_rotor"], r["open_closure"]))]
    return "\n".join([
        f"### Soak: {r['duration'] / MINUTE:.0f} simulated minutes of RSMG tumbling (`benchmarks/soak_rsmg.yaml`)",
        "",
        f"Status {r['status']}: {r['grips']} re-grips ({r['switches']} weld switches), {r['samples']} samples, "
        f"{r['singularity_events']} singularity events, {r['warnings']} MuJoCo warnings. Wall time "
        f"{r['wall']:.1f} s in all (simulate {r['stages']['simulate']:.1f} s, analyse {r['stages']['analyse']:.1f} "
        f"s, plots {r['stages']['plots']:.1f} s, write {r['stages']['write']:.1f} s).",
        "",
        "Each minute's largest value (and the kinetic energy's mean), with the grip feedback (the default; recorded "
        "whole) and open loop (`regrip_feedback: false`; over the stride's samples). The kinetic energy's peaks are "
        "the swings (a base joint at up to 12 rad/s):",
        "",
        "| minute | rotor error (deg) | closure error (um) | kinetic energy, max (mJ) | mean (mJ) | "
        "open loop: rotor error (deg) | open loop: closure error (um) |",
        "|---|---|---|---|---|---|---|",
        *rows,
        "",
        f"Recording stride {r['record_every']} (`sim.record_every`) against the soak recorded whole, one run "
        f"each in a fresh process: peak resident {r['peak_rss'] / 2**20:.0f} MiB against "
        f"{r['peak_rss_whole'] / 2**20:.0f} MiB; outputs written (plots, timeseries) in "
        f"{_outputs(r['stages']):.1f} s (plots {r['stages']['plots']:.1f} s, timeseries {r['stages']['write']:.1f} "
        f"s) against {_outputs(r['whole_stages']):.1f} s; wall {r['wall']:.1f} s against {r['whole_wall']:.1f} s "
        f"(plan {r['stages']['plan']:.1f} and {r['whole_stages']['plan']:.1f} s, simulate "
        f"{r['stages']['simulate']:.1f} and {r['whole_stages']['simulate']:.1f} s). The report's errors and events "
        + ("are the same (" + ", ".join(FOUND) + ")." if not r["differ"] else
           "differ in " + ", ".join(r["differ"]) + "."),
        "",
        f"Memory: peak resident {r['peak_rss'] / 2**20:.0f} MiB for the soak, {r['peak_rss_short'] / 2**20:.0f} "
        f"MiB for its first minute alone (both at stride {r['record_every']}): memory grows with the run, "
        f"{per_sample:.0f} bytes a sample (the plan, the columns the analysis reads at every sample, the analysis "
        "series). The soak's resident size at its peak in each stage (sampled every 2 ms, MiB): "
        + ", ".join(f"{name} {peak / 2**20:.0f}" for name, peak in r["stage_peaks"].items()) + ".",
    ])


if __name__ == "__main__":
    print(markdown(measure()))
