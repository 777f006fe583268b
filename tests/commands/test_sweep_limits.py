"""Sweeps held to what the machine can give (issue 33): a sweep too big to expand refused before it is expanded,
workers capped by the cores and the memory budget, Ray addresses checked and an unreachable cluster one line, a
sweep whose every run is bad input exit 2, results.csv safe to open in a spreadsheet, and idle workers quiet."""

import csv
import html
import json
import os
import resource
import signal
import subprocess
import sys

import pytest
import yaml

from simbench.cli import main
from simbench.commands.sweep import execute, load_sweep, run_sweep, table
from simbench.core import budget, interrupts

CASE1 = "spherical_arm/case1"


def write(tmp_path, spec: dict, name: str = "sweep") -> str:
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False, default_flow_style=True, width=1 << 20))
    return str(path)


def one_error_line(capsys) -> str:
    out = capsys.readouterr()
    lines = out.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in out.err, out.err
    return lines[0]


def test_a_sweep_too_big_to_expand_is_refused_before_it_is_expanded(tmp_path):
    """The tester's 203 kB file: a 99,000-item list under two 316-value grids is 316 x 316 = 99,856 runs, each
    holding its own copy of the list (at least 8 bytes an item: 79 GB, over the 64 GiB any machine is allowed).
    Under the tester's 4 GiB cap (where it ended in MemoryError) it is refused with the list's field, for
    --dry-run too, and nothing is written."""
    spec = {"base": CASE1, "grid": {"timing.duration": [1 + k / 100 for k in range(316)],
                                    "timing.hold": [k / 1000 for k in range(316)], "task.start": [[0] * 99_000]}}
    path = tmp_path / "sweep.yaml"
    path.write_text(json.dumps(spec, separators=(",", ":")))  # JSON is YAML
    assert 200_000 < path.stat().st_size < 210_000
    for extra in (["--dry-run"], []):
        done = subprocess.run([sys.executable, "-m", "simbench", "sweep", str(path), "--out", str(tmp_path / "out"),
                               *extra], capture_output=True, text=True, timeout=300, preexec_fn=_memory_cap)
        line = done.stderr.strip()
        assert done.returncode == 2 and "\n" not in line, done.stderr
        assert line.startswith(f"error: {path}: grid.task.start: "), line
        assert "99,856 runs" in line and "expected at most" in line, line
    assert not (tmp_path / "out").exists()


def _memory_cap() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (4 * 2**30, 4 * 2**30))


def test_the_field_that_multiplies_the_runs_is_named(tmp_path, capsys, monkeypatch):
    """Under a 1 MB budget 10,000 runs of case 1 (37 YAML values each: over 3 MB at 8 bytes a value) do not fit,
    and 20 do; the refusal names the grid or random.samples, whichever gives most of the runs."""
    monkeypatch.setattr(budget, "machine_limits", lambda out=None: budget.Limits(memory=10**6))
    durations = {"uniform": [2, 3]}
    cases = [({"grid": {"timing.duration": list(range(1, 101)), "timing.hold": list(range(100))}}, "grid"),
             ({"grid": {"timing.hold": [0, 1]}, "random": {"samples": 5000, "params": {"timing.duration": durations}}},
              "random.samples")]
    for spec, field in cases:
        path = write(tmp_path, {"base": CASE1, **spec})
        assert main(["sweep", path, "--dry-run"]) == 2
        line = one_error_line(capsys)
        assert line.startswith(f"error: {path}: {field}: 10,000 runs of ") and "expected at most" in line, line
    small = write(tmp_path, {"base": CASE1, "grid": {"timing.hold": [0, 1]},
                             "random": {"samples": 10, "params": {"timing.duration": durations}}})
    assert main(["sweep", small, "--dry-run"]) == 0
    assert capsys.readouterr().out.startswith("sweep: 20 runs of ")


