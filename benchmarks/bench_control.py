"""Closed-loop control steps per second: simbench's closed loop against a bare Python loop calling the same
controller, and the dm_control environment's step rate, on the same model in the same run.

- `simulate` with computed_torque (`control: {controller: computed_torque}`, a closed-loop controller: asked for
  every step's command from the measured state, simbench.physics.stepping.ClosedLoop: mj_step1, the command, mj_step2,
  every step checked and recorded), against a bare Python loop of `mujoco.mj_step` that asks the same
  controller for each command (a State of the data, `commands`, `data.ctrl`, `mj_step`: no checks, no
  recording). Both bind the controller first (computed torque's inverse dynamics of the plan) and start from
  the plan's start without settling; the loop ratio leaves each call's binding out. Target (issue 13): at
  least 0.5 of the bare loop.
- `simbench.env`: steps/s of `env.step` with the servo's commands as actions (precomputed: the environment's
  own cost, not a policy's), an episode from reset (no settling) to its end, against a bare Python loop of
  `mujoco.mj_step` with the same commands.
Pairs are timed in alternation (benchmarks.common.interleaved); ratios are medians of the pairwise ratios.
"""

from __future__ import annotations

import time
from typing import cast

import mujoco
import numpy as np
import yaml

from benchmarks.common import interleaved
from simbench import env as simbench_env
from simbench.api import JointTrajectory, State
from simbench.core.plant import Plant
from simbench.core.resources import scenarios_dir
from simbench.physics.computed_torque import ComputedTorque, ComputedTorqueSettings
from simbench.physics.controllers import Servo
from simbench.physics.sim import simulate
from simbench.physics.switches import at_start
from simbench.scenario import parse_scenario

REPEATS = 7
CASES = (("spherical_arm", "case1"), ("puma600", "weld_seam"))


class _TimedBind(ComputedTorque):
    """computed_torque that keeps how long each bind() took (part of both loops' time: the loop ratio leaves
    it out)."""

    def __init__(self, settings: ComputedTorqueSettings, times: list[float]):
        super().__init__(settings)
        self.times = times

    def bind(self, plant: Plant, trajectory: JointTrajectory) -> None:
        start = time.perf_counter()
        super().bind(plant, trajectory)
        self.times.append(time.perf_counter() - start)


def scenario(robot: str, name: str, control: dict | None = None, settle: float | None = None):
    """A shipped scenario with another `control:` section or settling time."""
    path = scenarios_dir() / robot / f"{name}.yaml"
    raw = yaml.safe_load(path.read_text())
    if control is not None:
        raw["control"] = control
    if settle is not None:
        raw.setdefault("sim", {})["settle"] = settle
    return parse_scenario(raw, str(path), default_name=name)


def measure_closed_loop(robot: str, name: str) -> dict:
    """simulate with computed_torque against a bare mj_step loop asking the same controller."""
    sc = scenario(robot, name, control={"controller": "computed_torque"})
    sim = sc.sim
    plant = Plant.load(sc.robot_def, sim.timestep, sim.kp, sim.kv, sim.force_limits, sim.gravity_compensation,
                       "torque")
    traj = sc.planner_def.plan(sc, sc.robot_def, float(plant.model.opt.timestep))
    steps, dt = traj.t.size - 1, float(plant.model.opt.timestep)
    qpos_adr, dof_adr = plant.qpos_adr, plant.dof_adr

    binds: dict[str, list[float]] = {"simulate": [], "bare": []}  # each call's binding time, warm-up first

    def controller(loop: str) -> ComputedTorque:
        """The scenario's computed_torque, its bind() timed into binds[loop]."""
        return _TimedBind(cast(ComputedTorqueSettings, sc.control), binds[loop])

    def closed_loop():
        simulate(plant, traj, controller("simulate"), settle=0.0)

    def bare_loop():
        ct = controller("bare")
        ct.bind(plant, traj)
        model, data, _ = at_start(plant, traj)
        mujoco.mj_forward(model, data)
        for k in range(steps):
            state = State(k=k, t=k * dt, q=data.qpos[qpos_adr], qd=data.qvel[dof_adr], qpos=data.qpos,
                          qvel=data.qvel, data=data)
            data.ctrl[:] = ct.commands(state)
            mujoco.mj_step(model, data)

    t_sim, t_bare = interleaved(closed_loop, bare_loop, REPEATS)
    b_sim, b_bare = np.array(binds["simulate"][1:]), np.array(binds["bare"][1:])
    return {"case": f"{robot}/{name}", "steps": steps, "simulate_steps_per_s": steps / np.median(t_sim),
            "bare_steps_per_s": steps / np.median(t_bare), "ratio": float(np.median(t_bare / t_sim)),
            "bind_s": float(np.median(np.concatenate([b_sim, b_bare]))),
            "loop_ratio": float(np.median((t_bare - b_bare) / (t_sim - b_sim)))}


