"""Learn a tracking policy on a simbench task by the cross-entropy method (CEM), in NumPy, on a couple of CPU cores.

    python examples/rl_cem/train.py                    # puma600/line: 10 iterations of 16 episodes, under a minute
    python examples/rl_cem/train.py --task spherical_arm/case1 --iterations 5 --out renders/rl_cem_case1

The policy is linear: a correction on top of the plan's reference, a gain for each of three features of the
observation (the position error q_ref - q, the reference's speed qd_ref, the speed error qd_ref - qd), the same
for every joint (3 parameters), or with --per-joint one a joint (3 x dof):

    target = q_ref + kp * (q_ref - q) + kf * qd_ref + kd * (qd_ref - qd)     (clipped to the action spec)

With every gain zero it commands the reference itself, which the joints' position servos follow with a lag. CEM
samples gains from a Gaussian, runs one episode each, refits the Gaussian to the best (the elite) and repeats.
An episode's score is the environment's own reward (0.5 at the scenario's path tolerance, 1 on the path) summed
over the episode and divided by its number of steps: the mean reward a step, in [0, 1]; an episode that ends in a
PhysicsError scores its rewards so far over the full length. It uses simbench.env's public API only (load_task,
the observation's names, the reward, the action spec).

Writes into --out (default renders/rl_cem/): curve.png (the reward curve), history.csv (one row an iteration),
policy.json (the best gains and their score) and episode/, the best policy's episode analysed and written as
`simbench run` writes a run (report.json with its status, timeseries, plots; --no-report skips it).
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path

import numpy as np
from dm_control.rl.control import PhysicsError

from simbench import env as simbench_env

FEATURES = ("q_ref - q", "qd_ref", "qd_ref - qd")
INITIAL_STD = np.array([2.0, 0.02, 0.02])  # each feature's gain: its spread at the start (1, s, s)


def features(obs) -> np.ndarray:
    """(3, dof): the policy's features of an observation."""
    return np.stack([obs["q_ref"] - obs["q"], obs["qd_ref"], obs["qd_ref"] - obs["qd"]])


