"""Methods side by side: one scenario's task planned and run by several planners (and controllers), into one
table (comparison.csv in SI units, comparison.md, comparison.json) and overlaid plots.

Each pair of a planner and a controller is one method, evaluated as a separate run of the scenario would be; only
the scenario's own pair keeps its `expect:`.
"""

from __future__ import annotations

import copy
import difflib
import html
import json
import os
from collections.abc import Collection
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from simbench import api
from simbench.analysis.scoring import score
from simbench.analysis.singularity_handling import SingularityHandling
from simbench.api import registry
from simbench.core import budget, destination
from simbench.core.atomic import staged_folder
from simbench.core.errors import PhysicsError, RunError, ScenarioError, printable
from simbench.outputs import csv_cells
from simbench.outputs.figures import columns
from simbench.outputs.page import table_page, write_page
from simbench.outputs.plot_formats import check_format
from simbench.physics.policy import refuse_code
from simbench.planners.path_methods import METHODS
from simbench.scenario import Scenario, load_scenario, parse_scenario
from simbench.scenario.validation import read_yaml

MINK = "mink_baseline"
PATH = "cartesian_path"  # the planner whose task.method `methods` compares
_SETTINGS = {"damping": "dls", "acceleration_limits": "time_scaling"}  # task fields only one method reads
_SOURCE = "compare"  # how a refusal of the arguments names where it comes from (the arguments, not a file)


@dataclass(frozen=True)
class MethodRun:
    """One method and what came of it: `status` the run's, or `failed`/`refused` with `error` saying why."""

    label: str
    planner: str
    controller: str
    scenario: Scenario
    status: str
    evaluation: Any = None  # simbench.commands.pipeline.Evaluation
    error: str | None = None


@dataclass(frozen=True)
class ComparisonResult:
    """A written comparison: where, the methods in order, the table's rows (comparison.csv, SI) and the files."""

    out: Path
    scenario: str
    robot: str
    methods: tuple[MethodRun, ...]
    rows: tuple[dict, ...]
    files: tuple[str, ...]


def compare(scenario_path: str | os.PathLike, planners: list[str] | None, controllers: list[str] | None, out: Path,
            force: bool = False, progress: bool = False, allow_code: bool = False,
            plot_format: str = "png", methods: list[str] | None = None) -> ComparisonResult:
    """Run the scenario's task with every pair of planners (or cartesian_path methods) and controllers, and write
    the table and plots.

    Args:
        scenario_path: The scenario whose task, robot and timing every method gets.
        planners: Planner names; `mink_baseline` follows the scenario's own planner's path. None: `methods`.
        controllers: Controller names; None for the scenario's own.
        out: The folder for comparison.csv/.md/.json, the overlaid plots and index.html.
        force: Replace a folder that holds another comparison (only files simbench wrote).
        progress: Show each run's progress.
        allow_code: Let a policy name a module to import.
        plot_format: `"png"`, `"svg"` or `"pdf"`.
        methods: A cartesian_path scenario's `task.method`s (planners/path_methods.METHODS), each its row, instead
            of `planners`.

    Returns:
        Where it was written, the methods in order with their runs, the table's rows (SI) and the files.

    Raises:
        ScenarioError: a bad argument, scenario file or destination, before anything runs.
    """
    source = Path(scenario_path)
    check_format(plot_format, "simbench.commands.compare")
    out = destination.followed(Path(out))
    if (planners is None) == (methods is None):
        raise ScenarioError(_SOURCE, "planners", "expected planners or methods (cartesian_path's task.method), one "
                                                 "of the two")
    base = load_scenario(source)
    raw = read_yaml(source)
    choices = (_planned(raw, base, _names(planners, "planner", registry.planners())) if methods is None
               else _methods(raw, base, source, _names(methods, "method", METHODS)))
    controllers = (_names(controllers, "controller", registry.controllers()) if controllers is not None
                   else [base.control.controller])
    variants = _variants(raw, base, source, choices, controllers,
                         "planners" if methods is None and len(controllers) == 1 else "methods")
    for *_, scenario in variants:  # every method affordable (simbench.core.budget) and allowed before any runs
        budget.check(scenario)
        refuse_code(scenario, allow_code)
    with destination.locked(out):
        destination.check(out, [source], force)
        # the pipeline (MuJoCo, SciPy) once the arguments are known good
        from simbench.commands.pipeline import evaluate

        runs = tuple(_run(partial(evaluate, allow_code=allow_code), *variant, progress) for variant in variants)
        rows = tuple(row(run) for run in runs)
        with staged_folder(out) as tmp:
            files = _write(tmp, base, runs, rows, plot_format)
    return ComparisonResult(out=out, scenario=base.name or source.stem, robot=base.robot, methods=runs, rows=rows,
                            files=tuple(files))