def test_more_workers_than_runs_end_without_a_traceback(tmp_path):
    """Two runs with --workers 3: the tester saw an idle worker's traceback at the end (here in 2 of 10 tries, from
    the pool that draws the plots: a race, which the next test pins down); three tries, none may print one."""
    path = write(tmp_path, {"base": CASE1, "outputs": "none", "grid": {"timing.duration": [2, 3]}})
    for _ in range(3):
        done = subprocess.run([sys.executable, "-m", "simbench", "sweep", path, "--out", str(tmp_path / "out"),
                               "--workers", "3", "--force", "--quiet"], capture_output=True, text=True, timeout=300)
        lines = done.stderr.splitlines()
        assert done.returncode == 0 and all(line.startswith("warning: 3 workers asked for") for line in lines), \
            done.stderr  # a warning where this machine has fewer than 3 CPUs, and nothing else


def _signal_handlers(folder) -> str:
    return f"{signal.getsignal(signal.SIGINT)} {signal.getsignal(signal.SIGTERM)}"


def test_plot_workers_leave_signals_to_the_sweep(tmp_path):
    """The figure drawn in a forked worker sees Ctrl-C ignored and SIGTERM's default (the end, quietly), not the
    command's handler that raises."""
    with interrupts.raising_interrupted():
        here, worker = table._draw([(_signal_handlers, ()), (_signal_handlers, ())], tmp_path, workers=2)
    assert "CtrlC" in here
    assert worker == f"{signal.SIG_IGN} {signal.SIG_DFL}"


def test_a_sweep_whose_every_run_is_bad_input_exits_2(tmp_path, capsys):
    """A valid base swept only over values the schema refuses: every run bad_input, so the sweep exits 2 with one
    line saying so (the rows are written), for --dry-run too. A sweep with one run refused and one that ran exits
    0, as before."""
    path = write(tmp_path, {"base": CASE1, "outputs": "none", "grid": {"timing.duration": [-1, -2]}})
    for extra in (["--dry-run"], ["--quiet"]):
        assert main(["sweep", path, "--out", str(tmp_path / "out"), *extra]) == 2
        line = one_error_line(capsys)
        assert line.startswith(f"error: {path}: every one of its 2 runs is bad input (the first, r0000: "
                               "timing.duration: "), line
    with open(tmp_path / "out" / "results.csv") as f:
        assert [row["status"] for row in csv.DictReader(f)] == ["bad_input", "bad_input"]
    mixed = write(tmp_path, {"base": CASE1, "outputs": "none", "grid": {"timing.duration": [2, -1]}}, "mixed")
    for extra in (["--dry-run"], ["--quiet"]):
        assert main(["sweep", mixed, "--out", str(tmp_path / "mixed"), *extra]) == 0
        assert capsys.readouterr().err == ""


FORMULAS = ['=HYPERLINK("http://127.0.0.1/","click")', "+1+2", "-2+3", "@SUM(A1:A2)", "\t=1", "\r=1", "'quoted"]


