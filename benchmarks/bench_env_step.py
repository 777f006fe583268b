"""What an RL-mode environment step costs (simbench.env.rl_mode: 20 ms control steps, residual actions), beside bare
MuJoCo and dm_control's reacher (`suite.load('reacher', 'easy')`, also 20 ms a control step), in one run:

- a physics step: an episode's `env.step` time over its physics steps, with the control step's substeps in
  MuJoCo's C loop (`simbench.env.substeps`, the default) and in the Python loop (`physics.c_loop = False`),
  against bare `mujoco.mj_step` of the same model from the same start with the same recorded commands;
- an `env.step`: simbench's against the reacher's (its control step is one 20 ms physics step);
- a reset (simbench's settles at the plan's start) against the reacher's;
- 84x84 pixels: `physics.render(84, 84, camera_id=0)` against the reacher's, on this machine's GL backend.

Precomputed actions (residual 0 for simbench, uniform random for the reacher), so no policy is counted. Each case
and its loops are timed in turn, the cases round-robin, REPEATS rounds after one warm-up; figures are medians.
"""

from __future__ import annotations

import copy
import time

import mujoco
import numpy as np
from dm_control import suite
from dm_control.rl import control

from simbench import env as simbench_env
from simbench.env.rl_mode import with_rl

REPEATS = 7
FRAMES = 30  # 84x84 frames rendered a round
CASES = ("dm_control reacher/easy", "puma600/line", "rsmg/three_turns")


def environment(case: str) -> control.Environment:
    """The environment a case names (simbench's in the RL mode, residual actions)."""
    if case.startswith("dm_control "):
        domain, task = case.split(" ", 1)[1].split("/")
        return suite.load(domain, task, task_kwargs={"random": 0})
    robot, name = case.split("/")
    return simbench_env.load_task(robot, name, *with_rl({"residual": True}))


class Case:
    """A case's environment, its recorded episode (actions, and every physics step's command) and its timers."""

    def __init__(self, name: str):
        self.name, self.env = name, environment(name)
        self.substeps = round(self.env.control_timestep() / self.env.physics.timestep())
        spec, rng = self.env.action_spec(), np.random.default_rng(0)
        step, self.actions, ctrls = self.env.reset(), [], []
        self.start = copy.copy(self.env.physics.data.ptr)
        while not step.last():
            action = rng.uniform(spec.minimum, spec.maximum) if self.reacher else np.zeros(spec.shape)
            step = self.env.step(action.astype(spec.dtype))
            self.actions.append(action.astype(spec.dtype))
            if self.reacher:
                ctrls.append(np.repeat(self.env.physics.data.ctrl[None], self.substeps, axis=0))
        self.ctrls = np.concatenate(ctrls) if self.reacher else simbench_env.recording(self.env).ctrl[:-1]

    @property
    def reacher(self) -> bool:
        return self.name.startswith("dm_control ")

    def episode(self, c_loop: bool = True) -> tuple[float, float]:
        """(the reset's time, the steps' time) of one episode."""
        if not self.reacher:
            self.env.physics.c_loop = c_loop
        start = time.perf_counter()
        self.env.reset()
        reset = time.perf_counter() - start
        start = time.perf_counter()
        for action in self.actions:
            self.env.step(action)
        return reset, time.perf_counter() - start

    def bare(self) -> float:
        """The time of bare mj_step through the episode's commands."""
        model, data = self.env.physics.model.ptr, copy.copy(self.start)
        start = time.perf_counter()
        for ctrl in self.ctrls:
            data.ctrl[:] = ctrl
            mujoco.mj_step(model, data)
        return time.perf_counter() - start

    def pixels(self) -> float:
        """The time of FRAMES 84x84 frames from camera 0."""
        start = time.perf_counter()
        for _ in range(FRAMES):
            self.env.physics.render(84, 84, camera_id=0)
        return time.perf_counter() - start


def measure() -> dict:
    """Every case's loops, timed in turn, round after round."""
    cases = [Case(name) for name in CASES]
    times: dict[str, dict[str, list[float]]] = {case.name: {} for case in cases}
    for repeat in range(REPEATS + 1):
        for case in cases:
            found = {"bare": case.bare(), "pixels": case.pixels()}
            found["reset"], found["c"] = case.episode(c_loop=True)
            if not case.reacher:
                found["python"] = case.episode(c_loop=False)[1]
            if repeat:  # the first round warms up
                for key, value in found.items():
                    times[case.name].setdefault(key, []).append(value)
    rows = []
    for case in cases:
        median = {key: float(np.median(values)) for key, values in times[case.name].items()}
        steps, physics_steps = len(case.actions), len(case.ctrls)
        rows.append({"case": case.name, "control_steps": steps, "substeps": case.substeps,
                     "env_step_us": 1e6 * median["c"] / steps,
                     "physics_c_us": 1e6 * median["c"] / physics_steps,
                     "physics_python_us": 1e6 * median["python"] / physics_steps if "python" in median else None,
                     "bare_us": 1e6 * median["bare"] / physics_steps,
                     "reset_ms": 1e3 * median["reset"], "pixels_ms": 1e3 * median["pixels"] / FRAMES})
    return {"rows": rows}


def markdown(results: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    def cell(value: float | None, digits: int = 1) -> str:
        return "-" if value is None else f"{value:.{digits}f}"

    rows = [f"| {r['case'] if r['case'].startswith('dm_control') else '`' + r['case'] + '` (RL mode)'} | "
            f"{r['control_steps']:,} x {r['substeps']} | {cell(r['env_step_us'])} | {cell(r['physics_c_us'])} | "
            f"{cell(r['physics_python_us'])} | {cell(r['bare_us'])} | {cell(r['reset_ms'], 2)} | "
            f"{cell(r['pixels_ms'], 2)} |" for r in results["rows"]]
    return "\n".join([
        f"### An RL-mode environment step, beside bare MuJoCo and dm_control's reacher ({REPEATS} rounds)",
        "",
        ("An episode's `env.step`s with precomputed actions (20 ms control steps), per control step and per physics "
         "step (substeps in MuJoCo's C loop, the default, and in the Python loop), against bare `mj_step` through "
         "the same commands; a reset; an 84x84 frame from camera 0. Medians over interleaved rounds:"),
        "",
        ("| environment | control steps x physics steps | env.step (us) | a physics step, C loop (us) | "
         "Python loop (us) | bare mj_step (us) | reset (ms) | 84x84 frame (ms) |"),
        "|---|---|---|---|---|---|---|---|",
        *rows,
    ])


if __name__ == "__main__":
    print(markdown(measure()))