def act(gains: np.ndarray, obs, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Position targets: the reference plus the gains' correction, within the action spec."""
    return np.clip(obs["q_ref"] + (gains * features(obs)).sum(axis=0), low, high)


def episode(env, gains: np.ndarray, length: int | None = None) -> tuple[float, int]:
    """Run one episode with `gains` (3, dof; or 3, 1: shared by the joints): (its rewards' sum over `length`
    steps (or over the steps run), the steps run). A PhysicsError ends it where it happened."""
    spec = env.action_spec()
    step, total, steps = env.reset(), 0.0, 0
    try:
        while not step.last():
            step = env.step(act(gains, step.observation, spec.minimum, spec.maximum))
            total += float(step.reward)
            steps += 1
    except PhysicsError:
        pass
    return total / (length or steps), steps


def cem(env, width: int, iterations: int, population: int, elite: int, seed: int, length: int, log=print) -> list:
    """The cross-entropy method over the gains (3, width: 1, shared by the joints, or dof): one dict an
    iteration (its scores' mean, the elite's mean, the best, the best gains so far)."""
    rng = np.random.default_rng(seed)
    mean = np.zeros((3, width))
    std = np.repeat(INITIAL_STD[:, None], width, axis=1)
    best_score, best_gains, history = -np.inf, mean.copy(), []
    for it in range(iterations):
        start = time.perf_counter()
        samples = mean + std * rng.standard_normal((population, 3, width))
        scores = np.array([episode(env, gains, length)[0] for gains in samples])
        order = np.argsort(scores)[::-1][:elite]
        elites = samples[order]
        # Refit to the elite; a floor of a twentieth of the initial spread keeps the search from collapsing.
        mean = elites.mean(axis=0)
        std = np.maximum(elites.std(axis=0), INITIAL_STD[:, None] / 20)
        if scores[order[0]] > best_score:
            best_score, best_gains = float(scores[order[0]]), samples[order[0]].copy()
        row = {"iteration": it + 1, "episodes": (it + 1) * population, "population_mean": float(scores.mean()),
               "elite_mean": float(scores[order].mean()), "best": float(scores[order[0]]),
               "best_so_far": best_score, "seconds": time.perf_counter() - start}
        history.append({**row, "best_gains": best_gains})
        log(f"iteration {it + 1:3d}: population mean {row['population_mean']:.4f}, elite mean "
            f"{row['elite_mean']:.4f}, best {row['best']:.4f} ({row['seconds']:.1f} s)")
    return history


def plot(history: list, reference: float, task: str, path: Path) -> None:
    """The reward curve: the population's mean, the elite's mean and the best, an iteration each."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    it = [row["iteration"] for row in history]
    fig, ax = plt.subplots(figsize=(6.4, 4))
    ax.plot(it, [row["population_mean"] for row in history], "o-", label="population mean")
    ax.plot(it, [row["elite_mean"] for row in history], "s-", label="elite mean")
    ax.plot(it, [row["best"] for row in history], "^-", label="best")
    ax.axhline(reference, color="gray", ls="--", label="the reference as target (all gains 0)")
    ax.set_xlabel("CEM iteration")
    ax.set_ylabel("mean reward a step (episode)")
    ax.set_ylim(0, 1.02)
    ax.set_title(f"CEM on {task}")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


class Parser(argparse.ArgumentParser):
    """A bad argument in one line on stderr, exit 2 (argparse's usage left to --help)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message}\n")


def at_least(low: int):
    """An argument's type: an integer >= low."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < low:
            raise argparse.ArgumentTypeError(f"expected an integer >= {low}, got {text!r}")
        return value
    return parse


def shipped_task(text: str) -> str:
    """An argument's type: a shipped task, robot/name (simbench.env.ALL_TASKS)."""
    if tuple(text.partition("/")[::2]) not in simbench_env.ALL_TASKS:
        shipped = ", ".join(f"{robot}/{name}" for robot, name in simbench_env.ALL_TASKS)
        raise argparse.ArgumentTypeError(f"expected a shipped task ({shipped}), got {text!r}")
    return text


def main(argv: list[str] | None = None) -> int:
    parser = Parser(description=__doc__.split("\n")[0])
    parser.add_argument("--task", type=shipped_task, default="puma600/line",
                        help="a shipped task, robot/name (simbench.env.ALL_TASKS)")
    parser.add_argument("--iterations", type=at_least(1), default=10)
    parser.add_argument("--population", type=at_least(2), default=16, help="episodes an iteration")
    parser.add_argument("--elite", type=at_least(2), default=None, help="episodes kept an iteration (a quarter)")
    parser.add_argument("--seed", type=at_least(0), default=0)
    parser.add_argument("--per-joint", action="store_true", help="a gain a joint for each feature (3 x dof)")
    parser.add_argument("--out", type=Path, default=Path("renders/rl_cem"))
    parser.add_argument("--no-report", action="store_true", help="skip writing the best policy's episode")
    args = parser.parse_args(argv)
    robot, _, name = args.task.partition("/")
    elite = args.elite or max(2, args.population // 4)
    if elite > args.population:
        parser.error(f"argument --elite: expected at most --population ({args.population}), got {elite}")
    try:  # before the search: a folder that cannot be made is known now, not a minute later
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        parser.error(f"argument --out: cannot make {str(args.out)!r}: {err.strerror}")

    env = simbench_env.load_task(robot, name)
    dof = env.action_spec().shape[0]
    reference, length = episode(env, np.zeros((3, 1)))
    print(f"{args.task}: {length} steps an episode, {dof} joints; the reference as target scores {reference:.4f}")
    history = cem(env, dof if args.per_joint else 1, args.iterations, args.population, elite, args.seed, length)

    plot(history, reference, args.task, args.out / "curve.png")
    with open(args.out / "history.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=[k for k in history[0] if k != "best_gains"])
        writer.writeheader()
        writer.writerows({k: v for k, v in row.items() if k != "best_gains"} for row in history)
    best = history[-1]
    gains = best["best_gains"]
    (args.out / "policy.json").write_text(json.dumps(
        {"task": args.task, "reference_score": reference, "best_score": best["best_so_far"],
         "gains": {feature: gains[i].tolist() for i, feature in enumerate(FEATURES)}}, indent=2) + "\n")
    print(f"best {best['best_so_far']:.4f} (the reference {reference:.4f}); the elite's mean from "
          f"{history[0]['elite_mean']:.4f} to {best['elite_mean']:.4f}; wrote {args.out / 'curve.png'}")
    if not args.no_report:
        episode(env, gains)
        result = simbench_env.write_outputs(env, args.out / "episode", video=False, force=True,
                                            control_info={"policy": "examples/rl_cem", **policy_info(gains)})
        print(f"the best policy's episode: {result.report.get('status')}, written to {result.out}")
    return 0


def policy_info(gains: np.ndarray) -> dict:
    """The gains as a report's control_info."""
    return {feature: [round(g, 6) for g in gains[i].tolist()] for i, feature in enumerate(FEATURES)}


if __name__ == "__main__":
    sys.exit(main())
