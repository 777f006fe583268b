"""The dm_control environment's overhead a step: `simbench.env`'s `env.step` beside dm_control's own reacher
(`suite.load('reacher', 'easy')`), each against raw `mujoco.mj_step` on the same model for the same substeps.

For each environment: episodes (as many as make MIN_STEPS control steps) from reset to their end with precomputed
actions (recorded from one episode first: the reference as the target for simbench's tasks, uniform random
actions within the spec for the reacher), so a policy's cost is not counted; and the raw loop: a copy of the reset
state, each recorded step's `data.ctrl` set and `mj_step` called as many times as the environment's control
timestep holds physics steps. The overhead a step is (environment's time - raw loop's time) / steps: what
dm_control's Environment and the task add (observation, reward, termination, simbench's split step and switches).
Every environment and its raw loop are timed in turn, environments round-robin, repeat after repeat (one warm-up
round first); figures are medians over the repeats.
The RSMG's raw loop runs without the planned weld switches (as loaded), so its physics is not quite the
episode's.
"""

from __future__ import annotations

import copy
import time

import mujoco
import numpy as np
from dm_control import suite
from dm_control.rl import control

from simbench import env as simbench_env

REPEATS = 11
MIN_STEPS = 4000  # control steps timed at least, in one or more episodes
CASES = ("dm_control reacher/easy", "spherical_arm/case1", "puma600/weld_seam", "agile_eye/avoidance",
         "rsmg/three_turns")


def environment(case: str) -> control.Environment:
    """The environment a case names."""
    if case.startswith("dm_control "):
        domain, task = case.split(" ", 1)[1].split("/")
        return suite.load(domain, task, task_kwargs={"random": 0})
    robot, name = case.split("/")
    return simbench_env.load_task(robot, name)


def recorded(case: str, env: control.Environment) -> tuple[np.ndarray, np.ndarray]:
    """One episode's actions and the `data.ctrl` each step left, from reset to the end."""
    spec, rng = env.action_spec(), np.random.default_rng(0)
    step, actions, ctrls = env.reset(), [], []
    while not step.last():
        if case.startswith("dm_control "):
            action = rng.uniform(spec.minimum, spec.maximum)
        else:
            action = np.clip(step.observation["q_ref"], spec.minimum, spec.maximum)
        step = env.step(action)
        actions.append(action)
        ctrls.append(env.physics.data.ctrl.copy())
    return np.array(actions), np.array(ctrls)


def timers(case: str):
    """(the environment's episodes, the raw loops, steps, substeps a step): the two as functions to time, each
    repeating its episode as often as it takes to reach MIN_STEPS (the reacher's episodes are short)."""
    env = environment(case)
    actions, ctrls = recorded(case, env)
    substeps = int(round(env.control_timestep() / env.physics.timestep()))
    env.reset()
    model = env.physics.model.ptr
    start = copy.copy(env.physics.data.ptr)
    episodes = -(-MIN_STEPS // len(actions))

    def episode():
        for _ in range(episodes):
            env.reset()
            for action in actions:
                env.step(action)

    def raw():
        for _ in range(episodes):
            data = copy.copy(start)
            for ctrl in ctrls:
                data.ctrl[:] = ctrl
                for _ in range(substeps):
                    mujoco.mj_step(model, data)

    return episode, raw, episodes * len(actions), substeps


def measure() -> dict:
    """Every case's environment and raw loop, timed in turn."""
    cases = {case: timers(case) for case in CASES}
    times: dict[str, dict[str, list[float]]] = {case: {"env": [], "raw": []} for case in CASES}
    for repeat in range(REPEATS + 1):
        for case, (episode, raw, _, _) in cases.items():
            for key, fn in (("env", episode), ("raw", raw)):
                start = time.perf_counter()
                fn()
                if repeat:  # the first round warms up
                    times[case][key].append(time.perf_counter() - start)
    rows = []
    for case, (_, _, steps, substeps) in cases.items():
        t_env, t_raw = np.array(times[case]["env"]), np.array(times[case]["raw"])
        rows.append({"case": case, "steps": steps, "substeps": substeps,
                     "env_us": 1e6 * float(np.median(t_env)) / steps, "raw_us": 1e6 * float(np.median(t_raw)) / steps,
                     "overhead_us": 1e6 * float(np.median(t_env - t_raw)) / steps,
                     "overhead_spread_us": 1e6 * float(np.percentile(t_env - t_raw, 75)
                                                      - np.percentile(t_env - t_raw, 25)) / steps})
    return {"rows": rows}


def markdown(results: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    rows = [f"| {r['case'] if r['case'].startswith('dm_control') else '`' + r['case'] + '`'} | {r['steps']:,} | "
            f"{r['substeps']} | {r['env_us']:.1f} | {r['raw_us']:.1f} | {r['overhead_us']:.1f} "
            f"({r['overhead_spread_us']:.1f}) |" for r in results["rows"]]
    return "\n".join([
        f"### The environment's overhead a step, beside dm_control's reacher ({REPEATS} interleaved rounds)",
        "",
        ("`env.step` over an episode with precomputed actions against raw `mujoco.mj_step` on the same model for "
         "the same physics steps (the control timestep's substeps), each environment and its raw loop in turn, "
         "the environments round-robin; medians over the rounds, microseconds a control step:"),
        "",
        "| environment | steps timed | physics steps a step | env.step (us) | raw mj_step (us) | overhead (us; IQR) |",
        "|---|---|---|---|---|---|",
        *rows,
    ])


if __name__ == "__main__":
    print(markdown(measure()))
