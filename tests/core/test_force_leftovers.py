"""What `--force` and a resume remove (issue 45): only what simbench's markers list, or what a simbench writer that
is gone left under a name and with a content that prove it simbench's (a staging folder holding its marker, a
lock file holding its token). A user's file that merely looks like a leftover (`.thesis.old-1/`,
`.results.partial-1`, an empty `.keep.lock`) or an empty folder of theirs is never removed: a write it blocks is
refused in one line naming it (exit 2). `reproduce --out` takes only a folder of its own, and a refusal names the
switch in the words of the caller: `force=True` from Python, `--force` on the command line."""

import shutil
import subprocess
import sys

import pytest
import yaml

import simbench
from simbench.cli import main
from simbench.commands.bench import load_suite, run_bench
from simbench.core import destination
from simbench.core.errors import ScenarioError
from tests.conftest import scenario_file

CASE1 = str(scenario_file("spherical_arm", "case1"))
BENCH = ["bench", "planar3r", "--tasks", "1", "--methods", "dls_adaptive", "--workers", "1", "--quiet"]


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


# A simbench writer killed by SIGKILL at the worst moment, in a process of its own: what it leaves is simbench's.
_KILLED = """
import os, signal, sys
from pathlib import Path
from simbench.core import destination
from simbench.core.atomic import staged_file, staged_folder
what, path = sys.argv[1], Path(sys.argv[2])
if what == "lock":  # holding the lock of `path`
    with destination.locked(path):
        os.kill(os.getpid(), signal.SIGKILL)
elif what == "staging folder":  # writing `path`'s outputs under its hidden name
    with staged_folder(path) as tmp:
        (tmp / "plots").mkdir()
        (tmp / "plots" / "joints.png").write_bytes(b"half a plot")
        os.kill(os.getpid(), signal.SIGKILL)
elif what == "staged file":  # writing the file `path` under its hidden name
    with staged_file(path) as tmp:
        tmp.write_text("half a row")
        os.kill(os.getpid(), signal.SIGKILL)
else:  # between setting `path`'s previous output aside and removing it (atomic._move)
    with staged_folder(path) as tmp:
        (tmp / "report.json").write_text("{}")
    path.rename(path.with_name(f".{path.name}.old-{os.getpid()}"))
    os.kill(os.getpid(), signal.SIGKILL)
"""


def killed(what: str, path) -> None:
    """Leave what a simbench writer of `path` killed while `what` leaves."""
    done = subprocess.run([sys.executable, "-c", _KILLED, what, str(path)], capture_output=True, text=True,
                          timeout=60, check=False)
    assert done.returncode == -9, done.stderr


def _tree(folder) -> dict:
    """Every file (its bytes) and folder (None) under `folder`."""
    return {p.relative_to(folder).as_posix(): None if p.is_dir() else p.read_bytes() for p in folder.rglob("*")}


def _hidden(folder) -> list[str]:
    """The hidden names under `folder` but markers: staging names, locks."""
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob(".*") if p.name != ".simbench")


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory):
    """A finished run's output folder."""
    out = tmp_path_factory.mktemp("run") / "out"
    assert main(["run", CASE1, "--out", str(out), "--no-video", "--quiet"]) == 0
    return out


@pytest.fixture(scope="module")
def finished_bench(tmp_path_factory):
    """A finished bench's output folder (the planar 3R, one task, one method)."""
    out = tmp_path_factory.mktemp("bench") / "out"
    run_bench(load_suite("planar3r").with_options(tasks=1, seed=0, methods=("dls_adaptive",)), out, workers=1)
    return out


# A user's things inside a finished output folder that look like simbench's leftovers: (what to make, its name in
# the refusal).
LOOKALIKES = {
    "set-aside folder": (lambda out: _write(out / ".thesis.old-1" / "chapter1.tex"), ".thesis.old-1/chapter1.tex"),
    "set-aside folder of a dead pid": (lambda out: _write(out / f".thesis.old-{_dead_pid()}" / "chapter1.tex"),
                                       "chapter1.tex"),
    "staged file": (lambda out: _write(out / ".results.partial-1"), ".results.partial-1"),
    "staged file of a dead pid": (lambda out: _write(out / f".results.partial-{_dead_pid()}"), ".results.partial-"),
    "empty lock file": (lambda out: (out / ".keep.lock").touch(), ".keep.lock"),
    "empty folder": (lambda out: (out / "drafts").mkdir(), "drafts/"),
}