def _names(names: Any, kind: str, known: Collection[str]) -> list[str]:
    """The names asked for, duplicates dropped; ScenarioError naming the first unknown one."""
    if isinstance(names, str) or not isinstance(names, (list, tuple)) or not names:
        raise ScenarioError(_SOURCE, f"{kind}s", f"expected a list of one or more {kind} names, got {names!r:.80}")
    for name in names:
        if not isinstance(name, str) or name not in known:
            hint = difflib.get_close_matches(str(name), known, n=1)
            suggestion = f"; did you mean {hint[0]!r}?" if hint else ""
            raise ScenarioError(_SOURCE, f"{kind}s", f"unknown {kind} {name!r} (expected one of: "
                                                     f"{', '.join(sorted(known))}){suggestion}")
    return list(dict.fromkeys(names))


def _planned(raw: dict, base: Scenario, planners: list[str]) -> list[tuple[str, str, Any, bool]]:
    """(label, planner, task, whether the scenario's own) of each planner."""
    return [(planner, planner, _task_for(planner, raw, base), planner == base.planner) for planner in planners]


def _methods(raw: dict, base: Scenario, source: Path, methods: list[str]) -> list[tuple[str, str, Any, bool]]:
    """(label, planner, task, whether the scenario's own) of each of cartesian_path's methods: the scenario's task
    with its `method`, without another method's settings; ScenarioError if the scenario is not cartesian_path's."""
    if base.planner != PATH:
        raise ScenarioError(_SOURCE, "methods", f"are {PATH}'s task.method, and {source} plans with "
                                                f"{base.planner}: compare planners with --planners")
    own = base.task.method
    return [(method, PATH, {**{k: v for k, v in raw["task"].items() if _SETTINGS.get(k, method) == method},
                            "method": method}, method == own) for method in methods]


def _variants(raw: dict, base: Scenario, source: Path, choices: list[tuple[str, str, Any, bool]],
              controllers: list[str], field: str) -> list[tuple[str, str, str, Scenario]]:
    """(label, planner, controller, scenario) of every choice (`_planned`, `_methods`) with every controller, each
    validated; ScenarioError naming one unsuited (and `field`, the argument at fault)."""
    out = []
    for choice, planner, task, own_choice in choices:
        for controller in controllers:
            doc = copy.deepcopy(raw)
            doc["planner"], doc["task"] = planner, copy.deepcopy(task)
            own = own_choice and controller == base.control.controller
            if controller != base.control.controller:
                doc["control"] = {"controller": controller}
            if not own:
                doc.pop("expect", None)
            try:
                scenario = parse_scenario(doc, str(source), default_name=source.stem)
            except ScenarioError as err:
                what = choice if len(controllers) == 1 else f"{choice} with {controller}"
                raise ScenarioError(_SOURCE, field, f"{what} cannot run {source}: {err.detail}") from None
            scenario._source = str(source)  # errors of its policy name the file, as `simbench run` of it does
            label = choice if len(controllers) == 1 else f"{choice} / {controller}"
            out.append((label, planner, controller, scenario))
    return out


def _task_for(planner: str, raw: dict, base: Scenario) -> Any:
    """The `task:` a planner gets: the mink baseline follows the scenario's planner; the planner a mink_baseline
    scenario follows gets the followed task; any other the task as written."""
    task = raw.get("task")
    if planner == base.planner:
        return task
    if planner == MINK:
        return {"follow": base.planner, "task": task}
    if base.planner == MINK and isinstance(task, dict):
        follow, followed_task = registry.planners()[MINK].followed_raw(task)
        if follow == planner:
            return followed_task
    return task


def _run(evaluate, label: str, planner: str, controller: str, scenario: Scenario, progress: bool) -> MethodRun:
    """One method evaluated; a physics failure or a refused plan is its row's status, not the comparison's end."""
    try:
        ev = evaluate(scenario, progress=progress)
    except PhysicsError as err:
        return MethodRun(label, planner, controller, scenario, "failed", error=str(err))
    except RunError as err:
        return MethodRun(label, planner, controller, scenario, "refused", error=str(err))
    return MethodRun(label, planner, controller, scenario, ev.verdict.status, evaluation=ev)


