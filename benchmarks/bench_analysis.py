"""The analysis against the simulation on every shipped scenario.

Per scenario, planned once, then in alternation: the simulation as `simbench.evaluate`'s `simulate` stage makes it
(`sim.simulate` with the scenario's controller, then `sim.commanded`) and the analysis as its `analyse` stage makes
it (`analysis.analyse` and `verdict.run_verdict` on that recording); the ratio is the median of the pairwise
ratios, so that a busy machine slows both alike. BEFORE holds the same figures for the code of commit 0ca0635,
measured by this module on a copy of that revision's src/.
"""

from __future__ import annotations

import numpy as np

from benchmarks.common import interleaved, shipped
from simbench.analysis import analyse
from simbench.analysis.verdict import run_verdict
from simbench.core.plant import Plant
from simbench.core.resources import scenarios_dir
from simbench.physics.sim import commanded, simulate
from simbench.robots import Tolerance

REPEATS = 15  # pairs a scenario: with 5, one loaded run swung the ratio by +-0.05
# Commit 0ca0635 (BENCHMARKS.md says when and where): scenario -> (simulate ms, analyse ms, median ratio).
BEFORE = {
    "agile_eye/avoidance": (99.3, 329.6, 3.31),
    "agile_eye/through_singularity": (81.2, 2964.9, 41.34),
    "puma600/circle": (27.5, 60.6, 2.25),
    "puma600/line": (31.8, 65.7, 2.03),
    "puma600/weld_seam": (35.3, 73.5, 2.34),
    "puma600/wrist_singularity": (21.7, 49.0, 2.26),
    "rsmg/three_turns": (450.8, 279.9, 0.60),
    "rsmg/tumble": (321.6, 204.6, 0.61),
    "spherical_arm/case1": (27.7, 66.4, 2.50),
    "spherical_arm/case1_joint_move": (25.0, 63.4, 2.59),
    "spherical_arm/case2": (26.7, 70.2, 2.59),
    "spherical_arm/case2_forward_twin": (25.1, 62.0, 2.49),
    "spherical_arm/case3": (25.1, 65.9, 2.60),
    "spherical_arm/case4": (40.8, 92.5, 2.48),
    "spherical_arm/demo": (35.6, 96.4, 2.77),
}


def measure_scenario(name: str) -> dict:
    """Median simulate and analyse times of one shipped scenario and the median of their pairwise ratios."""
    sc = shipped(name)
    robot, sim, a = sc.robot_def, sc.sim, sc.analysis
    plant = Plant.load(robot, sim.timestep, sim.kp, sim.kv, sim.force_limits, sim.gravity_compensation,
                       sc.controller_def.from_scenario(sc).actuation)
    planned = sc.planner_def.plan(sc, robot, float(plant.model.opt.timestep))
    near, margin = Tolerance(a.near_angle, a.near_length), Tolerance(a.limit_angle, a.limit_length)
    done = {}

    def simulate_stage():
        rec = simulate(plant, planned, sc.controller_def.from_scenario(sc), settle=sim.settle)
        done["run"] = commanded(planned, rec), rec

    def analyse_stage():
        traj, rec = done["run"]
        run_verdict(robot, traj, analyse(robot, traj, rec, near=near, margin=margin), a, sc.expect)

    simulate_stage()
    t_sim, t_ana = interleaved(simulate_stage, analyse_stage, REPEATS)
    return {"scenario": name, "samples": int(planned.t.size), "simulate": float(np.median(t_sim)),
            "analyse": float(np.median(t_ana)), "ratio": float(np.median(t_ana / t_sim))}


def measure() -> dict:
    """Every shipped scenario."""
    names = [str(p.relative_to(scenarios_dir()).with_suffix("")) for p in sorted(scenarios_dir().glob("*/*.yaml"))]
    return {"scenarios": [measure_scenario(name) for name in names]}


def markdown(result: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    rows = []
    for r in result["scenarios"]:
        before = BEFORE.get(r["scenario"])
        was = f"{before[1]:.1f} / {before[0]:.1f} = {before[2]:.2f}" if before else "-"
        rows.append(f"| `{r['scenario']}` | {r['samples']:,} | {1e3 * r['simulate']:.1f} | {1e3 * r['analyse']:.1f} | "
                    f"{r['ratio']:.2f} | {was} |")
    worst = max(result["scenarios"], key=lambda r: r["ratio"])
    return "\n".join([
        f"### Analysis against simulation ({REPEATS} interleaved pairs a scenario)",
        "",
        "`python -m benchmarks.bench_analysis`. Before: commit 0ca0635 measured by this module (on a copy of its "
        "src/), on the same machine the same day.",
        "",
        "| scenario | samples | simulate ms (median) | analyse ms (median) | analyse / simulate (median of pairs) | "
        "before: analyse / simulate ms = ratio |",
        "|---|---|---|---|---|---|",
        *rows,
        "",
        f"The largest ratio is {worst['ratio']:.2f} (`{worst['scenario']}`).",
    ])


if __name__ == "__main__":
    print(markdown(measure()))
