"""Sweeps: expansion of grids and random samples, failed runs as rows, the same table serially, in worker
processes and on a local Ray cluster, resuming after Ctrl-C, and sweep files that are refused with the field."""

import csv
import itertools
import json
import os
import subprocess
import sys

import numpy as np
import pyarrow.parquet as pq
import pytest
import yaml

import simbench
from simbench.cli import main
from simbench.commands.sweep import execute, load_sweep, run_sweep
from simbench.commands.sweep.spec import assign, parse_path
from simbench.commands.sweep.store import Store
from simbench.core.errors import ScenarioError
from simbench.core.resources import sweeps_dir
from simbench.scenario import parse_scenario
from tests.conftest import interrupt, scenario_file

CASE1 = "spherical_arm/case1"


def write(tmp_path, spec: dict, name: str = "sweep") -> str:
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return str(path)


def read_csv(path) -> list[dict]:
    with open(path) as f:
        return list(csv.DictReader(f))


def without_wall_time(rows: list[dict]) -> list[dict]:
    """wall_time is the one column measured on the machine rather than computed from the scenario."""
    return [{k: v for k, v in r.items() if k != "wall_time"} for r in rows]


def test_field_paths_parse_and_assign():
    assert parse_path("task.goal[1]") == ("task", "goal", 1)
    assert parse_path("task.path[0].line.start") == ("task", "path", 0, "line", "start")
    doc = {"task": {"goal": [1, 2, 3]}}
    assign(doc, ("task", "goal", 1), 9)
    assign(doc, ("sim", "timestep"), 0.002)
    assert doc == {"task": {"goal": [1, 9, 3]}, "sim": {"timestep": 0.002}}
    for bad in ("task..goal", "task.goal[x]", "1task", "task.goal[1"):
        with pytest.raises(ValueError, match="not a field path"):
            parse_path(bad)
    with pytest.raises(ValueError, match="has 3 items, no item \\[5\\]"):
        assign(doc, ("task", "goal", 5), 0)


def test_grid_crossed_with_random_samples(tmp_path):
    """Every grid point (last key fastest) crossed with the same seeded samples; bounds and kinds respected."""
    grid = {"timing.duration": [2, 4], "timing.law": ["cubic", "quintic", "4567"]}
    params = {"task.goal[1]": {"uniform": [60, 80]}, "sim.timestep": {"loguniform": [0.0005, 0.002]},
              "task.nd": {"integers": [5, 7]}, "task.start": {"uniform": [[118, 8, 118, 4], [122, 12, 122, 6]]}}
    spec = {"base": CASE1, "grid": grid, "random": {"samples": 5, "seed": 11, "params": params}}
    sweep = load_sweep(write(tmp_path, spec))
    assert len(sweep.variants) == 2 * 3 * 5
    assert [v.id for v in sweep.variants[:2]] == ["r0000", "r0001"]
    points = [tuple(v.params[k] for k in grid) for v in sweep.variants[::5]]
    assert points == list(itertools.product(*grid.values()))
    samples = [[v.params[k] for k in params] for v in sweep.variants[:5]]
    for g in range(6):  # the same samples at every grid point
        assert [[v.params[k] for k in params] for v in sweep.variants[5 * g:5 * g + 5]] == samples
    for goal1, dt, nd, start in samples:
        assert 60 <= goal1 <= 80 and 0.0005 <= dt <= 0.002 and nd in (5, 6, 7)
        assert np.all(np.array(start) >= [118, 8, 118, 4]) and np.all(np.array(start) <= [122, 12, 122, 6])
    assert len({s[0] for s in samples}) == 5
    v = sweep.variants[7]
    assert v.document["task"]["goal"][1] == v.params["task.goal[1]"]
    assert v.document["timing"]["law"] == v.params["timing.law"]
    again = load_sweep(write(tmp_path, spec, "again"))
    assert [v.params for v in again.variants] == [v.params for v in sweep.variants]
    other = load_sweep(write(tmp_path, {**spec, "random": {**spec["random"], "seed": 12}}, "other"))
    assert [v.params for v in other.variants] != [v.params for v in sweep.variants]


def test_a_base_with_the_longest_name_makes_valid_runs(tmp_path):
    """A base scenario named with the most characters a name may have is valid, and so is each of its runs: the
    run's name, the base's with '-r0000' added, is cut to fit rather than refused."""
    name = "n" + "a" * 98 + "z"
    base = tmp_path / "base.yaml"
    base.write_text(yaml.safe_dump({**yaml.safe_load(open(scenario_file("spherical_arm", "case1"))), "name": name}))
    assert simbench.load_scenario(base).name == name
    sweep = load_sweep(write(tmp_path, {"base": "base.yaml", "grid": {"timing.duration": [2, 3]}}))
    names = [parse_scenario(v.document, v.id).name for v in sweep.variants]
    assert len(set(names)) == 2 and all(len(n) <= 100 and n.startswith("naaa") and n.endswith(v.id)
                                        for n, v in zip(names, sweep.variants))


