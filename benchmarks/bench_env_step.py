"""What an RL-mode environment step costs (simbench.env.rl_mode: 20 ms control steps, residual actions), beside bare
MuJoCo and dm_control's reacher (`suite.load('reacher', 'easy')`, also 20 ms a control step), in one run:

- a physics step: an episode's `env.step` time over its physics steps, with the control step's substeps in
  MuJoCo's C loop (`simbench.env.substeps`, the default) and in the Python loop (`physics.c_loop = False`),
  against bare `mujoco.mj_step` of the same model from the same start with the same recorded commands;
- an `env.step`: simbench's against the reacher's (its control step is one 20 ms physics step);
- a reset (simbench's settles at the plan's start) against the reacher's; a random task's reset, planning its task
  or taking one from a pool planned ahead (`task_kwargs` `pool`), against 10 env.steps;
- 84x84 pixels: `physics.render(84, 84, camera_id=0)` against the reacher's, on this machine's GL backend, and
  against dm_control's own Physics of the same scene with the GL context its file sets (`simbench.env.pixels`).

Precomputed actions (residual 0 for simbench, uniform random for the reacher), so no policy is counted. Each case
and its loops are timed in turn, the cases round-robin, REPEATS rounds after one warm-up; figures are each loop's
least time over the rounds (the machine's other work only adds time: on a shared machine its pace changes by half
within seconds, which moved medians more than the differences measured).
"""

from __future__ import annotations

import copy
import time

import mujoco
import numpy as np
from dm_control import suite
from dm_control.mujoco import Physics
from dm_control.rl import control

from simbench import env as simbench_env
from simbench.env.rl_mode import with_rl
from simbench.physics.switches import apply_switch

REPEATS = 7
FRAMES = 30  # 84x84 frames rendered a round
CASES = ("dm_control reacher/easy", "puma600/line", "rsmg/three_turns")
POOL = 8  # random tasks a pool plans ahead


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
        self.start_model = copy.copy(self.env.physics.model.ptr)  # before the episode's switches edit it
        self.switches = {} if self.reacher else self.env.task._switches  # sample -> the plan's switches there
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
        """The time of bare mj_step through the episode's commands, the plan's switches (the RSMG's welds) applied
        at their samples as the environment applies them (so that both step the same physics)."""
        model, data = copy.copy(self.start_model), copy.copy(self.start)
        start = time.perf_counter()
        for k, ctrl in enumerate(self.ctrls):
            for switch in self.switches.get(k, ()):
                apply_switch(model, data, switch)
            data.ctrl[:] = ctrl
            mujoco.mj_step(model, data)
        return time.perf_counter() - start

    def pixels(self, physics: Physics | None = None) -> float:
        """The time of FRAMES 84x84 frames from camera 0 (of the environment's physics, or of `physics`)."""
        physics = physics or self.env.physics
        start = time.perf_counter()
        for _ in range(FRAMES):
            physics.render(84, 84, camera_id=0)
        return time.perf_counter() - start

    def file_pixels(self) -> float | None:
        """The same frames through dm_control's own Physics of the same model and state, its GL context as the
        scene file sets it (simbench's: a 1920x1080 buffer, a 4096 shadow map); None for the reacher."""
        if self.reacher:
            return None
        if not hasattr(self, "plain"):
            self.plain = Physics.from_model(self.env.physics.model)
            self.plain.data.qpos[:] = self.start.qpos
            self.plain.forward()
        return self.pixels(self.plain)


class RandomResets:
    """A robot's random-task resets: each planning its own task, or taking one of a pool planned ahead."""

    def __init__(self, name: str):
        robot, task = name.split("/")
        self.name = name
        self.planned = simbench_env.load_task(robot, task, *with_rl({"residual": True}, {"random": 0}))
        self.pooled = simbench_env.load_task(robot, task, *with_rl({"residual": True}, {"random": 0, "pool": POOL}))
        self.pooled.reset()
        self.pooled.task.pool.fill()  # timed after the pool is planned

    def times(self) -> tuple[float, float]:
        """(a reset that plans its task, a pooled reset), s."""
        found = []
        for env in (self.planned, self.pooled):
            start = time.perf_counter()
            env.reset()
            found.append(time.perf_counter() - start)
        return found[0], found[1]


