"""A bench's files beside its rows: every run's scenario file (scenarios/<id>.yaml, before the runs), then the
tables (simbench.commands.bench.board, simbench.commands.bench.paired), plots/ (a Pareto plot per robot among them),
summary.json,
index.html and, for several arms, a page per arm (simbench.commands.bench.allarms), each claimed in the folder's marker
before it is written (simbench.core.destination).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml
from matplotlib.figure import Figure

from simbench.api.panels import plot_text
from simbench.commands.bench.allarms import arm_page, grid, of_robot
from simbench.commands.bench.board import SCENARIOS, scenario_file
from simbench.commands.bench.paired import paired
from simbench.commands.sweep import table
from simbench.core.atomic import holds, staged_folder, write_text
from simbench.core.forked import dealt
from simbench.outputs.page import write_page
from simbench.outputs.page.html import cell, config_section, document, esc, figure_grid, href, paragraphs
from simbench.outputs.page.tables import MAX_ROWS
from simbench.outputs.plots import plain_ticks
from simbench.outputs.report import plain, write_report

try:  # libyaml's emitter where PyYAML has it: a scenario file in 1 ms rather than 4
    from yaml import CSafeDumper as _SafeDumper
except ImportError:
    from yaml import SafeDumper as _SafeDumper  # type: ignore[assignment]

RESULTS = ("runs.csv", "runs.parquet", "leaderboard.csv", "leaderboard_by_kind.csv", "paired.csv", "summary.json",
           "index.html")


def scenario_text(bench, variant) -> str:
    """Run `variant`'s scenario file: the document the bench runs (bench.methods: complete, SI) as YAML, after a
    comment saying which run of which bench it is."""
    spec = bench.spec
    head = (f"# simbench bench {spec.suite} ({spec.version}, seed {spec.seed}, {spec.tasks} tasks per robot): run "
            f"{variant.index + 1} "
            f"of {len(bench.variants)}, runs.csv's {variant.id}.\n"
            "# `simbench run` of this file plans, simulates and scores it alone, as the bench ran it.\n")
    return head + yaml.dump(plain(variant.document), Dumper=_Dumper, sort_keys=False, width=120)


class _Dumper(_SafeDumper):
    """YAML as a scenario file is written by hand: sections as blocks, a list of numbers on one line."""

    def represent_list(self, data: list) -> yaml.Node:
        flat = not any(isinstance(item, (list, dict)) for item in data)
        return self.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flat)


_Dumper.add_representer(list, _Dumper.represent_list)


def write_scenarios(store, out: Path, bench) -> None:
    """Every run's scenario file not yet in `out` as it should be, claimed in the folder's marker first; before the
    runs, so that a run in progress can be opened too."""
    texts = {scenario_file(v.id): scenario_text(bench, v) for v in bench.variants}
    todo = {name: text for name, text in texts.items() if not holds(out / name, text)}
    if not todo:
        return
    store.claim(tuple(todo))
    with store.writing():
        (out / SCENARIOS).mkdir(exist_ok=True)
        for name, text in todo.items():
            write_text(out / name, text)


def write(store, out: Path, runs: dict[str, list], boards: tuple[dict[str, list], dict[str, list]], summary: dict,
          workers: int) -> None:
    """Every file of the bench's results into `out`; `boards`: the leaderboard by robot and method, and by robot,
    method and kind of task. A bench of several arms (the suite's, `summary["robots"]`, whether or not a method
    applied to each) has a page per arm too (bench.allarms)."""
    robots = list(summary["robots"])
    arms = [arm_page(robot) for robot in robots] if len(robots) > 1 else []
    store.claim((*RESULTS, *arms))
    with store.writing():
        pairs = paired(runs, summary["seed"])
        stamped_runs = defined(runs, summary)
        table.write_csv(stamped_runs, out / "runs.csv")
        missing = table.write_parquet_where_installed(stamped_runs, out / "runs.parquet")  # bench.command says why
        parquet = [] if missing else ["runs.parquet"]
        table.write_csv(defined(boards[0], summary), out / "leaderboard.csv")
        table.write_csv(defined(boards[1], summary), out / "leaderboard_by_kind.csv")
        table.write_csv(defined(pairs, summary), out / "paired.csv")
        with staged_folder(out / "plots") as tmp:
            plots = {robot: [f"plots/{name}" for name in names]
                     for robot, names in draw(runs, boards[0], tmp, workers).items()}
        summary = {**summary, "workers": workers,
                   "outputs": {"tables": ["runs.csv", *parquet, "leaderboard.csv", "leaderboard_by_kind.csv",
                                          "paired.csv"],
                               "plots": [name for names in plots.values() for name in names],
                               "page": "index.html", "arm_pages": arms}}
        write_report(summary, out / "summary.json")
        tables = [("Leaderboard", "leaderboard.csv", boards[0]),
                  ("By kind of task", "leaderboard_by_kind.csv", boards[1]),
                  ("Method against method, on the tasks both ran", "paired.csv", pairs),
                  ("Every run, each linked to its scenario file", "runs.csv", runs)]
        title = f"Bench: {summary['suite']}"
        for robot, name in zip(robots, arms):
            mine = [(caption, file, of_robot(columns, robot)) for caption, file, columns in tables]
            lead = '<p><a href="index.html">All arms</a> of this bench, and its configuration.</p>\n'
            write_text(out / name, page(out, f"{title}, arm {robot}", lead, _intro(summary), mine,
                                        plots.get(robot, []), None))
        lead = grid(boards[0], robots, summary["methods"]) if arms else ""
        write_page(out, page(out, title, lead, _intro(summary), tables, summary["outputs"]["plots"], summary))


def defined(columns: dict[str, list], summary: dict) -> dict[str, list]:
    """A table (columns with a `robot` column) with what defines its rows' figures at its end, so that a table
    copied out of the folder still says them: the benchmark `version`, the suite's `seed` and each row's robot's
    `model_hash` (summary.json's)."""
    if not columns:
        return columns
    robots = columns["robot"]
    return {**columns, "version": [summary["version"]] * len(robots), "seed": [summary["seed"]] * len(robots),
            "model_hash": [summary["models"][robot] for robot in robots]}


def _intro(summary: dict) -> str:
    """What the bench ran and how its figures are decided."""
    counts = ", ".join(f"{n} {status}" for status, n in summary["status"].items() if n)
    return (f"{summary['runs']} runs ({counts}): {summary['tasks']} tasks per robot of benchmark version "
            f"{summary['version']} at seed {summary['seed']} "
            f"(through, near and far from each robot's singular set, in turn), by {', '.join(summary['methods'])}"
            f", on {summary['backend']}.\n\nEach run is planned, simulated and analysed as `simbench run` does, from "
            f"its scenario file ({SCENARIOS}/, linked from its row), which `simbench run` runs alone; one whose "
            f"plan takes more than {summary['max_slowdown']:g} times the asked duration, or more than "
            f"{summary['plan_seconds']:g} s to make, is too_slow. The leaderboard's intervals are bootstrap 95 % "
            "intervals over the tasks; paired.csv sets each method against each other on the tasks both ran (wins, "
            "ties and losses of the first, and the median difference first - second with its bootstrap 95 % "
            "interval); the Pareto plot places each method by its median slowdown and deviation p95.")


def page(out: Path, title: str, lead: str, intro: str, tables: list[tuple[str, str, dict[str, list]]],
         plots: list[str], summary: dict | None) -> str:
    """A bench's page: `lead` (HTML: the grid of arms, a link back to it), the tables ((caption, file, columns),
    a `scenario` column's paths as links to the files), the plots and the summary."""
    body = [f"<h1>{esc(title)}</h1>\n", lead, paragraphs(intro), '<h2 id="tables">Tables</h2>\n',
            *(_table(caption, name, columns) for caption, name, columns in tables),
            f'<h2 id="figures">Figures</h2>\n{figure_grid(out, plots)}' if plots else "", config_section(summary)]
    return document(f"simbench: {title}", "".join(body))


def _table(caption: str, name: str, columns: dict[str, list]) -> str:
    """A table of `columns` (its file `name` linked), a `scenario` column's paths as links; MAX_ROWS rows at most."""
    head = f'<h3>{esc(caption)} (<a href="{href(name)}">{esc(name)}</a>)</h3>\n'
    if not columns:
        return f'{head}<p class="note">(empty)</p>\n'
    rows = list(zip(*columns.values()))
    shown = "".join("<tr>" + "".join(f'<td><a href="{href(v)}">{esc(v)}</a></td>' if k == "scenario" else cell(v)
                                     for k, v in zip(columns, row)) + "</tr>\n" for row in rows[:MAX_ROWS])
    more = (f'<p class="note">The first {MAX_ROWS} of {len(rows)} rows; all are in the file above.</p>\n'
            if len(rows) > MAX_ROWS else "")
    header = "".join(f"<th>{esc(k)}</th>" for k in columns)
    return (f'{head}<div class="scroll"><table><thead><tr>{header}</tr></thead>\n<tbody>\n{shown}</tbody></table>'
            f"</div>\n{more}")


def draw(runs: dict[str, list], leaderboard: dict[str, list], folder: Path, workers: int = 1) -> dict[str, list[str]]:
    """Per robot: the Pareto plot of its methods (from `leaderboard`), and by method the path deviation against the
    closest approach, the plan's joint-speed share and the slowdown, into `folder`, by `workers` processes
    (core.forked.dealt); their file names by robot."""
    jobs, owners = [], []  # each figure's job, and its robot
    for robot in dict.fromkeys(runs["robot"]):
        rows = [i for i, r in enumerate(runs["robot"]) if r == robot]
        methods = list(dict.fromkeys(runs["method"][i] for i in rows))
        jobs.append((_save, (folder, f"pareto_{robot}.png", _pareto, leaderboard, robot, methods)))
        for kind, drawer in (("deviation", _deviation), ("speed_share", _speed_share), ("slowdown", _slowdown)):
            jobs.append((_save, (folder, f"{robot}_{kind}.png", drawer, runs, rows, methods, robot)))
        owners += [robot] * (len(jobs) - len(owners))
    names: dict[str, list[str]] = {robot: [] for robot in owners}
    for robot, name in zip(owners, dealt(jobs, workers, "drawing the bench's plots")):
        names[robot].append(name)
    return names


def _save(folder: Path, name: str, drawer, *args) -> str:
    """A figure of one panel drawn by `drawer(ax, *args)`, its ticks plain, saved as `folder`/`name`; `name`."""
    fig = Figure(figsize=(6.4, 4.2), layout="constrained")
    drawer(fig.add_subplot(), *args)
    plain_ticks(fig)
    fig.savefig(folder / name, dpi=100)
    return name


_AREA = 500.0  # pt^2: a Pareto plot's marker for an ok share of 1
_NEAR = 18.0  # px: points closer than this on a Pareto plot share a label


def _pareto(ax, leaderboard: dict[str, list], robot: str, methods: list[str]) -> None:
    """Each method at (slowdown median, deviation p95) with their bootstrap intervals, its disc's area the ok share
    (the ring: a share of 1), named; the methods no other beats on both (non_dominated) joined by a step line."""
    rows = {m: i for i, (r, m) in enumerate(zip(leaderboard.get("robot", []), leaderboard.get("method", [])))
            if r == robot}
    board = {name: leaderboard.get(name, []) for name in ("slowdown_median", "deviation_p95_mm", "ok_share")}
    placed = [m for m in methods if m in rows and None not in (board["slowdown_median"][rows[m]],
                                                                 board["deviation_p95_mm"][rows[m]])]
    points = np.array([[board[c][rows[m]] for c in ("slowdown_median", "deviation_p95_mm")] for m in placed],
                      float).reshape(-1, 2)
    for method, (x, y) in zip(placed, points):
        i, color = rows[method], f"C{methods.index(method) % 10}"
        bars = [[[max(v - leaderboard[f"{c}_lo"][i], 0.0)], [max(leaderboard[f"{c}_hi"][i] - v, 0.0)]]
                for c, v in (("slowdown_median", x), ("deviation_p95_mm", y))]
        ax.errorbar(x, y, xerr=bars[0], yerr=bars[1], fmt="none", ecolor=color, alpha=0.45, linewidth=1)
        ax.scatter(x, y, s=_AREA, facecolors="none", edgecolors=color, linewidths=0.8, linestyle=":")
        ax.scatter(x, y, s=_AREA * (board["ok_share"][i] or 0.0), color=color, alpha=0.75)
    front = points[non_dominated(points)]
    if len(front):
        front = front[np.lexsort((front[:, 1], front[:, 0]))]
        ax.plot(*front.T, drawstyle="steps-post", color="k", linewidth=1, linestyle="--")
        ax.scatter(*front.T, s=_AREA * 1.3, facecolors="none", edgecolors="k", linewidths=1.2,
                   label="non-dominated (joined by the dashed steps)")
        ax.legend(fontsize="small", loc="best", markerscale=0.4)
    for axis, values in zip("xy", points.T):
        if len(values) and values.min() > 0 and values.max() >= 10 * values.min():
            ax.set(**{f"{axis}scale": "log"})
    ax.margins(0.15)
    _names(ax, points, [plot_text(m) for m in placed])
    unplaced = [m for m in methods if m not in placed]
    note = f"\nno figure to place: {', '.join(map(plot_text, unplaced))}" if unplaced else ""
    ax.set(xlabel="median slowdown (planned / asked duration)", ylabel="95th percentile of the deviation (mm)",
           title=f"{plot_text(robot)}: deviation against slowdown (area: ok share){note}")


def _names(ax, points: np.ndarray, names: list[str]) -> None:
    """Name each point to the right of its marker, points drawn within _NEAR pixels of each other in one label, a
    name a line, the highest first (two methods with about the same figures: dls and dls_adaptive, say)."""
    ax.get_xlim(), ax.get_ylim()  # the limits autoscaled now: the points are measured where they will be drawn
    shown = ax.transData.transform(points) if len(points) else points
    groups: list[list[int]] = []
    for k, place in enumerate(shown):
        near = next((group for group in groups if np.hypot(*(shown[group[0]] - place)) < _NEAR), None)
        if near is None:
            groups.append([k])
        else:
            near.append(k)
    for group in groups:
        group.sort(key=lambda k: -shown[k][1])
        ax.annotate("\n".join(names[k] for k in group), points[group[0]], xytext=(14, 4), textcoords="offset points",
                    fontsize=8, va="top")


def non_dominated(points: np.ndarray) -> np.ndarray:
    """Which of `points` (rows of costs, each smaller the better) no other point dominates: none is at most as
    large in every cost and smaller in one."""
    at_most = np.less_equal(points[None, :, :], points[:, None, :]).all(axis=2)  # [i, j]: j at most i in each cost
    smaller = np.less(points[None, :, :], points[:, None, :]).any(axis=2)
    return np.logical_not((at_most & smaller).any(axis=1))


def _values(runs: dict[str, list], rows: list[int], method: str, column: str) -> list[tuple[int, float]]:
    return [(i, float(runs[column][i])) for i in rows if runs["method"][i] == method and runs[column][i] is not None]


def _deviation(ax, runs, rows, methods, robot) -> None:
    for method in methods:
        pairs = [(runs["closest_approach"][i], value) for i, value in _values(runs, rows, method, "deviation_max_mm")
                 if runs["closest_approach"][i] is not None]
        if pairs:
            x, y = np.array(pairs).T
            ax.scatter(np.maximum(x, 1e-5), np.maximum(y, 1e-4), s=14, alpha=0.7, label=plot_text(method))
    ax.set(xscale="log", yscale="log", xlabel="closest approach to rank loss (least singular value of [Jp/L; Jr])",
           ylabel="largest deviation from the path (mm)", title=f"{plot_text(robot)}: path deviation")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize="small")


def _strip(ax, runs, rows, methods, column: str) -> None:
    for k, method in enumerate(methods):
        values = [v for _, v in _values(runs, rows, method, column)]
        if values:
            ax.boxplot([values], positions=[k], widths=0.5, showfliers=False)
            jitter = np.linspace(-0.15, 0.15, len(values)) if len(values) > 1 else [0.0]
            ax.scatter(k + np.asarray(jitter), values, s=10, alpha=0.6)
    ax.set_xticks(range(len(methods)), [plot_text(m) for m in methods])


def _speed_share(ax, runs, rows, methods, robot) -> None:
    _strip(ax, runs, rows, methods, "speed_share_max")
    ax.axhline(1.0, color="tab:red", linewidth=1, linestyle="--")
    ax.set(ylabel="max |qd_ref| / speed limit", title=f"{plot_text(robot)}: joint-speed share (limit at 1)")


def _slowdown(ax, runs, rows, methods, robot) -> None:
    _strip(ax, runs, rows, methods, "slowdown")
    ax.set(ylabel="planned duration / asked duration", title=f"{plot_text(robot)}: slowdown")
