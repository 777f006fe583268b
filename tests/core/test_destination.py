"""No data loss (issue 11): simbench never writes over its input, the working folder or a file it did not write,
whatever --force says; one writer at a time; nothing left behind by a writer stopped by a signal; sweep workers
die with their parent. What a killed writer leaves, and what --force removes of it:
tests/core/test_force_leftovers.py."""

import shutil
import signal
import subprocess
import sys
import time

import pytest
import yaml

from simbench.cli import main
from simbench.core.destination import LOCK_TOKEN, locked
from tests.conftest import interrupt, scenario_file


def _workspace(tmp_path, monkeypatch):
    """A user's folder: work/scenarios/case1.yaml, the working folder work/."""
    work = tmp_path / "work"
    (work / "scenarios").mkdir(parents=True)
    scenario = work / "scenarios" / "case1.yaml"
    shutil.copy(scenario_file("spherical_arm", "case1"), scenario)
    monkeypatch.chdir(work)
    return work, scenario


@pytest.mark.parametrize("where", ["the scenario's folder", "the working folder", "an ancestor of both",
                                   "the scenario file itself", "a file"])
def test_force_never_replaces_the_input_the_working_folder_or_a_file(tmp_path, monkeypatch, capsys, where):
    work, scenario = _workspace(tmp_path, monkeypatch)
    (work / "data.csv").write_text("the user's data")
    out = {"the scenario's folder": scenario.parent, "the working folder": work, "an ancestor of both": tmp_path,
           "the scenario file itself": scenario, "a file": work / "data.csv"}[where]
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    assert main(["run", str(scenario), "--out", str(out), "--no-video", "--quiet", "--force"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {out}: ") and "pick another --out" in err[0]
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before  # nothing touched


def test_a_sweep_never_replaces_the_folder_holding_its_file(tmp_path, monkeypatch, capsys):
    work, scenario = _workspace(tmp_path, monkeypatch)
    sweep = work / "scenarios" / "sweep.yaml"
    sweep.write_text(yaml.safe_dump({"base": "case1.yaml", "grid": {"timing.duration": [2, 3]}}))
    assert main(["sweep", str(sweep), "--out", str(sweep.parent), "--force", "--quiet"]) == 2
    assert "holds the input" in capsys.readouterr().err
    assert sweep.exists() and scenario.exists()


def test_a_second_writer_is_refused_while_the_first_holds_the_folder(tmp_path, capsys):
    out = tmp_path / "out"
    with locked(out):
        assert main(["run", str(scenario_file("spherical_arm", "case1")), "--out", str(out), "--no-video",
                     "--quiet"]) == 2
    assert "another simbench run or sweep is writing into this folder" in capsys.readouterr().err
    assert not out.exists()


def test_sigterm_during_the_video_cleans_up_as_ctrl_c_does(tmp_path):
    out = tmp_path / "out"
    command = [sys.executable, "-m", "simbench", "run", str(scenario_file("spherical_arm", "case1")), "--out",
               str(out), "--quiet"]
    stopped = interrupt(command, lambda: any(tmp_path.glob(".out.partial-*/plots/*.png")), tmp_path,
                        signum=signal.SIGTERM)
    assert stopped.returncode == 128 + signal.SIGTERM and stopped.stderr.strip() == "interrupted"
    assert list(tmp_path.iterdir()) == []  # no output, no staging folder, no lock


@pytest.mark.parametrize("signum", [signal.SIGKILL, signal.SIGTERM], ids=["SIGKILL", "SIGTERM"])
def test_a_killed_sweeps_workers_die_with_it_and_it_resumes_without_losing_a_row(tmp_path, signum):
    spec = {"base": "spherical_arm/case1", "outputs": "none",
            "random": {"samples": 12, "seed": 4, "params": {"timing.duration": {"uniform": [2, 4]}}}}
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump(spec))
    out = tmp_path / "out"
    command = [sys.executable, "-m", "simbench", "sweep", str(path), "--out", str(out), "--workers", "2", "--quiet"]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while len(list((out / "rows").glob("*.json"))) < 2:
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.01)
    workers = [int(p) for p in subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True,
                                              text=True).stdout.split()]
    assert workers
    proc.send_signal(signum)
    proc.communicate(timeout=60)
    assert proc.returncode in (-signal.SIGKILL, 128 + signal.SIGTERM)
    deadline = time.monotonic() + 5
    while any(_running(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_running(pid) for pid in workers)  # no orphan after 5 s
    done = {p.name for p in (out / "rows").glob("*.json")}
    finished = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert finished.returncode == 0, finished.stderr
    with open(out / "results.csv") as f:
        ids = [line.split(",")[1] for line in f.read().splitlines()[1:]]
    assert len(ids) == len(set(ids)) == 12 and done <= {p.name for p in (out / "rows").glob("*.json")}


def _running(pid: int) -> bool:
    """Whether the process exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


# --- issue 33: the marker lists files, not folders; the lock file never follows a symlink ---------------------------

def _small_sweep(work, outputs="report"):
    sweep = work / "scenarios" / "sweep.yaml"
    doc = {"base": "case1.yaml", "grid": {"timing.duration": [2, 3]}, "outputs": outputs, "plots": ["tool_rms"]}
    sweep.write_text(yaml.safe_dump(doc))
    return sweep


def _marked(folder) -> set:
    """Every file some marker on its way down lists (the markers read here line by line, as JSON)."""
    import json

    listed = set()
    for marker in folder.rglob(".simbench"):
        for line in marker.read_text().splitlines():
            listed |= {(marker.parent / name).relative_to(folder).as_posix() for name in json.loads(line)["files"]}
    return listed


@pytest.mark.parametrize("outputs", ["report", "full"])
def test_a_sweeps_markers_list_every_file_it_wrote_at_every_depth(tmp_path, monkeypatch, outputs):
    work, _ = _workspace(tmp_path, monkeypatch)
    out = work / "out"
    assert main(["sweep", str(_small_sweep(work, outputs)), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    on_disk = {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file() and p.name != ".simbench"}
    assert {"rows/r0000.json", "results.csv", "index.html"} <= on_disk
    assert any(name.startswith("plots/") for name in on_disk)
    assert on_disk <= _marked(out)


@pytest.mark.parametrize("inside", ["plots", "runs", "rows", "runs/r0000"])
@pytest.mark.parametrize("force", [False, True], ids=["resume", "force"])
def test_a_sweep_run_again_never_removes_a_users_file_inside_its_folder(tmp_path, monkeypatch, capsys, inside,
                                                                          force):
    work, _ = _workspace(tmp_path, monkeypatch)
    out = work / "out"
    args = ["sweep", str(_small_sweep(work)), "--out", str(out), "--workers", "1", "--quiet"]
    assert main(args) == 0
    mine = out / inside / "my_notes.txt"
    mine.parent.mkdir(parents=True, exist_ok=True)
    mine.write_text("the user's notes")
    capsys.readouterr()
    assert main(args + ["--force"] * force) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{inside}/my_notes.txt" in err[0] and "simbench did not write" in err[0]
    assert mine.read_text() == "the user's notes"


def test_force_replaces_a_folder_whose_marker_lists_a_folder_by_name_only_if_it_holds_nothing_else(tmp_path,
                                                                                                     capsys):
    """The marker of earlier versions listed a sweep's folders by name: a name accounts for itself only."""
    out = tmp_path / "out"
    (out / "plots").mkdir(parents=True)
    (out / "plots" / "mine.png").write_bytes(b"the user's figure")
    (out / ".simbench").write_text('{"written_by": "simbench", "files": ["plots"]}\n')
    assert main(["run", str(scenario_file("spherical_arm", "case1")), "--out", str(out), "--no-video", "--quiet",
                 "--force"]) == 2
    assert "plots/mine.png" in capsys.readouterr().err
    assert (out / "plots" / "mine.png").read_bytes() == b"the user's figure"


@pytest.mark.parametrize("there", [True, False])
def test_the_lock_file_never_follows_a_symlink(tmp_path, capsys, there):
    """A symlink where the lock file goes, to the user's file or to a name not yet taken: refused in one line,
    the file untouched, nothing created at the link's target."""
    victim = tmp_path / "victim.txt"
    if there:
        victim.write_text("the user's file")
    (tmp_path / ".out.lock").symlink_to(victim)
    out = tmp_path / "out"
    assert main(["run", str(scenario_file("spherical_arm", "case1")), "--out", str(out), "--no-video",
                 "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and ".out.lock" in err[0] and "symlink" in err[0]
    assert (victim.read_text() == "the user's file" if there else not victim.exists()) and not out.exists()


@pytest.mark.parametrize("content", [b"", b"my notes\n"])
def test_a_users_file_where_the_lock_goes_is_refused_and_kept(tmp_path, capsys, content):
    """A file of the user's named as simbench's lock would be (`.out.lock`, empty or not): refused in one line
    naming it, the file as it was (the lock, removed when a write ends, took it with it); a lock simbench's killed
    writer left (its token, no holder) is taken and removed as before."""
    mine = tmp_path / ".out.lock"
    mine.write_bytes(content)
    out, case1 = tmp_path / "out", str(scenario_file("spherical_arm", "case1"))
    assert main(["run", case1, "--out", str(out), "--no-video", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and ".out.lock: is a file simbench did not write" in err[0]
    assert mine.read_bytes() == content and not out.exists()
    mine.write_bytes(LOCK_TOKEN)
    assert main(["run", case1, "--out", str(out), "--no-video", "--quiet"]) == 0
    assert not mine.exists() and (out / "report.json").is_file()


def test_force_never_replaces_a_folder_of_other_runs_outputs(tmp_path, capsys):
    """A folder holding simbench's outputs in subfolders (renders/ itself, say) was not written by simbench: it
    has no marker of its own. --force into it is refused, naming a file, and the runs in it are kept."""
    case1 = str(scenario_file("spherical_arm", "case1"))
    for name in ("a", "b"):
        assert main(["run", case1, "--out", str(tmp_path / "renders" / name), "--no-video", "--quiet"]) == 0
    before = {p: p.read_bytes() for p in (tmp_path / "renders").rglob("*") if p.is_file()}
    assert main(["run", case1, "--out", str(tmp_path / "renders"), "--no-video", "--quiet", "--force"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {tmp_path / 'renders'}: ") and "a/" in err[0], err
    assert {p: p.read_bytes() for p in (tmp_path / "renders").rglob("*") if p.is_file()} == before