def measure() -> dict:
    """Every case's loops, timed in turn, round after round."""
    cases = [Case(name) for name in CASES]
    randoms = {case.name: RandomResets(case.name) for case in cases if not case.reacher}
    times: dict[str, dict[str, list[float]]] = {case.name: {} for case in cases}
    for repeat in range(REPEATS + 1):
        for case in cases:
            found = {"bare": case.bare(), "pixels": case.pixels()}
            found["reset"], found["c"] = case.episode(c_loop=True)
            if not case.reacher:
                found["python"] = case.episode(c_loop=False)[1]
                found["file_pixels"] = case.file_pixels()
                found["random_reset"], found["pooled_reset"] = randoms[case.name].times()
            if repeat:  # the first round warms up
                for key, value in found.items():
                    times[case.name].setdefault(key, []).append(value)
    rows = []
    for case in cases:
        least = {key: float(np.min(values)) for key, values in times[case.name].items()}
        steps, physics_steps = len(case.actions), len(case.ctrls)
        rows.append({"case": case.name, "control_steps": steps, "substeps": case.substeps,
                     "env_step_us": 1e6 * least["c"] / steps,
                     "physics_c_us": 1e6 * least["c"] / physics_steps,
                     "physics_python_us": 1e6 * least["python"] / physics_steps if "python" in least else None,
                     "bare_us": 1e6 * least["bare"] / physics_steps,
                     "overhead_us": 1e6 * (least["c"] - least["bare"]) / steps,
                     "reset_ms": 1e3 * least["reset"], "pixels_ms": 1e3 * least["pixels"] / FRAMES,
                     **{key: 1e3 * least[key] / (FRAMES if key == "file_pixels" else 1) if key in least else None
                        for key in ("random_reset", "pooled_reset", "file_pixels")}})
    return {"rows": rows}


def markdown(results: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    def cell(value: float | None, digits: int = 1) -> str:
        return "-" if value is None else f"{value:.{digits}f}"

    def name(r: dict) -> str:
        return r["case"] if r["case"].startswith("dm_control") else f"`{r['case']}` (RL mode)"

    steps = [f"| {name(r)} | {r['control_steps']:,} x {r['substeps']} | {cell(r['env_step_us'])} | "
             f"{cell(r['overhead_us'])} | {cell(r['physics_c_us'])} | {cell(r['physics_python_us'])} | "
             f"{cell(r['bare_us'])} | {r['physics_c_us'] / r['bare_us']:.2f} |" for r in results["rows"]]
    resets = [f"| {name(r)} | {cell(r['reset_ms'], 2)} | {cell(r['random_reset'], 0)} | {cell(r['pooled_reset'], 2)} | "
              f"{cell(r['env_step_us'] * 10 / 1e3, 2)} | {cell(r['pixels_ms'], 2)} | {cell(r['file_pixels'], 2)} |"
              for r in results["rows"]]
    return "\n".join([
        f"### An RL-mode environment step, beside bare MuJoCo and dm_control's reacher ({REPEATS} rounds)",
        "",
        ("An episode's `env.step`s with precomputed actions (20 ms control steps), per control step and per physics "
         "step (substeps in MuJoCo's C loop, the default, and in the Python loop), against bare `mj_step` through "
         "the same commands; the overhead is env.step less its physics steps' bare time. The least of interleaved "
         "rounds:"),
        "",
        ("| environment | control steps x physics steps | env.step (us) | overhead a step (us) | a physics step, "
         "C loop (us) | Python loop (us) | bare mj_step (us) | C loop / bare |"),
        "|---|---|---|---|---|---|---|---|",
        *steps,
        "",
        (f"Resets: the task's own; a random task planned at the reset (`random`); a random task from a pool of {POOL} "
         "planned ahead (`pool`, timed once the pool is planned), beside 10 env.steps. An 84x84 frame from camera 0, "
         "and the same frame through dm_control's own Physics with the GL context the scene file sets:"),
        "",
        ("| environment | reset (ms) | random task planned (ms) | random task from a pool (ms) | 10 env.steps (ms) | "
         "84x84 frame (ms) | the file's context (ms) |"),
        "|---|---|---|---|---|---|---|",
        *resets,
    ])


if __name__ == "__main__":
    print(markdown(measure()))
