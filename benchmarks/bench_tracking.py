"""Steps per second of simbench's tracking loop against raw MuJoCo stepping, on the same model in the same run.

The tracking loop is `simbench.sim.simulate`: controls from the plan, stepping, and recording of state and
tool position at every step. It is compared, pair by pair in alternation, with
  - a plain Python loop of mujoco.mj_step (how a script steps a model), and
  - mujoco.rollout with no recording (stepping in C: the ceiling).
Target (issue 2): at least 0.85 of raw stepping.
"""

from __future__ import annotations

import mujoco
import numpy as np
from mujoco import rollout

import simbench
from benchmarks.common import interleaved
from simbench.resources import scenarios_dir
from simbench.sim import Plant, simulate

REPEATS = 15


def measure(robot_name: str = "spherical_arm", scenario: str = "demo") -> dict:
    """Median steps/s of each loop and the median pairwise ratios."""
    sc = simbench.load_scenario(scenarios_dir() / robot_name / f"{scenario}.yaml")
    plant = Plant.load(sc.robot_def)
    model = plant.model
    traj = sc.planner_def.plan(sc, sc.robot_def, float(model.opt.timestep))
    steps = traj.t.size - 1
    data = mujoco.MjData(model)
    state0 = np.empty(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(model, data, state0, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    ctrl = np.zeros((1, steps, model.nu))

    def tracking():
        simulate(plant, traj, settle=0.0)

    def python_loop():
        d = mujoco.MjData(model)
        d.ctrl[:] = traj.q_ref[0]
        for _ in range(steps):
            mujoco.mj_step(model, d)

    def c_loop():
        rollout.rollout(model, data, state0[None], ctrl, nstep=steps)

    t_track, t_py = interleaved(tracking, python_loop, REPEATS)
    t_track2, t_c = interleaved(tracking, c_loop, REPEATS)
    return {
        "model": robot_name, "steps": steps,
        "tracking_steps_per_s": steps / np.median(np.concatenate([t_track, t_track2])),
        "python_mj_step_per_s": steps / np.median(t_py),
        "c_rollout_steps_per_s": steps / np.median(t_c),
        "ratio_vs_python_loop": float(np.median(t_py / t_track)),
        "ratio_vs_c_rollout": float(np.median(t_c / t_track2)),
    }


def markdown(r: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    return "\n".join([
        f"### Tracking loop against raw stepping ({r['model']}, {r['steps']} steps, {REPEATS} interleaved pairs)",
        "",
        "| loop | steps/s (median) | tracking loop's speed / this loop's (median of pairwise ratios) |",
        "|---|---|---|",
        f"| simbench tracking loop (`sim.simulate`: controls, steps, records state and tool) "
        f"| {r['tracking_steps_per_s']:,.0f} | 1 |",
        f"| Python loop of `mujoco.mj_step` | {r['python_mj_step_per_s']:,.0f} | {r['ratio_vs_python_loop']:.2f} |",
        f"| `mujoco.rollout`, no recording (C) | {r['c_rollout_steps_per_s']:,.0f} | {r['ratio_vs_c_rollout']:.2f} |",
        "",
        "Target: at least 0.85 of raw stepping.",
    ])


if __name__ == "__main__":
    print(markdown(measure()))