def _write(path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("the user's own")


@pytest.mark.parametrize("command", ["run", "bench"])
@pytest.mark.parametrize("lookalike", LOOKALIKES)
def test_force_never_removes_a_users_file_that_looks_like_a_leftover(request, tmp_path, capsys, command, lookalike):
    make, named = LOOKALIKES[lookalike]
    out = tmp_path / "out"
    shutil.copytree(request.getfixturevalue(f"finished_{command}"), out)
    make(out)
    before = _tree(tmp_path)
    args = ["run", CASE1, "--no-video", "--quiet"] if command == "run" else BENCH
    capsys.readouterr()
    assert main(args + ["--out", str(out), "--force"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {out}: ") and "simbench did not write" in err[0], err
    assert named in err[0]
    assert _tree(tmp_path) == before


def test_a_users_folder_beside_an_output_under_a_dead_staging_name_is_kept(finished_run, tmp_path):
    """`.out.old-PID` beside `out`, of a process that is gone but not written by simbench (no marker): a run into
    `out` leaves it as it is."""
    out = tmp_path / "out"
    shutil.copytree(finished_run, out)
    theirs = tmp_path / f".out.old-{_dead_pid()}" / "notes.txt"
    _write(theirs)
    assert main(["run", CASE1, "--out", str(out), "--no-video", "--quiet", "--force"]) == 0
    assert theirs.read_text() == "the user's own"


def test_a_killed_writers_leftovers_beside_its_output_are_removed_and_a_live_ones_kept(tmp_path):
    out = tmp_path / "out"
    killed("staging folder", out)
    killed("set aside", tmp_path / "earlier")  # then renamed as `out`'s, as a writer of `out` leaves it
    (aside,) = tmp_path.glob(".earlier.old-*")
    aside.rename(tmp_path / aside.name.replace(".earlier.", ".out.", 1))
    killed("lock", out)
    assert sorted(p.name.split("-")[0] for p in tmp_path.iterdir()) == [".out.lock", ".out.old", ".out.partial"]
    with subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"]) as alive:
        live = tmp_path / f".out.partial-{alive.pid}"
        live.mkdir()
        assert main(["run", CASE1, "--out", str(out), "--no-video", "--quiet"]) == 0
        alive.kill()
    assert sorted(p.name for p in tmp_path.iterdir()) == [live.name, "out"]


def test_bench_force_removes_a_killed_writers_leftovers_inside_its_folder(finished_bench, tmp_path, capsys):
    """A bench folder holding what killed writers left (a staging folder of its plots, a row half-written under
    its hidden name, a run's lock): simbench's, removed by --force."""
    out = tmp_path / "out"
    shutil.copytree(finished_bench, out)
    killed("staging folder", out / "plots")
    destination.mark_more(out, ["rows/extra.json"])  # as the bench claims a row before it writes it
    killed("staged file", out / "rows" / "extra.json")
    killed("lock", out / "runs" / "r9999")
    assert [name.split("-")[0] for name in _hidden(out)] == [".plots.partial", "rows/.extra.json.partial",
                                                             "runs/.r9999.lock"]
    assert main(BENCH + ["--out", str(out), "--force"]) == 0, capsys.readouterr().err
    assert _hidden(out) == [] and not (out / "runs").exists()


@pytest.mark.parametrize("force", [False, True], ids=["resumed", "forced"])
def test_a_sweep_whose_full_output_runs_were_killed_resumes_or_is_replaced(tmp_path, force):
    """Ctrl-C or SIGTERM ends a sweep's busy workers at once, mid-run: with outputs: full they leave their run's
    lock and staging folder in runs/ (`.r0001.lock`, `.r0001.partial-PID/...`). Those are simbench's own: the
    same command resumes over them, and --force replaces them, leaving none behind."""
    from simbench.commands.sweep import load_sweep, run_sweep

    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": "spherical_arm/case1", "outputs": "full",
                                    "grid": {"timing.duration": [2, 3]}}))
    sweep, out = load_sweep(path), tmp_path / "out"
    run_sweep(sweep, out, workers=1)
    gone = sweep.variants[1].id  # as a worker killed mid-run leaves it: no row, no folder, its leftovers
    (out / "rows" / f"{gone}.json").unlink()
    shutil.rmtree(out / "runs" / gone)
    for name in ("results.csv", "results.parquet", "summary.json", "index.html"):
        (out / name).unlink(missing_ok=True)
    killed("lock", out / "runs" / gone)
    killed("staging folder", out / "runs" / gone)
    result = run_sweep(sweep, out, workers=1, force=force)
    assert result.resumed == (0 if force else 1) and result.table["status"] == ["ok", "ok"]
    assert sorted(p.name for p in (out / "runs").iterdir()) == [v.id for v in sweep.variants]


# --- reproduce --out: a folder of its own ---------------------------------------------------------------------------

def test_reproduce_into_the_root_is_refused_before_anything_is_written(monkeypatch, capsys):
    """`--out /` would write /000 (and a lock and a staging folder beside it): refused in one line before the
    folder is locked (a lock taken here fails the test instead of writing into /)."""
    from simbench.commands import reproduce

    def never(out):
        raise AssertionError(f"would lock {out}")

    monkeypatch.setattr(reproduce.destination, "locked", never)
    assert main(["reproduce", "000", "--out", "/"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: /: ") and "pick another --out" in err[0], err


def test_reproduce_into_a_folder_of_other_things_is_refused(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("the user's own")
    assert main(["reproduce", "000", "--out", str(tmp_path), "--force"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "notes.txt" in err[0] and "pick another --out" in err[0], err
    assert [p.name for p in tmp_path.iterdir()] == ["notes.txt"]


# --- the switch named in the caller's words ------------------------------------------------------------------------

def test_a_refusal_names_force_as_the_caller_passes_it(finished_run, tmp_path):
    """From Python, `force=True`; on the command line (destination.command_line), `--force`."""
    out = tmp_path / "out"
    shutil.copytree(finished_run, out)
    with pytest.raises(ScenarioError) as api:
        simbench.run(CASE1, out=out, video=False)
    assert "pass force=True to replace it" in str(api.value) and "--force" not in str(api.value)
    with pytest.raises(ScenarioError) as cli, destination.command_line():
        simbench.run(CASE1, out=out, video=False)
    assert "pass --force to replace it, or --out to write elsewhere" in str(cli.value)