# --- the table ------------------------------------------------------------------------------------------------

def singular_sets(run: MethodRun) -> list[api.SingularSet]:
    """The robot's singular sets along the run, distances in multiples of the near tolerance (<= 1: near)."""
    a = run.scenario.analysis
    return run.scenario.robot_def.singular_sets(run.evaluation.recording, api.Tolerance(a.near_angle, a.near_length))


def row(run: MethodRun) -> dict:
    """The table's row of a method, SI units (docs/guide/compare.md); the figures a bench shares, as
    simbench.analysis.scoring decides them."""
    ev = run.evaluation
    shared = score(run.status, run.error, None if ev is None else ev.analysis.tracking,
                   None if ev is None else ev.analysis.metrics)
    out: dict[str, Any] = {"method": run.label, "planner": run.planner, "controller": run.controller,
                           "status": shared["status"], "error": shared["error"], "violations": ""}
    if ev is None:
        return out
    robot = run.scenario.robot_def
    tracking, traj, rec = ev.analysis.tracking, ev.trajectory, ev.recording
    out["violations"] = " ".join(sorted({v["kind"] for v in ev.verdict.violations}))
    out.update(tool_error_max_m=tracking["tool_error_max"], tool_error_rms_m=tracking["tool_error_rms"],
               path_deviation_max_m=shared["deviation_max"], path_deviation_rms_m=tracking["tool_rms"],
               plan_path_deviation_max_m=_plan_deviation(robot, traj))
    peak = ev.analysis.extremes["qd_ref_peak"]  # of every sample, also where the outputs keep every k-th
    out.update({f"qd_peak_{name}": float(peak[j]) for j, name in enumerate(robot.joints)})
    out.update({f"qd_share_{name}": float(peak[j] / robot.qd_max[j]) for j, name in enumerate(robot.joints)})
    out["qd_share_max"] = shared["speed_share_max"]
    simulated = rec.qd_peak if rec.qd_peak is not None else np.abs(rec.thinned().qd).max(axis=0, initial=0.0)
    out["qd_share_max_simulated"] = float((simulated / robot.qd_max).max())  # every state's, a stride's too
    out.update(slowdown=shared["slowdown"], closest_approach=shared["closest_approach"])
    for name, least in ev.analysis.extremes["singular_min"].items():
        out[f"singular_min_{name}"] = least
    for name, figures in ev.analysis.metrics.items():
        if name != SingularityHandling.name:  # its figures are the shared columns above
            out.update(columns(name, figures))
    for prefix, events in (("singular_events", ev.analysis.singularity_events),
                           ("limit_events", ev.analysis.limit_events)):
        for kind in sorted({e["kind"] for e in events}):
            out[f"{prefix}_{kind}"] = sum(e["kind"] == kind for e in events)
    return out


def _plan_deviation(robot, traj) -> float | None:
    """The largest distance of the plan's own tool (the robot's fk at q_ref) from the plan's tool_ref path."""
    from simbench.analysis import path_deviation

    if not robot.has_fk:
        return None
    return float(path_deviation(traj.tool_ref, robot.fk(traj.q_ref)).max())


def _columns(rows: tuple[dict, ...]) -> list[str]:
    """Every row's columns, in the order first met; event counts last (absent from a row: 0)."""
    names: dict[str, None] = {}
    for r in rows:
        names.update(dict.fromkeys(k for k in r if "_events_" not in k))
    events = sorted({k for r in rows for k in r if "_events_" in k})
    return list(names) + events


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, str):
        return csv_cells.safe(value)
    return str(value)


def table_csv(rows: tuple[dict, ...]) -> str:
    """comparison.csv: a row per method; an event kind not met counts 0, a figure a failed method lacks is empty."""
    columns = _columns(rows)
    lines = [csv_cells.row(columns)]
    for r in rows:
        ran = "tool_error_max_m" in r
        lines.append(csv_cells.row(_cell(r.get(c, 0 if ran and "_events_" in c else None)) for c in columns))
    return "".join(lines)


