"""A bench's files beside its rows: every run's scenario file (scenarios/<id>.yaml, before the runs), then the
tables (simbench.bench.board), plots/, summary.json and index.html, each claimed in the folder's marker before it
is written (simbench.destination).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml
from matplotlib.figure import Figure

from simbench.atomic import staged_folder, write_text
from simbench.page import write_page
from simbench.page.html import cell, config_section, document, esc, figure_grid, href, paragraphs
from simbench.page.tables import MAX_ROWS
from simbench.plots import plain_ticks
from simbench.report import plain, write_report
from simbench.sweep import table

try:  # libyaml's emitter where PyYAML has it: a scenario file in 1 ms rather than 4
    from yaml import CSafeDumper as _SafeDumper
except ImportError:
    from yaml import SafeDumper as _SafeDumper  # type: ignore[assignment]

RESULTS = ("runs.csv", "runs.parquet", "leaderboard.csv", "leaderboard_by_kind.csv", "summary.json", "index.html")
SCENARIOS = "scenarios"  # the folder of the runs' scenario files


def scenario_file(run_id: str) -> str:
    """Where run `run_id`'s scenario file is, relative to the bench's folder (runs.csv's `scenario`)."""
    return f"{SCENARIOS}/{run_id}.yaml"


def scenario_text(bench, variant) -> str:
    """Run `variant`'s scenario file: the document the bench runs (bench.methods: complete, SI) as YAML, after a
    comment saying which run of which bench it is."""
    spec = bench.spec
    head = (f"# simbench bench {spec.suite} (seed {spec.seed}, {spec.tasks} tasks per robot): run {variant.index + 1} "
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
    todo = {name: text for name, text in texts.items() if not _holds(out / name, text)}
    if not todo:
        return
    store.claim(tuple(todo))
    with store.writing():
        (out / SCENARIOS).mkdir(exist_ok=True)
        for name, text in todo.items():
            write_text(out / name, text)


def _holds(path: Path, text: str) -> bool:
    """Whether `path` is a file (not a link) holding `text`."""
    try:
        return not path.is_symlink() and path.read_text(encoding="utf-8") == text
    except (OSError, UnicodeDecodeError):
        return False


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
                 f", on {summary['backend']}.\n\nEach run is planned, simulated and analysed as `simbench run` does, from "
                 f"its scenario file ({SCENARIOS}/, linked from its row), which `simbench run` runs alone; one whose "
                 f"plan takes more than {summary['max_slowdown']:g} times the asked duration, or more than "
                 f"{summary['plan_seconds']:g} s to make, is too_slow. The leaderboard's intervals are bootstrap 95 % "
                 "intervals over the tasks.")
        write_page(out, page(out, f"Bench: {summary['suite']}", intro, runs, boards, plots, summary))


def page(out: Path, title: str, intro: str, runs: dict[str, list], boards: tuple[dict[str, list], dict[str, list]],
         plots: list[str], summary: dict) -> str:
    """index.html: the leaderboards, every run (its `scenario` a link to its file), the plots and the summary."""
    tables = [("Leaderboard", "leaderboard.csv", boards[0]), ("By kind of task", "leaderboard_by_kind.csv", boards[1]),
              ("Every run, each linked to its scenario file", "runs.csv", runs)]
    body = [f"<h1>{esc(title)}</h1>\n", paragraphs(intro), '<h2 id="tables">Tables</h2>\n',
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
            plain_ticks(fig)
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
