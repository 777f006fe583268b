"""A sweep's results: one table (CSV, and Parquet where pyarrow is installed) with a row per run, a summary, and
plots of metrics against parameters. Rows are in run order and `wall_time` (the only machine-dependent column)
comes last, so that the same sweep gives the same table serially, in parallel or on a cluster.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from simbench.api.panels import plot_text
from simbench.core import extras
from simbench.core.atomic import staged_file, staged_folder, write_text
from simbench.core.forked import dealt
from simbench.outputs import csv_cells
from simbench.outputs.plots import plain_ticks

STATUSES = ("ok", "limits", "too_slow", "bad_input", "run_failed", "crashed")  # too_slow: cut past a time limit
FINISHED = ("ok", "limits")  # runs with metrics (`limits`: ran to the end, broke a promise: simbench.analysis.verdict)
_MAX_CATEGORIES = 20
_MAX_PARAM_PANELS = 6


def columns(rows: list[dict], params: list[str]) -> dict[str, list]:
    """The table as columns, rows in run order."""
    rows = sorted(rows, key=lambda r: r["run"])
    metric_names: dict[str, None] = {}
    for row in rows:
        metric_names.update(dict.fromkeys(row["metrics"]))
    table: dict[str, list] = {"run": [r["run"] for r in rows], "id": [r["id"] for r in rows]}
    for name in params:
        table[name] = [r["params"].get(name) for r in rows]
    table["status"] = [r["status"] for r in rows]
    table["error"] = [r["error"] for r in rows]
    for name in metric_names:
        table[name] = [r["metrics"].get(name) for r in rows]
    table["wall_time"] = [r["wall_time"] for r in rows]
    return table


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (list, dict)):
        return json.dumps(value)
    if isinstance(value, str):
        return csv_cells.safe(value)
    return str(value)


def write_csv(table: dict[str, list], path: Path) -> None:
    """results.csv: empty cells where a run has no value; lists as JSON; formula-like text quoted (csv_cells)."""
    lines = [csv_cells.row(table)]
    lines += map(csv_cells.row, zip(*(map(_cell, column) for column in table.values())))
    write_text(path, "".join(lines))


def _arrow_column(values: list):
    """A typed column (a pyarrow Array) where the values share a type; JSON text where they do not (lists, mixed
    kinds)."""
    import pyarrow as pa

    if not any(isinstance(v, (list, dict)) for v in values):
        try:
            return pa.array(values)
        except (pa.ArrowInvalid, pa.ArrowTypeError):
            pass
    return pa.array([None if v is None else json.dumps(v) for v in values], pa.string())


def write_parquet_where_installed(table: dict[str, list], path: Path) -> str | None:
    """The table's Parquet copy at `path`, typed columns, where pyarrow is installed (None); else the note saying
    why it was left out (the CSV table holds the same rows)."""
    missing = extras.missing("pyarrow", path.name)
    if missing is None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        arrow = pa.table({name: _arrow_column(values) for name, values in table.items()})
        with staged_file(path) as tmp:
            pq.write_table(arrow, tmp)
    return missing


def status_counts(status: list[str]) -> dict[str, int]:
    """Runs by status, every status named."""
    return {s: status.count(s) for s in STATUSES}


def summary(table: dict[str, list], metrics: list[str]) -> dict:
    """Counts by status, and for each plotted metric its range over the runs that finished, with their ids."""
    status = table["status"]
    out: dict[str, Any] = {"runs": len(status), "status": status_counts(status), "metrics": {}}
    for name in metrics:
        values = [(v, i) for v, i, s in zip(table.get(name, []), table["id"], status)
                  if s in FINISHED and isinstance(v, (int, float)) and math.isfinite(v)]
        if values:
            lo, hi = min(values), max(values)
            out["metrics"][name] = {"min": lo[0], "min_run": lo[1], "median": float(np.median([v for v, _ in values])),
                                    "max": hi[0], "max_run": hi[1]}
    return out


def _axis(values: list) -> tuple[np.ndarray, list[str] | None] | None:
    """Positions (and labels if categorical) for a parameter on an x axis; None for vectors or too many labels."""
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        return np.asarray(values, float), None
    if any(isinstance(v, (list, dict)) for v in values):
        return None
    labels = sorted({str(v) for v in values})
    if len(labels) > _MAX_CATEGORIES:
        return None
    return np.array([labels.index(str(v)) for v in values], float), labels


def write_plots(table: dict[str, list], params: list[str], grid: list[str], metrics: list[str],
                folder: Path, workers: int = 1) -> tuple[list[str], list[str]]:
    """A figure per metric and a heat map over two numeric grid parameters; (files, notes on what was not)."""
    figures, notes = [], []
    status = np.array(table["status"])
    axes = {p: _axis(table[p]) for p in params}
    plotted = [p for p in params if axes[p] is not None][:_MAX_PARAM_PANELS]
    notes += [f"parameter {p} is not plotted (vector values or too many categories)" for p in params
              if axes[p] is None]
    numeric_grid = [p for p in grid if axes[p] is not None and axes[p][1] is None]
    for metric in metrics:
        if metric not in table:
            notes.append(f"no metric '{metric}' in the results (plots: expects a column of results.csv)")
            continue
        y = np.array([v if isinstance(v, (int, float)) else np.nan for v in table[metric]], float)
        if plotted:
            figures.append((_scatter, (metric, y, status, plotted, axes)))
        if len(numeric_grid) >= 2:
            figures.append((_heatmap, (metric, y, np.isin(status, FINISHED), numeric_grid[:2], table)))
    with staged_folder(folder) as tmp:
        written = _draw(figures, tmp, workers)
    return written, notes


def _draw(figures: list[tuple], folder: Path, workers: int) -> list[str]:
    """Draw each (function, arguments) figure into `folder`; the files' names, in order. matplotlib draws in one
    thread, so with `workers` > 1 this process and forked ones draw them at once (core.forked.dealt: the first here,
    the second in a child)."""
    return dealt([(draw, (*args, folder)) for draw, args in figures], workers, "drawing the sweep's plots")


def _scatter(metric: str, y: np.ndarray, status: np.ndarray, params: list[str], axes: dict, folder: Path) -> str:
    fig = Figure(figsize=(4.2 * len(params), 3.6))
    panels = fig.subplots(1, len(params), squeeze=False, sharey=True)
    ok = np.isin(status, FINISHED)
    finite = ok & np.isfinite(y)
    broke = finite & (status == "limits")
    floor = np.nanmin(y[finite]) if finite.any() else 0.0
    log_y = finite.any() and (y[finite] > 0).all() and y[finite].max() > 100 * y[finite].min()
    for ax, name in zip(panels[0], params):
        x, labels = axes[name]
        kept = finite & ~broke
        ax.plot(x[kept], y[kept], "o", ms=4, color="tab:blue", alpha=0.7, label="ok")
        if broke.any():
            ax.plot(x[broke], y[broke], "o", ms=5, color="tab:orange", alpha=0.8, label=f"limits ({broke.sum()})")
        if (~ok).any():
            ax.plot(x[~ok], np.full((~ok).sum(), floor), "x", ms=7, color="tab:red", label=f"failed ({(~ok).sum()})")
        if labels is not None:
            ax.set_xticks(range(len(labels)), [plot_text(label) for label in labels], rotation=30, ha="right")
        elif (x > 0).all() and x.max() > 100 * x.min():
            ax.set_xscale("log")
        ax.set_xlabel(plot_text(name))
        ax.grid(alpha=0.3)
    if log_y:
        panels[0][0].set_yscale("log")
    panels[0][0].set_ylabel(plot_text(metric))
    panels[0][0].legend(fontsize=8)
    return _save(fig, folder, f"{_safe(metric)}.png")


def _heatmap(metric: str, y: np.ndarray, ok: np.ndarray, pair: list[str], table: dict, folder: Path) -> str:
    """The median of the metric over the finished runs (`ok`) at each grid cell; a cell with none blank."""
    xs, ys = (sorted(set(table[p])) for p in pair)
    by_cell: dict[tuple, list[float]] = {}
    for k, cell in enumerate(zip(table[pair[0]], table[pair[1]])):
        if ok[k] and np.isfinite(y[k]):
            by_cell.setdefault(cell, []).append(y[k])
    cells = np.full((len(ys), len(xs)), np.nan)
    for (xv, yv), values in by_cell.items():
        cells[ys.index(yv), xs.index(xv)] = np.median(values)
    fig = Figure(figsize=(5.5, 4.2))
    ax = fig.subplots()
    image = ax.imshow(cells, origin="lower", aspect="auto", cmap="viridis")
    ax.set_xticks(range(len(xs)), [f"{v:g}" for v in xs])
    ax.set_yticks(range(len(ys)), [f"{v:g}" for v in ys])
    ax.set_xlabel(plot_text(pair[0]))
    ax.set_ylabel(plot_text(pair[1]))
    fig.colorbar(image, ax=ax, label=f"{plot_text(metric)} (median)")
    return _save(fig, folder, f"{_safe(metric)}_grid.png")


def _save(fig: Figure, folder: Path, name: str) -> str:
    plain_ticks(fig)
    fig.tight_layout()
    fig.savefig(folder / name, dpi=100)
    return name


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "._-" else "_" for c in name)