def test_table_metrics_are_the_runs_own_numbers(tmp_path):
    """A row's metrics equal those of the same scenario evaluated on its own; its report is kept."""
    spec = {"base": CASE1, "grid": {"timing.duration": [3, 5]}}
    result = run_sweep(load_sweep(write(tmp_path, spec)), tmp_path / "out", workers=1)
    scenario = simbench.load_scenario(scenario_file(*CASE1.split("/")))
    alone = simbench.evaluate(scenario.model_copy(update={"timing": scenario.timing.model_copy(
        update={"duration": 5.0})}))
    row = read_csv(tmp_path / "out" / "results.csv")[1]
    assert row["timing.duration"] == "5" and row["status"] == "ok"
    assert float(row["tool_rms"]) == alone.analysis.tracking["tool_rms"]
    assert float(row["joint_max.q3"]) == alone.analysis.tracking["joint_max"]["q3"]
    assert int(row["singularity_events"]) == len(alone.analysis.singularity_events)
    report = json.loads((tmp_path / "out" / "runs" / "r0001" / "report.json").read_text())
    assert report["tracking"]["tool_rms"] == float(row["tool_rms"])
    assert result.summary["status"] == {"ok": 2, "limits": 0, "too_slow": 0, "bad_input": 0, "run_failed": 0,
                                       "crashed": 0}


def test_failed_runs_are_rows_not_crashes(tmp_path):
    """A start the method cannot repair (exit 1 as a run) and one outside the joint range (exit 2 as a run) are
    rows with their reasons; the sweep goes on and exits 0."""
    tasks = [{"start": [300, 0, 80, 30], "goal": [47, 400, -75, 100]},
             {"start": [120, 500, 120, 5], "goal": [120, 75, 5, 90]},
             {"start": [120, 10, 120, 5], "goal": [120, 75, 5, 90]}]
    path = write(tmp_path, {"base": CASE1, "grid": {"task": tasks}})
    assert main(["sweep", path, "--out", str(tmp_path / "out"), "--workers", "2", "--quiet"]) == 0
    rows = read_csv(tmp_path / "out" / "results.csv")
    assert [r["status"] for r in rows] == ["run_failed", "bad_input", "ok"]
    assert "tangent triangle of Fig. 8 has no solution" in rows[0]["error"]
    assert rows[1]["error"].startswith("task.start: q2 = 500 mm is outside the joint range")
    assert rows[0]["tool_rms"] == "" and float(rows[2]["tool_rms"]) < 1e-3
    assert json.loads(rows[2]["task"]) == tasks[2]


def test_serial_parallel_and_ray_give_the_same_table(tmp_path):
    pytest.importorskip("ray", reason="the Ray extra is part of [test]; this check needs it")
    spec = {"base": CASE1, "outputs": "none", "grid": {"timing.law": ["cubic", "4567"]},
            "random": {"samples": 2, "seed": 5, "params": {"timing.duration": {"uniform": [2, 4]}}}}
    sweep = load_sweep(write(tmp_path, spec))
    tables = {}
    for how, kwargs in {"serial": {"workers": 1}, "processes": {"workers": 2},
                        "ray": {"workers": 2, "ray": "local"}}.items():
        result = run_sweep(sweep, tmp_path / how, **kwargs)
        assert result.summary["status"]["ok"] == 4
        tables[how] = (without_wall_time(read_csv(tmp_path / how / "results.csv")),
                       pq.read_table(tmp_path / how / "results.parquet").drop(["wall_time"]))
    assert tables["serial"][0] == tables["processes"][0] == tables["ray"][0]
    assert tables["serial"][1].equals(tables["processes"][1]) and tables["serial"][1].equals(tables["ray"][1])
    assert len(tables["serial"][0]) == 4 and tables["serial"][0][0]["tool_rms"] != ""