def _display(column: str, robot) -> tuple[str, float, str]:
    """(label, scale, format) of a column in comparison.md: mm, deg/s (or mm/s), percent."""
    if column.endswith("_m"):
        return column.removesuffix("_m").replace("_", " ") + " (mm)", 1e3, "{:.3f}"
    if column.startswith("qd_peak_"):
        joint = column.removeprefix("qd_peak_")
        revolute = robot.kinds[robot.joints.index(joint)] == api.REVOLUTE
        return f"{joint} speed peak ({'deg/s' if revolute else 'mm/s'})", (180 / np.pi if revolute else 1e3), "{:.1f}"
    if column.startswith("qd_share_"):
        what = column.removeprefix("qd_share_").replace("_", " ")
        return f"{what} speed peak (% of limit)", 100.0, "{:.1f}"
    if column == "slowdown":
        return "slowdown (planned / asked duration)", 1.0, "{:.3f}"
    if column == "closest_approach":
        return "closest approach to rank loss (rad-like gap)", 1.0, "{:.4f}"
    if column.startswith("singular_min_"):
        return f"min distance to {column.removeprefix('singular_min_')} (x near tol.)", 1.0, "{:.3f}"
    if "_events_" in column:
        family, kind = column.split("_events_")
        return f"{family} events: {kind}", 1.0, "{:d}"
    return column.replace("_", " "), 1.0, "{}"


def markdown_text(text: Any) -> str:
    """Text (a model's joint name, say) as a Markdown table reads it as written: HTML's metacharacters as entities,
    backslashes and '|' escaped (so that no cell ends early), control characters and line breaks as printable
    escapes (so that no row splits)."""
    return printable(html.escape(str(text), quote=False).replace("\\", "\\\\").replace("|", "\\|"))


