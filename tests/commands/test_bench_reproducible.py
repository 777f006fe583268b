"""Every bench run reproducible alone (issue 46): the bench writes each run's scenario file (scenarios/<id>.yaml,
complete, SI) beside its row before the runs, runs.csv and index.html link each run to it, and `simbench run` of
it gives the row's figures; a run whose plan passes the suite's max_slowdown is `too_slow`, named and counted
apart, as is one still planning past its plan_seconds, cut at once; the progress line names the run and its
stage. Truths: `simbench run` of the file in this process (the run pipeline writing every output, not the bench's
report-only path), the documents the bench hands its runs (plan_bench), the page's links as an HTML parser reads
them, and the folder's markers as --force reads them."""

import csv
import json
import math
from html.parser import HTMLParser

import pytest

from simbench.cli import main
from simbench.commands.bench import load_suite
from simbench.commands.bench.runner import plan_bench
from simbench.core import destination
from simbench.outputs.report import plain
from simbench.scenario.validation import read_yaml

METHODS = "dls_adaptive,pinv"
COMMAND = ["bench", "planar3r", "--tasks", "2", "--methods", METHODS, "--workers", "1", "--quiet"]


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    """A planar 3R bench of 2 tasks by 2 methods, through the CLI; its folder."""
    out = tmp_path_factory.mktemp("bench") / "planar"
    assert main(COMMAND + ["--out", str(out)]) == 0
    return out


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _number(text):
    return None if text == "" else float(text)


def test_each_run_has_its_scenario_file_holding_what_the_bench_ran(bench):
    """runs.csv names each run's file; the file's YAML is the document the bench hands that run, whole."""
    rows = _rows(bench / "runs.csv")
    variants = {v.id: v for v in plan_bench(load_suite("planar3r").with_options(2, None, METHODS.split(","))).variants}
    assert len(rows) == len(variants) == 4
    for row in rows:
        run_id = f"{row['task']}-{row['method']}"
        assert row["scenario"] == f"scenarios/{run_id}.yaml"
        text = (bench / row["scenario"]).read_text()
        assert text.startswith("# simbench bench planar3r (sb-1, seed 0, 2 tasks per robot): run ")
        document = read_yaml(bench / row["scenario"])
        assert document == plain(variants[run_id].document)
        assert {"robot", "planner", "task", "timing", "units", "sim", "analysis", "control"} <= set(document)
        assert document["task"]["start"] and document["task"]["path"] and document["units"] == {"angle": "rad",
                                                                                                 "length": "m"}


def test_simbench_run_of_a_runs_scenario_file_gives_its_rows_figures(bench, tmp_path):
    """`simbench run` of a file, in another folder (a `through` task by dls_adaptive, a `near` one by pinv):
    report.json's status, deviation (m against mm), orientation error (rad against deg), speed share, slowdown and
    closest approach are the row's to 1e-9."""
    rows = [r for r in _rows(bench / "runs.csv") if (r["kind"], r["method"]) in {("through", "dls_adaptive"),
                                                                                 ("near", "pinv")}]
    assert len(rows) == 2
    for row in rows:
        out = tmp_path / row["task"] / row["method"]
        assert main(["run", str(bench / row["scenario"]), "--out", str(out), "--no-video", "--quiet"]) in (0, 3)
        report = json.loads((out / "report.json").read_text())
        figures = report["metrics"]["singularity_handling"]
        assert report["status"] == row["status"]
        ours = {"deviation_max_mm": report["tracking"]["tool_max"] * 1e3,
                "orientation_max_deg": math.degrees(report["tracking"]["orientation_max"]),
                **{name: figures[name] for name in ("speed_share_max", "slowdown", "closest_approach")}}
        for name, value in ours.items():
            assert value == pytest.approx(_number(row[name]), rel=1e-9, abs=1e-12), (row["scenario"], name)


class _Links(HTMLParser):
    def __init__(self):
        super().__init__()
        self.hrefs = []

    def handle_starttag(self, tag, attrs):
        if tag == "a":
            self.hrefs.append(dict(attrs)["href"])


def test_the_page_links_every_run_to_its_scenario_file(bench):
    links = _Links()
    links.feed((bench / "index.html").read_text())
    scenarios = [h for h in links.hrefs if h.startswith("scenarios/")]
    assert sorted(scenarios) == sorted(r["scenario"] for r in _rows(bench / "runs.csv"))
    assert all((bench / h).is_file() for h in scenarios)
    assert {"runs.csv", "leaderboard.csv", "leaderboard_by_kind.csv"} <= set(links.hrefs)


def test_force_and_resume_treat_the_scenario_files_as_simbenchs(tmp_path, capsys):
    """The files are listed in the folder's marker: resuming keeps them, --force replaces them, a file of the
    user's put among them stops --force (named), and one removed is written again."""
    out = tmp_path / "one"
    command = ["bench", "planar3r", "--tasks", "1", "--methods", "dls_adaptive", "--workers", "1", "--quiet",
               "--out", str(out)]
    assert main(command) == 0
    scenario = out / "scenarios" / "planar3r-t0000-dls_adaptive.yaml"
    text = scenario.read_text()
    assert destination.foreign(out, empty=True) == []
    scenario.unlink()
    assert main(command) == 0  # resumed: the run has its row, its file is written again
    assert json.loads((out / "summary.json").read_text())["resumed"] == 1 and scenario.read_text() == text
    (out / "scenarios" / "notes.txt").write_text("mine")
    assert main(command + ["--force"]) == 2
    assert "scenarios/notes.txt" in capsys.readouterr().err and (out / "scenarios" / "notes.txt").exists()
    (out / "scenarios" / "notes.txt").unlink()
    assert main(command + ["--force"]) == 0 and scenario.read_text() == text