def test_results_csv_text_cells_cannot_run_as_formulas(tmp_path):
    """Text a spreadsheet would take for a formula (OWASP's list: = + - @, tab, carriage return) is written after a
    single quote, as is text starting with one; numbers, negative ones too, are written as they are. The sweep's
    page shows the text as given."""
    path = write(tmp_path, {"base": CASE1, "outputs": "none",
                            "grid": {"timing.law": FORMULAS + ["cubic"], "timing.hold": [-0.5]}})
    run_sweep(load_sweep(path), tmp_path / "out", workers=1)
    with open(tmp_path / "out" / "results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [row["timing.law"] for row in rows] == ["'" + text for text in FORMULAS] + ["cubic"]
    assert {row["timing.hold"] for row in rows} == {"-0.5"}
    assert all(row["error"].startswith("timing.") for row in rows)  # every run refused, by the schema
    with open(tmp_path / "out" / "index.html", newline="") as f:
        page = f.read()
    for text in FORMULAS:
        shown = html.escape(text).encode("ascii", "xmlcharrefreplace").decode()
        assert f"<td>{shown}</td>" in page, text
    assert "<td>-0.5</td>" not in page and '<td class="n">-0.5</td>' in page


def counted_workers(monkeypatch) -> list:
    """Every worker process a sweep starts, recorded as it is started."""
    started = []

    class Counted(execute._Worker):
        def __init__(self, ctx):
            super().__init__(ctx)
            started.append(self)

    monkeypatch.setattr(execute, "_Worker", Counted)
    return started


def test_workers_beyond_the_cpus_are_capped_with_a_warning(tmp_path, capsys, monkeypatch):
    """--workers 32 on this machine starts one worker per CPU it may use (os.sched_getaffinity), at most one a run,
    and says so in one line."""
    started = counted_workers(monkeypatch)
    cpus = len(os.sched_getaffinity(0))
    path = write(tmp_path, {"base": CASE1, "outputs": "none", "grid": {"timing.duration": [2, 2.5, 3, 3.5]}})
    assert main(["sweep", path, "--out", str(tmp_path / "out"), "--workers", "32", "--quiet"]) == 0
    line = one_error_line(capsys)
    assert line.startswith(f"warning: 32 workers asked for, more than the {cpus} CPUs this process may use: "
                           f"running {min(cpus, 4)} at once"), line
    assert len(started) == (min(cpus, 4) if cpus > 1 else 0)


def test_workers_are_capped_by_the_memory_budget(tmp_path, capsys, monkeypatch):
    """Under a 100 MB budget there is room for one worker (a worker alone was measured at 61 MB): the sweep runs in
    this process, saying why, whatever --workers asks; its runs still run."""
    started = counted_workers(monkeypatch)
    monkeypatch.setattr(execute, "cpu_count", lambda: 4)
    monkeypatch.setattr(budget, "machine_limits", lambda out=None: budget.Limits(memory=100 * 10**6,
                                                                                    memory_basis="test"))
    path = write(tmp_path, {"base": CASE1, "outputs": "none", "grid": {"timing.duration": [2, 3]}})
    assert main(["sweep", path, "--out", str(tmp_path / "out"), "--workers", "2", "--quiet"]) == 0
    line = one_error_line(capsys)
    assert line.startswith("warning: 2 workers asked for, each may need about ") and "of the 100 MB memory budget " \
        "(test): running 1 at once" in line, line
    assert started == []
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["status"]["ok"] == 2


@pytest.mark.parametrize("address", ["garbage", "127.0.0.1", "127.0.0.1:0", "127.0.0.1:65536", "127.0.0.1:port",
                                     "http://127.0.0.1:6379", ":6379", "ray://", "host_name:1"])
def test_a_malformed_ray_address_is_one_line(tmp_path, capsys, address):
    path = write(tmp_path, {"base": CASE1, "grid": {"timing.duration": [2]}})
    assert main(["sweep", path, "--out", str(tmp_path / "out"), "--ray", address]) == 2
    line = one_error_line(capsys)
    assert line == f"error: --ray: expected local, a running cluster's HOST:PORT (e.g. 10.0.0.5:6379) or " \
                   f"ray://HOST:PORT, got {address!r}", line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("address", ["127.0.0.1:1", "ray://127.0.0.1:1", "[::1]:1"])
def test_an_unreachable_ray_cluster_is_one_line(tmp_path, capsys, address):
    """Port 1 on this machine's loopback is closed: the connection is refused at once, and the sweep says so in
    one line before its folder is made (Ray itself retried for over 590 s)."""
    pytest.importorskip("ray", reason="the Ray extra is part of [test]; this check needs it")
    path = write(tmp_path, {"base": CASE1, "grid": {"timing.duration": [2]}})
    assert main(["sweep", path, "--out", str(tmp_path / "out"), "--ray", address]) == 2
    line = one_error_line(capsys)
    assert line.startswith(f"error: --ray: no Ray cluster answers at {address}: "), line
    assert "connection refused" in line or "cannot assign" in line or "not available" in line, line
    assert not (tmp_path / "out").exists()
