"""paired.csv (docs/guide/bench-statistics.md): per robot, each pair of methods A, B on the tasks both ran, task by
task: A's wins, ties and losses against B on `ok` and on the deviation from the path, and the median paired
difference A - B in deviation and in slowdown with its percentile bootstrap interval (the pairs resampled, as
board's leaderboard resamples tasks). Each figure to board.FIGURES significant digits, the generator seeded from
the suite's seed and the three names: the same runs write the same bytes.
"""

from __future__ import annotations

from itertools import combinations
from typing import Any

import numpy as np

from simbench.commands.bench import board

COUNTS = ("wins", "ties", "losses")  # A's against B


def paired(runs: dict[str, list], seed: int) -> dict[str, list]:
    """paired.csv as columns (runs.csv's as columns in, `runs`): a row per robot and unordered pair of the methods
    that ran its tasks, robots and methods in the order they first appear in `runs`."""
    rows = []
    for robot in dict.fromkeys(runs["robot"]):
        tasks: dict[str, dict[str, int]] = {}  # method -> task -> its row in runs
        for i, (name, method, task) in enumerate(zip(runs["robot"], runs["method"], runs["task"])):
            if name == robot:
                tasks.setdefault(method, {})[task] = i
        for a, b in combinations(tasks, 2):
            pairs = [(i, tasks[b][task]) for task, i in tasks[a].items() if task in tasks[b]]
            rows.append(_row(runs, robot, a, b, pairs, seed))
    if not rows:
        return {}
    return {name: [row[name] for row in rows] for name in rows[0]}


def _row(runs: dict[str, list], robot: str, a: str, b: str, pairs: list[tuple[int, int]],
         seed: int) -> dict[str, Any]:
    """One pair's row over `pairs`, (A's row, B's row) per task both ran, in runs.csv's order of A's rows."""
    status, deviation, slowdown = runs["status"], runs["deviation_max_mm"], runs["slowdown"]
    row: dict[str, Any] = {"robot": robot, "method_a": a, "method_b": b, "tasks": len(pairs)}
    row.update(_tally("ok", [int(status[i] == "ok") - int(status[j] == "ok") for i, j in pairs]))
    row.update(_tally("deviation", [_smaller(deviation[i], deviation[j]) for i, j in pairs]))
    rng = board.generator(seed, robot, a, b)
    for name, column, unit in (("deviation", deviation, "_mm"), ("slowdown", slowdown, "")):
        differences = _differences(column, pairs)
        row[f"{name}_n"] = len(differences)
        row.update(board.estimate(f"{name}_diff_median{unit}", differences, np.median, rng))
    return row


def _tally(name: str, outcomes: list[int]) -> dict[str, int]:
    """`name`_wins, _ties and _losses: how many of `outcomes` (+1 A wins, 0 a tie, -1 B wins) are each."""
    return {f"{name}_{count}": outcomes.count(sign) for count, sign in zip(COUNTS, (1, 0, -1))}


def _smaller(x: float | None, y: float | None) -> int:
    """+1 where `x` is the smaller to FIGURES significant digits, -1 where `y` is, 0 where they are equal to those
    digits or both are missing; a missing value (None, or not finite) loses to one present."""
    x, y = board.rounded(x), board.rounded(y)
    if x is None or y is None:
        return (x is not None) - (y is not None)
    return (x < y) - (x > y)


def _differences(column: list, pairs: list[tuple[int, int]]) -> np.ndarray:
    """`column`[A] - `column`[B] over the pairs where both are finite, in the pairs' order."""
    values = np.array([[np.nan if column[k] is None else column[k] for k in pair] for pair in pairs],
                      float).reshape(-1, 2)
    finite = np.isfinite(values).all(axis=1)
    return values[finite, 0] - values[finite, 1]