def test_interrupted_sweep_resumes_where_it_stopped(tmp_path):
    """Ctrl-C stops the sweep and its workers (exit 130) leaving each finished run's row; the same command
    then runs only the rest, and the table equals that of an uninterrupted sweep."""
    spec = {"base": CASE1, "outputs": "none",
            "random": {"samples": 24, "seed": 2, "params": {"timing.duration": {"uniform": [2, 6]}}}}
    path = write(tmp_path, spec)
    out = tmp_path / "out"
    command = [sys.executable, "-m", "simbench", "sweep", path, "--out", str(out), "--workers", "2", "--quiet"]
    stopped = interrupt(command, lambda: len(list((out / "rows").glob("*.json"))) >= 3, None, timeout=60)
    err = stopped.stderr
    assert stopped.returncode == 130 and "run the same command again to resume" in err and "Traceback" not in err
    done = len(list((out / "rows").glob("*.json")))
    assert 3 <= done < 24
    assert not (out / "results.csv").exists()
    finished = subprocess.run(command[:-1], capture_output=True, text=True, timeout=300)
    assert finished.returncode == 0 and f"{done} from an earlier start" in finished.stdout
    reference = run_sweep(load_sweep(path), tmp_path / "reference", workers=2)
    table = reference.table
    failed = [(s, e) for s, e in zip(table["status"], table["error"]) if s != "ok"]
    assert reference.summary["status"]["ok"] == 24, failed
    assert without_wall_time(read_csv(out / "results.csv")) == without_wall_time(
        read_csv(tmp_path / "reference" / "results.csv"))


def test_a_full_output_run_without_its_row_is_run_again(tmp_path):
    """With outputs: full, a sweep stopped after a run wrote its folder but before its row was recorded finds
    that folder on resuming: the run is redone into it, not refused as an existing output."""
    spec = {"base": CASE1, "outputs": "full", "grid": {"timing.duration": [2, 3]}}
    sweep = load_sweep(write(tmp_path, spec))
    out = tmp_path / "out"
    first = run_sweep(sweep, out, workers=1)
    row = out / "rows" / f"{sweep.variants[1].id}.json"
    row.unlink()
    resumed = run_sweep(sweep, out, workers=1)
    assert resumed.resumed == 1 and resumed.table["status"] == ["ok", "ok"]
    assert resumed.table["tool_rms"] == first.table["tool_rms"]
    assert (out / "runs" / sweep.variants[1].id / "report.json").exists()


def test_a_run_that_kills_its_worker_is_a_crashed_row(tmp_path, monkeypatch):
    """Worker processes are forked, so they run this patched run_variant: the run whose document asks for it
    dies mid-run (as in a segfault); its row says so, the worker is replaced and the other runs finish."""
    real = execute.run_variant

    def dying(document, **kwargs):
        if document["timing"]["duration"] == 3:
            os._exit(7)
        return real(document, **kwargs)

    monkeypatch.setattr(execute, "run_variant", dying)
    spec = {"base": CASE1, "outputs": "none", "grid": {"timing.duration": [2, 3, 4, 5]}}
    result = run_sweep(load_sweep(write(tmp_path, spec)), tmp_path / "out", workers=2)
    assert result.table["status"] == ["ok", "crashed", "ok", "ok"]
    assert result.table["error"][1] == "its worker process died (exit code 7)"


def test_output_folder_is_guarded(tmp_path):
    """A folder holding other results needs --force; a folder another sweep is writing into is refused."""
    first = load_sweep(write(tmp_path, {"base": CASE1, "outputs": "none", "grid": {"timing.duration": [2]}}))
    second = load_sweep(write(tmp_path, {"base": CASE1, "outputs": "none", "grid": {"timing.duration": [3]}}, "b"))
    out = tmp_path / "out"
    run_sweep(first, out, workers=1)
    with pytest.raises(ScenarioError, match="holds other results.*force=True"):
        run_sweep(second, out, workers=1)
    assert run_sweep(second, out, workers=1, force=True).table["timing.duration"] == [3]
    busy = "another simbench run or sweep is writing into this folder"
    with Store(out, second), pytest.raises(ScenarioError, match=busy):
        run_sweep(second, out, workers=1)
    assert run_sweep(second, out, workers=1).resumed == 1