def measure_environment(robot: str, name: str) -> dict:
    """env.step with the servo's commands against a bare mj_step loop with the same commands."""
    sc = scenario(robot, name, settle=0.0)
    env = simbench_env.load(sc)
    task = env.task
    servo = Servo.from_scenario(sc)
    servo.bind(task.plant, task.plan)
    ctrl = servo.open_loop()
    assert ctrl is not None, "the servo's commands follow from the plan"
    actions = ctrl[:, task.plant.actuators]
    steps = task.n - 1

    def environment():
        env.reset()
        for k in range(steps):
            env.step(actions[k])

    def bare_loop():
        model, data, _ = at_start(task.plant, task.plan)
        mujoco.mj_forward(model, data)
        for k in range(steps):
            data.ctrl[:] = ctrl[k]
            mujoco.mj_step(model, data)

    t_env, t_bare = interleaved(environment, bare_loop, REPEATS)
    return {"case": f"{robot}/{name}", "steps": steps, "env_steps_per_s": steps / np.median(t_env),
            "bare_steps_per_s": steps / np.median(t_bare), "ratio": float(np.median(t_bare / t_env))}


def measure() -> dict:
    """Every case, both measurements."""
    closed = [measure_closed_loop(*case) for case in CASES]
    environment = [measure_environment(*case) for case in CASES]
    return {"closed_loop": closed, "environment": environment}


def markdown(results: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    closed = [f"| `{r['case']}` ({r['steps']:,} steps) | {r['simulate_steps_per_s']:,.0f} | "
              f"{r['bare_steps_per_s']:,.0f} | {r['ratio']:.2f} | {1e3 * r['bind_s']:.0f} | "
              f"{r['loop_ratio']:.2f} |" for r in results["closed_loop"]]
    envs = [f"| `{r['case']}` ({r['steps']:,} steps) | {r['env_steps_per_s']:,.0f} | {r['bare_steps_per_s']:,.0f} "
            f"| {r['ratio']:.2f} |" for r in results["environment"]]
    return "\n".join([
        f"### Closed-loop control and the dm_control environment ({REPEATS} interleaved pairs)",
        "",
        ("`simulate` with computed_torque (closed loop: the controller asked every step, each step checked and "
         "recorded) against a bare Python `mujoco.mj_step` loop asking the same controller (both bind it first: "
         "computed torque's inverse dynamics of the whole plan):"),
        "",
        ("| scenario | simulate, steps/s (median) | bare loop, steps/s | simulate's speed / the bare loop's | "
         "binding the controller (ms, median) | the same ratio, each call's binding left out |"),
        "|---|---|---|---|---|---|",
        *closed,
        "",
        "Target: at least 0.5 of the bare loop.",
        "",
        ("`simbench.env`: `env.step` with the servo's commands as actions (precomputed), reset to the episode's "
         "end, against a bare Python `mujoco.mj_step` loop with the same commands:"),
        "",
        "| scenario | env.step, steps/s (median) | bare loop, steps/s | env's speed / the bare loop's |",
        "|---|---|---|---|",
        *envs,
    ])


if __name__ == "__main__":
    print(markdown(measure()))
