"""A bench's files beside its rows: the tables (simbench.bench.board), plots/, summary.json and index.html, each
claimed in the folder's marker before it is written (simbench.destination).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from simbench.atomic import staged_folder
from simbench.page import table_page, write_page
from simbench.report import write_report
from simbench.sweep import table

RESULTS = ("runs.csv", "runs.parquet", "leaderboard.csv", "leaderboard_by_kind.csv", "summary.json", "index.html")


def write(store, out: Path, runs: dict[str, list], boards: tuple[dict[str, list], dict[str, list]], summary: dict,
          workers: int) -> None:
    """Every file of the bench's results into `out`; `boards`: the leaderboard by robot and method, and by robot,
    method and kind of task."""
    store.claim(RESULTS)
    with store.writing():
        table.write_csv(runs, out / "runs.csv")
        missing = table.write_parquet_where_installed(runs, out / "runs.parquet")  # bench.command says why
        parquet = [] if missing else ["runs.parquet"]
        table.write_csv(boards[0], out / "leaderboard.csv")
        table.write_csv(boards[1], out / "leaderboard_by_kind.csv")
        with staged_folder(out / "plots") as tmp:
            plots = [f"plots/{name}" for name in draw(runs, tmp)]
        summary = {**summary, "workers": workers,
                   "outputs": {"tables": ["runs.csv", *parquet, "leaderboard.csv", "leaderboard_by_kind.csv"],
                               "plots": plots,
                               "page": "index.html"}}
        write_report(summary, out / "summary.json")
        counts = ", ".join(f"{n} {status}" for status, n in summary["status"].items() if n)
        intro = (f"{summary['runs']} runs ({counts}): {summary['tasks']} tasks per robot at seed {summary['seed']} "
                 f"(through, near and far from each robot's singular set, in turn), by {', '.join(summary['methods'])}"
                 f", on {summary['backend']}.\n\nEach run is planned, simulated and analysed as `simbench run` does; "
                 "the leaderboard's intervals are bootstrap 95 % intervals over the tasks.")
        write_page(out, table_page(out, f"Bench: {summary['suite']}", intro,
                                   [("Leaderboard (leaderboard.csv)", Path("leaderboard.csv")),
                                    ("By kind of task (leaderboard_by_kind.csv)", Path("leaderboard_by_kind.csv")),
                                    ("Every run (runs.csv)", Path("runs.csv"))], plots, summary))


def draw(runs: dict[str, list], folder: Path) -> list[str]:
    """Per robot, by method: the path deviation against the closest approach, the plan's joint-speed share and the
    slowdown, into `folder`; their file names."""
    names = []
    for robot in dict.fromkeys(runs["robot"]):
        rows = [i for i, r in enumerate(runs["robot"]) if r == robot]
        methods = list(dict.fromkeys(runs["method"][i] for i in rows))
        for kind, drawer in (("deviation", _deviation), ("speed_share", _speed_share), ("slowdown", _slowdown)):
            fig = Figure(figsize=(6.4, 4.2), layout="constrained")
            drawer(fig.add_subplot(), runs, rows, methods, robot)
            name = f"{robot}_{kind}.png"
            fig.savefig(folder / name, dpi=100)
            names.append(name)
    return names


def _values(runs: dict[str, list], rows: list[int], method: str, column: str) -> list[tuple[int, float]]:
    return [(i, float(runs[column][i])) for i in rows if runs["method"][i] == method and runs[column][i] is not None]


def _deviation(ax, runs, rows, methods, robot) -> None:
    for method in methods:
        pairs = [(runs["closest_approach"][i], value) for i, value in _values(runs, rows, method, "deviation_max_mm")
                 if runs["closest_approach"][i] is not None]
        if pairs:
            x, y = np.array(pairs).T
            ax.scatter(np.maximum(x, 1e-5), np.maximum(y, 1e-4), s=14, alpha=0.7, label=method)
    ax.set(xscale="log", yscale="log", xlabel="closest approach to rank loss (least singular value of [Jp/L; Jr])",
           ylabel="largest deviation from the path (mm)", title=f"{robot}: path deviation")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize="small")


def _strip(ax, runs, rows, methods, column: str) -> None:
    for k, method in enumerate(methods):
        values = [v for _, v in _values(runs, rows, method, column)]
        if values:
            ax.boxplot([values], positions=[k], widths=0.5, showfliers=False)
            jitter = np.linspace(-0.15, 0.15, len(values)) if len(values) > 1 else [0.0]
            ax.scatter(k + np.asarray(jitter), values, s=10, alpha=0.6)
    ax.set_xticks(range(len(methods)), methods)


def _speed_share(ax, runs, rows, methods, robot) -> None:
    _strip(ax, runs, rows, methods, "speed_share_max")
    ax.axhline(1.0, color="tab:red", linewidth=1, linestyle="--")
    ax.set(ylabel="max |qd_ref| / speed limit", title=f"{robot}: joint-speed share (limit at 1)")


def _slowdown(ax, runs, rows, methods, robot) -> None:
    _strip(ax, runs, rows, methods, "slowdown")
    ax.set(ylabel="planned duration / asked duration", title=f"{robot}: slowdown")