BAD_SWEEPS = [
    ("no base", {"grid": {"timing.duration": [2]}}, "base: missing"),
    ("unknown base", {"base": "spherical_arm/case9", "grid": {"timing.duration": [2]}}, "base: no scenario file"),
    ("nothing varied", {"base": CASE1}, "nothing to vary"),
    ("empty grid list", {"base": CASE1, "grid": {"timing.duration": []}}, "grid.timing.duration"),
    ("bad path", {"base": CASE1, "grid": {"timing..duration": [2]}}, "grid.timing..duration: 'timing..duration' is "
                                                                       "not a field path"),
    ("unknown field", {"base": CASE1, "grid": {"sim.timestpe": [0.001]}},
     "grid.sim.timestpe: unknown field (expected one of: timestep, settle, velocity_feedforward, kp, kv, "
     "force_limits, gravity_compensation, record_every); did you mean 'timestep'?"),
    ("unknown section", {"base": CASE1, "grid": {"simulation.timestep": [0.001]}},
     "grid.simulation.timestep: 'simulation' is an unknown field"),
    ("index beyond the list", {"base": CASE1, "grid": {"task.goal[4]": [1]}},
     "grid.task.goal[4]: the base's task.goal has 4 items, no item [4]"),
    ("an item of a field the base lacks", {"base": CASE1, "grid": {"task.goa[1]": [1]}},
     "grid.task.goa[1]: the base has no field task.goa (a list indexed with [1] must be in the base)"),
    ("two kinds", {"base": CASE1, "random": {"samples": 2, "params": {"timing.duration": {
        "uniform": [1, 2], "normal": [1, 1]}}}}, "expected exactly one of uniform"),
    ("low above high", {"base": CASE1, "random": {"samples": 2, "params": {"timing.duration": {
        "uniform": [3, 2]}}}}, "uniform: [low, high] with low <= high"),
    ("log of zero", {"base": CASE1, "random": {"samples": 2, "params": {"sim.timestep": {
        "loguniform": [0, 0.002]}}}}, "loguniform: bounds must be > 0"),
    ("vector bounds differ", {"base": CASE1, "random": {"samples": 2, "params": {"task.goal": {
        "uniform": [[1, 2], [3, 4, 5]]}}}}, "its two bounds must be the same length"),
    ("a number and a list as bounds", {"base": CASE1, "random": {"samples": 2, "params": {"task.goal[1]": {
        "uniform": [60, [80]]}}}}, "random.params.task.goal[1].uniform: expected both bounds numbers, or both lists"),
    ("a list and a number as bounds", {"base": CASE1, "random": {"samples": 2, "params": {"task.goal": {
        "normal": [[120, 75, 5, 90], 1]}}}}, "random.params.task.goal.normal: expected both bounds numbers, or both"),
    ("swept twice", {"base": CASE1, "grid": {"timing.duration": [2]}, "random": {"samples": 2, "params": {
        "timing.duration": {"uniform": [2, 3]}}}}, "swept twice"),
    ("swept twice, spelt two ways", {"base": CASE1, "grid": {"task.goal[1]": [60]}, "random": {"samples": 2,
        "params": {"task.goal[01]": {"uniform": [60, 70]}}}}, "random.params.task.goal[01]: swept twice: grid sweeps "
     "task.goal[1]"),
    ("a list and an item of it", {"base": CASE1, "grid": {"task.goal[1]": [60, 70], "task.goal": [[120, 75, 5, 90]]}},
     "grid.task.goal: overlaps: grid sweeps task.goal[1]"),
    ("video without outputs", {"base": CASE1, "grid": {"timing.duration": [2]}, "video": True},
     "video: true needs outputs: full"),
    ("zero samples", {"base": CASE1, "random": {"samples": 0, "params": {"timing.duration": {"uniform": [2, 3]}}}},
     "random.samples"),
    ("too many runs", {"base": CASE1, "grid": {"timing.duration": list(range(1, 400)),
                                               "timing.hold": list(range(0, 300))}}, "runs (expected at most"),
    ("misspelt field", {"base": CASE1, "grids": {"timing.duration": [2]}}, "grids: unknown field"),
]


@pytest.mark.parametrize("spec, expected", [b[1:] for b in BAD_SWEEPS], ids=[b[0] for b in BAD_SWEEPS])
def test_bad_sweep_files_exit_2_naming_the_field(tmp_path, capsys, spec, expected):
    path = write(tmp_path, spec)
    code = main(["sweep", path, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and expected in err[0], err
    assert err[0].startswith(f"error: {path}: ")
    assert not (tmp_path / "out").exists()


def test_shipped_sweeps_are_valid():
    shipped = sorted(sweeps_dir().glob("*.yaml"))
    assert len(shipped) >= 3
    for path in shipped:
        sweep = load_sweep(path)
        assert len(sweep.variants) >= 10


def test_a_worker_stopped_as_soon_as_it_is_forked_ends():
    """A sweep whose last run crashed stops the replacement worker it has just forked. Under a parent whose SIGTERM
    handler swallows the signal (a sweep's own handler may), a worker that has not yet reset it inherited the
    handler: stopped by SIGTERM it lived on and the sweep waited for ever (seen under load). Stopped at once,
    twenty times in a row, each worker ends within seconds."""
    import multiprocessing
    import signal
    import threading

    previous = signal.signal(signal.SIGTERM, lambda *_: None)
    try:
        ctx = multiprocessing.get_context("fork")
        for _ in range(20):
            worker = execute._Worker(ctx)
            done = threading.Event()
            threading.Thread(target=lambda w=worker: (w.stop(), done.set()), daemon=True).start()
            assert done.wait(10.0), "the worker outlived its stop"
    finally:
        signal.signal(signal.SIGTERM, previous)