def table_markdown(base: Scenario, rows: tuple[dict, ...]) -> str:
    """comparison.md: a column per method, a line per figure, in mm, deg/s and percent."""
    robot = base.robot_def
    a = base.analysis
    lines = [f"# {base.name}: methods compared", "",
             markdown_text(base.description.strip() or f"robot {base.robot}, planner {base.planner}"), "",
             f"Robot {markdown_text(base.robot)}. Tool error: the simulated tool against the plan's reference at the "
             "same time; path deviation: its distance from the planned path; plan path deviation: the plan's own tool "
             "(the robot's forward kinematics at its joint references). Speed peaks are the plan's. Distances to "
             f"singular sets are in multiples of the near tolerance ({np.rad2deg(a.near_angle):g} deg, "
             f"{a.near_length * 1e3:g} mm): at most 1 is near.", "",
             "| | " + " | ".join(f"`{markdown_text(r['method'])}`" for r in rows) + " |",
             "|---|" + "---:|" * len(rows)]
    for column in _columns(rows):
        if column == "method":
            continue
        label, scale, fmt = _display(column, robot)
        cells = []
        for r in rows:
            value = r.get(column, 0 if "tool_error_max_m" in r and "_events_" in column else None)
            if value is None or value == "":
                cells.append("")
            elif isinstance(value, (int, float)) and not isinstance(value, bool):
                cells.append(fmt.format(int(value)) if fmt == "{:d}" else fmt.format(value * scale))
            else:
                cells.append(markdown_text(value))
        lines.append(f"| {markdown_text(label)} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


# --- the outputs ----------------------------------------------------------------------------------------------

def _write(folder: Path, base: Scenario, runs: tuple[MethodRun, ...], rows: tuple[dict, ...],
           plot_format: str) -> list[str]:
    """Every output into `folder`; their names."""
    (folder / "comparison.csv").write_text(table_csv(rows))
    (folder / "comparison.md").write_text(table_markdown(base, rows))
    plots = _plots(folder / "plots", base, runs, plot_format)
    files = ["comparison.csv", "comparison.md", "comparison.json", *(f"plots/{p}" for p in plots)]
    document = {
        "scenario": {"name": base.name, "file": base.source, "description": base.description},
        "robot": base.robot,
        "methods": [{"method": run.label, "planner": run.planner, "controller": run.controller,
                     "status": run.status, "error": run.error,
                     "violations": [] if run.evaluation is None else list(run.evaluation.verdict.violations),
                     "plan_warnings": [] if run.evaluation is None else list(run.evaluation.trajectory.warnings),
                     "config": run.scenario.model_dump(mode="json")} for run in runs],
        "rows": list(rows),
        "outputs": files,
    }
    from simbench.outputs.report import plain

    (folder / "comparison.json").write_text(json.dumps(plain(document), indent=2, allow_nan=False) + "\n")
    write_page(folder, table_page(
        folder, f"Comparison: {base.name} ({base.robot})",
        f"The task of {base.source or base.name}, with each method in turn. {base.description}",
        [("Methods, SI units (comparison.csv)", Path("comparison.csv"))], [f"plots/{p}" for p in plots],
        document["methods"][0]["config"]))
    return [*files, "index.html"]


def _plots(folder: Path, base: Scenario, runs: tuple[MethodRun, ...], plot_format: str) -> list[str]:
    """The methods overlaid against time: tool error, joint speeds, distance to each singular set."""
    from matplotlib import rcParams

    from simbench.api.panels import plot_text, time_panels
    from simbench.outputs.plots import save

    folder.mkdir(parents=True, exist_ok=True)
    ran = [r for r in runs if r.evaluation is not None]
    robot = base.robot_def
    cycle = rcParams["axes.prop_cycle"].by_key()["color"]
    color = {r.label: cycle[i % len(cycle)] for i, r in enumerate(runs)}
    floor = 1e-4  # mm: the log scales' floor

    fig, axes = time_panels(2, 8, 5.5)
    for r in ran:
        series, t = r.evaluation.analysis.series, r.evaluation.recording.t
        axes[0, 0].plot(t, np.maximum(series["path_deviation"] * 1e3, floor), color=color[r.label], lw=1.2,
                        label=plot_text(r.label))
        axes[1, 0].plot(t, np.maximum(series["tool_error"] * 1e3, floor), color=color[r.label], lw=1.2)
    axes[0, 0].axhline(base.analysis.path_tolerance * 1e3, color="k", ls=":", lw=0.8, label="path tolerance")
    axes[0, 0].set_ylabel("distance from path (mm)")
    axes[1, 0].set_ylabel("tool error (mm)")
    axes[1, 0].set_xlabel("time (s)")
    axes[0, 0].set_title(f"{base.name}: the simulated tool against the plan's reference", y=1.0)
    for ax in axes[:, 0]:
        ax.set_yscale("log")
        ax.grid(alpha=0.3, which="both")
    axes[0, 0].legend(fontsize=8, loc="best")
    files = [save(fig, folder, "tool_error", plot_format)]

    fig, axes = time_panels(robot.dof, 8, 1.7 * robot.dof + 0.8)
    for j, ax in enumerate(axes[:, 0]):
        revolute = robot.kinds[j] == api.REVOLUTE
        scale, unit = (180 / np.pi, "deg/s") if revolute else (1e3, "mm/s")
        for r in ran:
            ev = r.evaluation
            ax.plot(ev.trajectory.t, ev.trajectory.qd_ref[:, j] * scale, color=color[r.label], lw=1.2,
                    label=plot_text(r.label))
            rec = ev.recording.thinned()  # qd is kept at every record_every-th state
            ax.plot(rec.t, rec.qd[:, j] * scale, color=color[r.label], lw=0.7, ls="--")
        for sign in (-1, 1):
            ax.axhline(sign * robot.qd_max[j] * scale, color="k", ls=":", lw=0.8)
        ax.set_ylabel(f"{plot_text(robot.joints[j])} ({unit})")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8, loc="best")
    axes[0, 0].set_title("Joint speeds: planned (solid), simulated (dashed), speed limits (dotted)", y=1.0)
    axes[-1, 0].set_xlabel("time (s)")
    files.append(save(fig, folder, "joint_speeds", plot_format))

    sets = {r.label: singular_sets(r) for r in ran}
    first = next(iter(sets.values()), [])
    if first:
        cols = 1 if len(first) <= 4 else 3
        rows_ = -(-len(first) // cols)
        fig, axes = time_panels(rows_, 8 if cols == 1 else 13, 2.0 * rows_ + 0.8, cols=cols, gap=0.4, top=0.75)
        fig.suptitle("Distance to each singular set, in multiples of the near tolerance (dotted: near)")
        for i, (ax, sset) in enumerate(zip(axes.flat, first)):
            for r in ran:
                ax.plot(r.evaluation.recording.t, np.maximum(sets[r.label][i].distance, 1e-3), color=color[r.label],
                        lw=1.2, label=plot_text(r.label))
            ax.axhline(1.0, color="k", ls=":", lw=0.8)
            ax.set_yscale("log")
            ax.set_title(plot_text(f"{sset.name}: {sset.condition}"), fontsize=8, y=1.0)
            ax.grid(alpha=0.3, which="both")
        for ax in list(axes.flat)[len(first):]:
            ax.remove()
        axes[0, 0].legend(fontsize=8, loc="best")
        for ax in axes[-1]:
            ax.set_xlabel("time (s)")
        files.append(save(fig, folder, "singular_distance", plot_format))
    return files
