"""Steps per second of simbench's tracking loop against raw MuJoCo stepping, on the same model in the same run.

The tracking loop is `simbench.physics.sim.simulate`: controls from the plan (simbench.physics.controllers.Servo),
stepping, and recording of state and
tool position at every step, with no Python in the loop between switches (`mujoco.rollout` over precomputed
controls, one call per stretch between electromagnet switches). It is compared, pair by pair in alternation,
with
  - a plain Python loop of mujoco.mj_step (how a script steps a model), and
  - mujoco.rollout with no recording (stepping in C: the ceiling),
on a serial arm and on the RSMG, whose run is cut into stretches by its weld switches.
Target (issues 2 and 6): at least 0.9 of raw stepping.
"""

from __future__ import annotations

import mujoco
import numpy as np
from mujoco import rollout

from benchmarks.common import interleaved, shipped
from simbench.core.plant import Plant
from simbench.physics.controllers import Servo
from simbench.physics.sim import simulate
from simbench.physics.switches import apply_switch, at_start

REPEATS = 15
CASES = (("spherical_arm", "demo"), ("rsmg", "three_turns"))


def _start(plant: Plant, traj) -> tuple[mujoco.MjModel, mujoco.MjData, dict[int, list]]:
    """A model and data at the plan's start, as `simulate` sets them (`sim.at_start`), and the later switches
    by step: the baselines do the same physics as the tracking loop, only without recording."""
    model, data, steps = at_start(plant, traj)
    mujoco.mj_forward(model, data)
    by_step: dict[int, list] = {}
    for switch, k in zip(traj.switches, steps):
        if k > 0:
            by_step.setdefault(int(k), []).append(switch)
    return model, data, by_step


def measure_case(robot_name: str, scenario: str) -> dict:
    """Median steps/s of each loop and the median pairwise ratios."""
    sc = shipped(f"{robot_name}/{scenario}")
    plant = Plant.load(sc.robot_def, sc.sim.timestep)
    traj = sc.planner_def.plan(sc, sc.robot_def, float(plant.model.opt.timestep))
    steps = traj.t.size - 1
    servo = Servo()
    servo.bind(plant, traj)
    ctrl = servo.open_loop()[:-1]
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS

    def tracking():
        simulate(plant, traj, settle=0.0)

    def python_loop():
        model, data, by_step = _start(plant, traj)
        for k in range(steps):
            for switch in by_step.get(k, ()):
                apply_switch(model, data, switch)
            data.ctrl[:] = ctrl[k]
            mujoco.mj_step(model, data)

    def c_loop():
        model, data, by_step = _start(plant, traj)
        state = np.empty(mujoco.mj_stateSize(model, spec))
        done = 0
        for stop in sorted(k for k in by_step if k < steps) + [steps]:
            mujoco.mj_getState(model, data, state, spec)
            rollout.rollout(model, data, state[None], ctrl[None, done:stop],
                            control_spec=mujoco.mjtState.mjSTATE_CTRL)  # leaves data at the chunk's last state
            for switch in by_step.get(stop, ()):
                apply_switch(model, data, switch)
            done = stop

    t_track, t_py = interleaved(tracking, python_loop, REPEATS)
    t_track2, t_c = interleaved(tracking, c_loop, REPEATS)
    return {
        "case": f"{robot_name}/{scenario}", "steps": steps, "switches": len(traj.switches),
        "tracking_steps_per_s": steps / np.median(np.concatenate([t_track, t_track2])),
        "python_mj_step_per_s": steps / np.median(t_py),
        "c_rollout_steps_per_s": steps / np.median(t_c),
        "ratio_vs_python_loop": float(np.median(t_py / t_track)),
        "ratio_vs_c_rollout": float(np.median(t_c / t_track2)),
    }


def measure() -> list[dict]:
    """Every case."""
    return [measure_case(*case) for case in CASES]


def markdown(results: list[dict]) -> str:
    """The result as a BENCHMARKS.md section."""
    rows = []
    for r in results:
        rows += [f"| `{r['case']}` ({r['steps']:,} steps, {r['switches']} switches) | simbench tracking loop "
                 f"(`sim.simulate`: controls, steps, records state and sensors) | {r['tracking_steps_per_s']:,.0f} "
                 "| 1 |",
                 f"| | Python loop of `mujoco.mj_step` | {r['python_mj_step_per_s']:,.0f} | "
                 f"{r['ratio_vs_python_loop']:.2f} |",
                 f"| | `mujoco.rollout`, no recording (C) | {r['c_rollout_steps_per_s']:,.0f} | "
                 f"{r['ratio_vs_c_rollout']:.2f} |"]
    return "\n".join([
        f"### Tracking loop against raw stepping ({REPEATS} interleaved pairs)",
        "",
        "| scenario | loop | steps/s (median) | tracking loop's speed / this loop's (median of pairwise ratios) |",
        "|---|---|---|---|",
        *rows,
        "",
        "Target: at least 0.9 of raw stepping.",
    ])


if __name__ == "__main__":
    print(markdown(measure()))