def test_a_run_past_the_suites_max_slowdown_is_too_slow(tmp_path, capsys):
    """A suite stating max_slowdown 0.5 (a plan may take half the asked time): the run, whose slowdown is 1 (it
    keeps the asked timing), is too_slow in runs.csv (its cost said first in its error, its figures kept), counted
    apart in the leaderboard, the summary and the command's line."""
    suite = tmp_path / "slow.yaml"
    suite.write_text("robots: [planar3r]\ntasks: 1\nmethods: [dls_adaptive]\nmax_slowdown: 0.5\n")
    out = tmp_path / "out"
    assert main(["bench", str(suite), "--workers", "1", "--out", str(out)]) == 0
    assert "(1 too_slow)" in capsys.readouterr().out
    (row,) = _rows(out / "runs.csv")
    assert row["status"] == "too_slow" and float(row["slowdown"]) == 1.0
    assert row["error"].startswith("too_slow: the plan takes 1 times the asked duration, past the suite's "
                                   "max_slowdown 0.5")
    assert float(row["deviation_max_mm"]) > 0
    (board,) = _rows(out / "leaderboard.csv")
    assert (board["too_slow"], board["ok"], board["ok_share"]) == ("1", "0", "0.0")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"]["too_slow"] == 1 and summary["max_slowdown"] == 0.5


@pytest.mark.parametrize("field, value, expected", [("max_slowdown", "0", "expected greater than 0, got 0"),
                                                    ("max_slowdown", "fast", "expected a valid number, got 'fast'"),
                                                    ("plan_seconds", "-1", "expected greater than 0, got -1")])
def test_a_bad_cost_is_one_line_naming_the_file_and_field(tmp_path, capsys, field, value, expected):
    suite = tmp_path / "suite.yaml"
    suite.write_text(f"robots: [planar3r]\n{field}: {value}\n")
    assert main(["bench", str(suite), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [f"error: {suite}: {field}: {expected}"]


def test_the_progress_line_names_the_run_and_what_it_is_doing(tmp_path, capsys):
    """The bench's progress line: `<run id>: <stage>` for every stage the run pipeline goes through (its
    stopwatch's), in that order."""
    assert main(["bench", "planar3r", "--tasks", "1", "--methods", "dls_adaptive", "--workers", "1", "--out",
                 str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    shown = [err.find(f"planar3r-t0000-dls_adaptive: {stage}") for stage in
             ("loading", "planning", "simulating", "analysing")]
    assert -1 not in shown and shown == sorted(shown), err[-2000:]


def test_worker_processes_tell_each_runs_stages_as_they_go():
    """Two runs on two worker processes: each run's stages come to the parent before its outcome, in the
    pipeline's order, each under its own run."""
    from simbench.commands.sweep.execute import in_processes

    bench = plan_bench(load_suite("planar3r").with_options(1, None, ["dls_adaptive", "pinv"]))
    told = []
    tasks = [(v.index, {"document": v.document, "source": v.id}) for v in bench.variants]
    for index, outcome in in_processes(tasks, 2, lambda i, stage: told.append((i, stage))):
        assert outcome["status"] == "ok"
        told.append((index, "done"))
    for index in (0, 1):
        assert [stage for i, stage in told if i == index] == ["load", "plan", "simulate", "analyse", "done"]


def test_a_limit_that_passes_at_once_leaves_no_timer_behind():
    """A stage limit of a microsecond, 300 times: each time the stage is cut or ends, and afterwards no timer runs
    and the SIGALRM handler is the one before (an alarm due before the stage's block began used to escape it and
    leave the timer cutting whatever ran next, every half second)."""
    import signal

    from simbench.commands.pipeline import TooSlow, _limited

    before, cut = signal.getsignal(signal.SIGALRM), 0
    for _ in range(300):
        try:
            with _limited("plan", 1e-6):
                sum(range(200))
        except TooSlow:
            cut += 1
        assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)
        assert signal.getsignal(signal.SIGALRM) == before
    assert cut > 0


def test_a_run_planning_past_the_suites_plan_seconds_is_cut_too_slow(tmp_path):
    """plan_seconds 0.001: time_scaling's plan of the planar 3R's first task (seconds when not cut) is cut within
    a second of starting, too_slow, its error saying what passed which limit; the signal handler is as before."""
    import signal

    before = signal.getsignal(signal.SIGALRM)
    suite = tmp_path / "quick.yaml"
    suite.write_text("robots: [planar3r]\ntasks: 1\nmethods: [time_scaling]\nplan_seconds: 0.001\n")
    out = tmp_path / "out"
    assert main(["bench", str(suite), "--workers", "1", "--out", str(out), "--quiet"]) == 0
    (row,) = _rows(out / "runs.csv")
    assert row["status"] == "too_slow" and row["error"] == "planning passed the 0.001 s it may take"
    assert float(row["wall_time"]) < 1.0 and row["deviation_max_mm"] == ""
    (board,) = _rows(out / "leaderboard.csv")
    assert board["too_slow"] == "1"
    assert signal.getsignal(signal.SIGALRM) == before
