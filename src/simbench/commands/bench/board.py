"""A bench's tables (columns: docs/guide/bench.md): runs.csv, a row per task and method, as simbench.analysis.scoring
scores it (shared with `compare`), `too_slow` where its plan's slowdown passes the suite's max_slowdown, with
its scenario file; leaderboard.csv, a row per robot and method, and leaderboard_by_kind.csv, per
kind of task too, with percentile bootstrap intervals drawn at the suite's seed, the robot's and the method's name,
each figure to FIGURES significant digits: the same suite at the same seed writes the same bytes. Paired
statistics between methods: simbench.commands.bench.paired.
"""

from __future__ import annotations

import math
import zlib
from functools import partial
from typing import Any

import numpy as np

from simbench.analysis.scoring import score_flat

TOO_SLOW = "too_slow"  # a run whose plan passed a cost the suite states
PARAMS = ("robot", "task", "kind", "shape", "method", "planner", "anchor_gap", "length_mm", "duration")
FIGURES = 6
BOOTSTRAP = 2000
LEVEL = 95.0
_P95 = partial(np.percentile, q=95.0)
COLUMNS = {"status": "status", "error": "error", "deviation_max_mm": "deviation_max",  # runs.csv's: scoring's
           "orientation_max_deg": "orientation_max", "speed_share_max": "speed_share_max", "slowdown": "slowdown",
           "closest_approach": "closest_approach"}
SCENARIOS = "scenarios"  # the folder of the runs' scenario files


def scenario_file(run_id: str) -> str:
    """Where run `run_id`'s scenario file is, relative to the bench's folder (runs.csv's `scenario`)."""
    return f"{SCENARIOS}/{run_id}.yaml"


def runs_table(rows: list[dict], max_slowdown: float) -> dict[str, list]:
    """runs.csv as columns, in run order."""
    rows = sorted(rows, key=lambda r: r["run"])
    table: dict[str, list] = {name: [r["params"].get(name) for r in rows] for name in PARAMS}
    table["scenario"] = [scenario_file(r["id"]) for r in rows]
    scores = [_cut(score_flat(r["status"], r["error"], r["metrics"]), max_slowdown) for r in rows]
    for name, shared in COLUMNS.items():
        table[name] = [s[shared] for s in scores]
    table["deviation_max_mm"] = [None if d is None else float(d) * 1e3 for d in table["deviation_max_mm"]]
    table["orientation_max_deg"] = [None if a is None else math.degrees(a) for a in table["orientation_max_deg"]]
    table["violations"] = [r["metrics"].get("violations.kinds") or "" for r in rows]
    table["wall_time"] = [r["wall_time"] for r in rows]
    return table


def _cut(score: dict[str, Any], max_slowdown: float) -> dict[str, Any]:
    """A run's score, its status `too_slow` where its plan's slowdown passes `max_slowdown` (the cost said first in
    its error, the run's own figures kept)."""
    slowdown = score["slowdown"]
    if slowdown is None or slowdown <= max_slowdown:
        return score
    said = (f"too_slow: the plan takes {slowdown:.4g} times the asked duration, past the suite's max_slowdown "
            f"{max_slowdown:g}")
    return {**score, "status": TOO_SLOW, "error": f"{said}; {score['error']}" if score["error"] else said}


def leaderboard(runs: dict[str, list], seed: int, by: tuple[str, ...] = ("robot", "method")) -> dict[str, list]:
    """leaderboard.csv as columns: a row per robot and method (and per value of any other column of `by`, the
    task's kind for leaderboard_by_kind.csv), in the order they first appear in `runs`."""
    groups: dict[tuple, list[int]] = {}
    for i, key in enumerate(zip(*(runs[name] for name in by))):
        groups.setdefault(key, []).append(i)
    rows = [_row(runs, dict(zip(by, key)), index, seed) for key, index in groups.items()]
    if not rows:
        return {}
    return {name: [row[name] for row in rows] for name in rows[0]}


def generator(seed: int, *names: str) -> np.random.Generator:
    """The bootstrap's generator for a row named by `names` (robot and method, say): seeded from the suite's seed
    and each name's CRC-32, so that a row's draws depend on nothing else (not on the other rows, nor on the order
    the runs finished in)."""
    return np.random.default_rng([seed, *(zlib.crc32(name.encode()) for name in names)])


def _row(runs: dict[str, list], key: dict[str, str], index: list[int], seed: int) -> dict[str, Any]:
    rng = generator(seed, *key.values())
    ok = np.array([runs["status"][i] == "ok" for i in index], float)
    shares = _finite(runs["speed_share_max"], index)
    row: dict[str, Any] = {**key, "planner": runs["planner"][index[0]], "tasks": len(index), "ok": int(ok.sum()),
                           TOO_SLOW: sum(runs["status"][i] == TOO_SLOW for i in index)}
    row.update(estimate("ok_share", ok, np.mean, rng))
    row.update(estimate("deviation_p95_mm", _finite(runs["deviation_max_mm"], index), _P95, rng))
    row["speed_share_max"] = rounded(shares.max()) if len(shares) else None
    row.update(estimate("slowdown_median", _finite(runs["slowdown"], index), np.median, rng))
    row.update(estimate("orientation_p95_deg", _finite(runs["orientation_max_deg"], index), _P95, rng))
    return row


def estimate(name: str, values: np.ndarray, statistic, rng: np.random.Generator) -> dict[str, float | None]:
    """`name`, `name`_lo and `name`_hi: the statistic of `values` and its bootstrap interval (None without values)."""
    if not len(values):
        return {name: None, f"{name}_lo": None, f"{name}_hi": None}
    lo, hi = bootstrap(values, statistic, rng)
    return {name: rounded(statistic(values)), f"{name}_lo": rounded(lo), f"{name}_hi": rounded(hi)}


def _finite(column: list, index: list[int]) -> np.ndarray:
    """The finite values of `column` at `index` (a missing one, None, left out)."""
    values = np.array([column[i] if column[i] is not None else np.nan for i in index], float)
    return values[np.isfinite(values)]


def bootstrap(values: np.ndarray, statistic, rng: np.random.Generator) -> tuple[float, float]:
    """The percentile bootstrap interval at LEVEL of `statistic` (a function of an array and `axis`) over
    `values`: BOOTSTRAP resamples with replacement, each of len(values)."""
    draws = values[rng.integers(0, len(values), (BOOTSTRAP, len(values)))]
    stats = statistic(draws, axis=1)
    tail = (100.0 - LEVEL) / 2
    lo, hi = np.percentile(stats, [tail, 100.0 - tail])
    return float(lo), float(hi)


def rounded(value: Any) -> float | None:
    """`value` to FIGURES significant digits, as a float (None stays None)."""
    if value is None or not math.isfinite(float(value)):
        return None
    return float(f"{float(value):.{FIGURES}g}")
