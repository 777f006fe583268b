"""Train PPO (stable-baselines3) on a simbench task's RL mode, through its Gymnasium id, on one CPU core.

    pip install -e '.[rl,train]'
    python examples/rl_ppo/train.py                                   # puma600/line, seed 0, 300k steps
    python examples/rl_ppo/train.py --task agile_eye/avoidance --seeds 0 1 2 --out renders/rl_ppo_eye

The environment is `gymnasium.make("simbench/<robot>-<task>-v0", rl=RL)`: 20 ms control steps, residual actions in
[-1, 1] of the plan's reference (each joint's target is its reference shifted by 0.05 rad at an action of 1: the
action 0 is a bare position servo, which lags the path), the gaussian reward of the tool's distance from its
reference (0.5 at 5 mm), float32, the observation flattened (Gymnasium's FlattenObservation); `--rl` takes other
settings. PPO runs with stable-baselines3's defaults but for the policy's initial spread (`--log-std-init`) and a
learning rate falling linearly to 0 over the run (`--learning-rate` at the start; at a constant rate, PPO drifted
off the servo's return after 200k steps), behind VecNormalize (observations only). Every `--eval-every` steps the
policy, made deterministic, runs one episode on an evaluation copy; its return is the curve.

Beside the curve, on the same reward: the servo's return (simbench's servo: the residual of the servo's target at
0), the action 0's, and a random policy's (uniform actions, the mean of `--random-episodes` episodes).

Writes into --out (default renders/rl_ppo/<robot>-<task>/): curve.csv (seed, steps, return), references.json (the
settings, the three returns, the target: 0.8 of the servo's, and each seed's best and final returns, the first
step at the target and its wall time), curve.png (every seed's curve with the references).
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import gymnasium
import numpy as np

import simbench.env.gym_ids  # noqa: F401  (registers simbench/<robot>-<task>-v0)
from simbench.env import ALL_TASKS, rl_mode

RL = {"residual": True, "residual_of": "reference", "width": 0.005}
"""The RL mode trained (rl_mode.RL's fields; float32 is gym_ids' default): target = reference + 0.05 rad x action,
the reward 0.5 at 5 mm from the path (the shipped scenarios' path tolerance)."""
TARGET_SHARE = 0.8
"""The share of the servo's return a seed must reach."""


def make_env(task: str, rl: dict) -> gymnasium.Env:
    """The task's RL mode (`rl`: rl_mode.RL's fields) as a Gymnasium environment with a flat observation."""
    robot, name = task.split("/")
    return gymnasium.wrappers.FlattenObservation(gymnasium.make(f"simbench/{robot}-{name}-v0", rl=rl))


def episode_return(env: gymnasium.Env, act, seed: int) -> float:
    """One episode's return under `act` (observation -> action)."""
    observation, _ = env.reset(seed=seed)
    total, done = 0.0, False
    while not done:
        observation, reward, terminated, truncated, _ = env.step(act(observation))
        total += float(reward)
        done = terminated or truncated
    return total


def references(task: str, rl: dict, episodes: int) -> dict[str, float]:
    """On the same reward: the servo's return (the residual of the servo's target at 0), the action 0's in the
    mode trained, and a random policy's (uniform actions, the mean of `episodes`)."""
    servo_env = make_env(task, {**rl, "residual": True, "residual_of": "servo"})
    env = make_env(task, rl)
    zero = np.zeros(env.action_space.shape, env.action_space.dtype)
    env.action_space.seed(0)
    return {"servo": episode_return(servo_env, lambda _: zero, seed=0),
            "action 0": episode_return(env, lambda _: zero, seed=0),
            "random": float(np.mean([episode_return(env, lambda _: env.action_space.sample(), seed=k)
                                     for k in range(episodes)]))}


def train(task: str, rl: dict, seed: int, steps: int, eval_every: int, log_std_init: float,
          learning_rate: float) -> list[tuple[int, float]]:
    """PPO on the task from `seed`: (steps, deterministic return) every `eval_every` steps, from step 0."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    torch.set_num_threads(1)
    venv = VecNormalize(DummyVecEnv([lambda: make_env(task, rl)]), norm_reward=False)
    venv.seed(seed)
    model = PPO("MlpPolicy", venv, seed=seed, device="cpu", policy_kwargs={"log_std_init": log_std_init},
                learning_rate=lambda remaining: learning_rate * remaining)  # to 0 at the end (rl-zoo's lin_)
    evaluation = make_env(task, rl)
    curve: list[tuple[int, float]] = []

    def evaluate(at: int) -> None:
        def act(observation):
            return model.predict(venv.normalize_obs(observation), deterministic=True)[0]
        curve.append((at, episode_return(evaluation, act, seed=0)))

    class Every(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps % eval_every == 0:
                evaluate(self.num_timesteps)
            return True

    evaluate(0)
    model.learn(total_timesteps=steps, callback=Every())
    return curve


def plot(path: Path, task: str, rows: list[tuple[int, int, float]], refs: dict[str, float]) -> None:
    """Every seed's curve with the servo's and the random policy's returns."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.6), dpi=100)
    for seed in sorted({r[0] for r in rows}):
        mine = [(s, g) for k, s, g in rows if k == seed]
        ax.plot([s for s, _ in mine], [g for _, g in mine], label=f"PPO seed {seed}")
    ax.axhline(refs["servo"], color="k", lw=1, label="simbench's servo")
    ax.axhline(TARGET_SHARE * refs["servo"], color="k", lw=1, ls=":", label=f"{TARGET_SHARE:g} x servo")
    ax.axhline(refs["random"], color="tab:red", lw=1, ls="--", label="random policy")
    ax.set(xlabel="environment steps", ylabel="return (deterministic policy)", title=f"PPO on {task}")
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


class Parser(argparse.ArgumentParser):
    """A bad argument in one line on stderr, exit 2, before any training."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message}\n")


def settings(text: str) -> dict:
    """An argument's type: the RL mode's settings as a JSON object (simbench.env.rl_mode.RL's fields)."""
    try:
        value = json.loads(text)
        if not isinstance(value, dict):
            raise ValueError("not an object")
        rl_mode.as_rl(value)
    except ValueError as err:  # a JSONDecodeError is one
        raise argparse.ArgumentTypeError(f"expected a JSON object of rl_mode.RL's fields, got {text!r}: {err}") \
            from None
    return value


def main(argv: list[str] | None = None) -> int:
    parser = Parser(description=__doc__.split("\n")[0])
    tasks = [f"{robot}/{name}" for robot, name in ALL_TASKS]
    parser.add_argument("--task", default="puma600/line", metavar="ROBOT/TASK", choices=tasks,
                        help="a task of simbench.env.ALL_TASKS")
    parser.add_argument("--rl", type=settings, default=RL, help="the RL mode's settings as JSON (float32 added)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--steps", type=int, default=300_000)
    parser.add_argument("--eval-every", type=int, default=10_000)
    parser.add_argument("--log-std-init", type=float, default=-1.0, help="the policy's initial log spread")
    parser.add_argument("--learning-rate", type=float, default=3e-4, help="at the start, falling linearly to 0")
    parser.add_argument("--random-episodes", type=int, default=5)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    if min(args.steps, args.eval_every, args.random_episodes) < 1 or min(args.seeds) < 0:
        parser.error("--steps, --eval-every and --random-episodes must be at least 1, --seeds at least 0")
    out = args.out or Path("renders/rl_ppo") / args.task.replace("/", "-")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        parser.error(f"argument --out: cannot make {str(out)!r}: {err.strerror}")

    refs = references(args.task, args.rl, args.random_episodes)
    print(f"{args.task}: returns {refs}", flush=True)
    rows: list[tuple[int, int, float]] = []
    seeds: dict[int, dict] = {}
    for seed in args.seeds:
        start = time.perf_counter()
        curve = train(args.task, args.rl, seed, args.steps, args.eval_every, args.log_std_init, args.learning_rate)
        rows += [(seed, s, g) for s, g in curve]
        reached = [s for s, g in curve if g >= TARGET_SHARE * refs["servo"]]
        seeds[seed] = {"best": max(g for _, g in curve), "final": curve[-1][1],
                       "first_step_at_target": reached[0] if reached else None,
                       "wall_s": round(time.perf_counter() - start, 1)}
        print(f"seed {seed}: {seeds[seed]}", flush=True)
    with open(out / "curve.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["seed", "steps", "return"])
        writer.writerows(rows)
    summary = {"task": args.task, "rl": args.rl, "steps": args.steps, "log_std_init": args.log_std_init,
               "learning_rate": args.learning_rate,
               "references": refs, "target": TARGET_SHARE * refs["servo"], "seeds": seeds}
    (out / "references.json").write_text(json.dumps(summary, indent=2) + "\n")
    plot(out / "curve.png", args.task, rows, refs)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
