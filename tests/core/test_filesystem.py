"""What the file system refuses (issue 11): an input simbench may not read, a destination it may not write, a disk
that fills up mid-run. Each ends with one line naming the path and saying the problem in words (simbench.core.errors),
no traceback; exit 2 before the run, 1 once outputs are being written; nothing half-written: no staging folder
or lock left beside the output, the previous output as it was, the input untouched.

The cases are generated: failure classes x commands. chmod does not stop root (or any process with
CAP_DAC_OVERRIDE), so there the chmod cases are skipped, and their emulated twins (the same errno raised where the
kernel would raise it) run in their place; as root, `capsh --drop=cap_dac_override,cap_dac_read_search -- -c
'pytest tests/core/test_filesystem.py'` runs them for real. A full disk is the kernel's own refusal, RLIMIT_FSIZE = 0
for the duration of one stage (EFBIG; SIGXFSZ ignored), or ENOSPC raised by the lowest write simbench calls for
that stage, after part of the file is written.
"""

import builtins
import contextlib
import errno
import json
import os
import resource
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
import yaml
from matplotlib.figure import Figure

import simbench
from simbench.cli import main
from simbench.commands import pipeline
from simbench.commands.sweep import store as sweep_store
from simbench.commands.sweep import table as sweep_table
from simbench.core import atomic, destination
from simbench.core.errors import (OutputError, PhysicsError, RunError, ScenarioError, name_max, os_words, printable,
                                  shown)
from simbench.outputs import report
from simbench.scenario import validation
from tests.conftest import scenario_file


def _chmod_binds() -> bool:
    """Whether chmod stops this process: not so for root (os.geteuid() == 0) or any process with
    CAP_DAC_OVERRIDE, so for root with those capabilities dropped."""
    with tempfile.TemporaryDirectory() as tmp:
        probe = Path(tmp) / "probe"
        probe.write_text("")
        probe.chmod(0)
        try:
            probe.open().close()
        except PermissionError:
            return True
        return False


needs_permissions = pytest.mark.skipif(not _chmod_binds(), reason=(
    f"running as {'root' if os.geteuid() == 0 else 'a user'} able to read a file of mode 000: chmod would not make "
    "the kernel refuse (the emulated twin of this case runs instead)"))
EFBIG_WORDS = os_words(OSError(errno.EFBIG, "File too large"))
ENOSPC_WORDS = "no space left on the device"
SWEEP_KEPT = "the rows of the finished runs are kept: run the same command again to resume"


# --- the user's folder and what is left in it ---------------------------------------------------------------------

@pytest.fixture
def ws(tmp_path, monkeypatch):
    """A user's working folder holding case1.yaml and sweep.yaml (two runs of it, nothing kept but rows)."""
    work = tmp_path / "work"
    work.mkdir()
    shutil.copy(scenario_file("spherical_arm", "case1"), work / "case1.yaml")
    (work / "sweep.yaml").write_text(yaml.safe_dump({"base": "case1.yaml", "outputs": "none",
                                                     "grid": {"timing.duration": [2, 3]}}))
    monkeypatch.chdir(work)
    yield work
    for path in [work, *work.rglob("*")]:  # what a case made unreadable, for pytest to remove
        if stat.S_ISDIR(os.lstat(path).st_mode):
            path.chmod(0o755)


def files(folder: Path) -> dict[str, bytes]:
    """Every file under `folder` (symlinks as their target's name), by path relative to it."""
    out = {}
    for path in sorted(folder.rglob("*")):
        mode = os.lstat(path).st_mode  # os.lstat: a case may refuse os.stat() of its path
        if stat.S_ISLNK(mode):
            out[str(path.relative_to(folder))] = os.readlink(path).encode()
        elif stat.S_ISREG(mode):
            try:
                out[str(path.relative_to(folder))] = path.read_bytes()
            except PermissionError:  # a case's unreadable input: its size and mode, then
                out[str(path.relative_to(folder))] = f"{os.lstat(path).st_size} {mode:o}".encode()
    return out


def leftovers(folder: Path) -> list[str]:
    """Staging folders, set-aside folders and lock files anywhere under `folder`."""
    return sorted(str(p) for p in folder.rglob(".*") if ".partial-" in p.name or ".old-" in p.name
                  or p.name.endswith(".lock"))


def call(args: list[str], capsys) -> tuple[int, list[str]]:
    """Exit code and stderr lines of the command; never a traceback, never an internal error."""
    code = main(args)
    err = capsys.readouterr().err
    assert "Traceback" not in err and "internal error" not in err, err
    return code, err.strip().splitlines()


# --- inputs: exit 2, one line naming the file -----------------------------------------------------------------------

def _unreadable(ws, chmod: bool):
    path = ws / "private.yaml"
    shutil.copy(ws / "case1.yaml", path)
    if chmod:
        path.chmod(0)
    return path, "permission denied: cannot read it"


def _in_unreadable_folder(ws, chmod: bool):
    (ws / "locked").mkdir()
    path = ws / "locked" / "case1.yaml"
    shutil.copy(ws / "case1.yaml", path)
    if chmod:
        (ws / "locked").chmod(0)
    return path, "permission denied: a folder on its path cannot be entered"


def _symlink_loop(ws):
    (ws / "a.yaml").symlink_to("b.yaml")
    (ws / "b.yaml").symlink_to("a.yaml")
    return ws / "a.yaml", "a symlink loop (too many levels of symbolic links)"


def _broken_symlink(ws):
    (ws / "gone.yaml").symlink_to("nowhere.yaml")
    return ws / "gone.yaml", "no such file (a symlink to a missing file)"


def _name_too_long(ws):
    name = "x" * 300 + ".yaml"
    return ws / name, f"name too long (305 characters; at most {name_max(ws)})"


def _file_in_the_way(ws):
    (ws / "notes").write_text("a file")
    return ws / "notes" / "case1.yaml", f"{ws / 'notes'} is a file, not a folder"


def _a_folder(ws):
    (ws / "folder.yaml").mkdir()
    return ws / "folder.yaml", "a folder, not a file (expected a YAML scenario)"


def _emulated(setup, owner, name, code):
    """The case with the kernel's refusal raised by owner.name for its path (chmod does not stop root)."""
    def make(ws, monkeypatch):
        path, words = setup(ws, chmod=False)
        real = getattr(owner, name, None) or getattr(builtins, name)  # a module's `open` is the built-in one
        monkeypatch.setattr(owner, name, _refuse(real, path, code), raising=False)
        return path, words
    return make


def _refuse(real, target, code):
    def fake(path, *args, **kwargs):
        if os.fspath(path) == os.fspath(target):
            raise OSError(code, os.strerror(code), os.fspath(path))
        return real(path, *args, **kwargs)
    return fake


INPUTS = {
    "unreadable file": (lambda ws, mp: _unreadable(ws, chmod=True), needs_permissions),
    "unreadable file (emulated EACCES)": (_emulated(_unreadable, validation, "open", errno.EACCES), None),
    "in an unreadable folder": (lambda ws, mp: _in_unreadable_folder(ws, chmod=True), needs_permissions),
    "in an unreadable folder (emulated EACCES)": (_emulated(_in_unreadable_folder, os, "stat", errno.EACCES), None),
    "symlink loop": (lambda ws, mp: _symlink_loop(ws), None),
    "broken symlink": (lambda ws, mp: _broken_symlink(ws), None),
    "name too long": (lambda ws, mp: _name_too_long(ws), None),
    "a file in the way": (lambda ws, mp: _file_in_the_way(ws), None),
    "a folder": (lambda ws, mp: _a_folder(ws), None),
}
INPUT_CASES = [pytest.param(name, command, id=f"{command}-{name}", marks=mark or ())
               for name, (_, mark) in INPUTS.items() for command in ("run", "validate", "sweep")]


@pytest.mark.parametrize("name, command", INPUT_CASES)
def test_an_input_the_file_system_refuses_is_one_line_and_exit_2(ws, monkeypatch, capsys, name, command):
    path, words = INPUTS[name][0](ws, monkeypatch)
    if command == "sweep":  # given as the sweep file (it is refused before it is read)
        args = ["sweep", str(path), "--out", str(ws / "out"), "--quiet", "--workers", "1"]
    elif command == "run":
        args = ["run", str(path), "--out", str(ws / "out"), "--no-video", "--quiet"]
    else:
        args = ["validate", str(path)]
    before = files(ws)
    code, lines = call(args, capsys)
    assert (code, lines) == (2, [f"error: {path}: {words}"])
    assert files(ws) == before and not (ws / "out").exists() and leftovers(ws) == []


# The sweep's base scenario refused: read_yaml's words (a symlink loop, a folder), or, where the sweep looks for
# its base and the kernel refuses even to look (os.stat), the kernel's.
BASES = {name: INPUTS[name] for name in ("unreadable file", "unreadable file (emulated EACCES)",
                                         "in an unreadable folder", "in an unreadable folder (emulated EACCES)",
                                         "name too long", "symlink loop", "a folder")}


@pytest.mark.parametrize("name", [pytest.param(name, marks=mark or ()) for name, (_, mark) in BASES.items()])
def test_a_sweep_whose_base_the_file_system_refuses_is_one_line_and_exit_2(ws, monkeypatch, capsys, name):
    path, words = BASES[name][0](ws, monkeypatch)
    sweep = ws / "bad_base.yaml"
    sweep.write_text(yaml.safe_dump({"base": str(path.relative_to(ws)), "grid": {"timing.duration": [2, 3]}}))
    before = files(ws)
    code, lines = call(["sweep", str(sweep), "--out", str(ws / "out"), "--quiet"], capsys)
    assert code == 2 and len(lines) == 1
    if name.startswith("in an unreadable folder"):  # refused while looking for the base
        assert lines == [f"error: {path}: permission denied"]
    else:
        assert lines == [f"error: {path}: {words}"]
    assert files(ws) == before and not (ws / "out").exists()


# --- destinations: exit 2 before anything runs, nothing created -----------------------------------------------------

def _dest_parent_is_a_file(ws):
    (ws / "notes").write_text("a file")
    out = ws / "notes" / "out"
    return out, f"cannot write the output folder: {ws / 'notes'} is a file, not a folder; pick another --out"


def _dest_is_a_file(ws):
    (ws / "notes").write_text("a file")
    return ws / "notes", "is a file, not a folder; pick another --out"


def _dest_name_too_long(ws):
    limit = name_max(ws) - destination._HIDDEN
    return ws / ("o" * 300), (f"name too long (300 characters; at most {limit} for an output folder, which simbench "
                              "first writes under a longer hidden name); pick another --out")


def _dest_symlink_loop(ws):
    (ws / "o1").symlink_to("o2")
    (ws / "o2").symlink_to("o1")
    return ws / "o1", "a symlink loop (too many levels of symbolic links); pick another --out"


def _dest_broken_symlink(ws):
    (ws / "o1").symlink_to("nowhere")
    return ws / "o1", "a broken symlink (it points to nothing); pick another --out"


def _dest_read_only_parent(ws, monkeypatch=None, code=None):
    (ws / "shelf").mkdir()
    out = ws / "shelf" / "out"
    if monkeypatch is None:
        (ws / "shelf").chmod(0o555)
    else:
        monkeypatch.setattr(os, "open", _refuse(os.open, ws / "shelf" / ".out.lock", code))
    words = os_words(OSError(code or errno.EACCES, ""))
    return out, f"cannot write the output folder: {words} ({ws / 'shelf'}); pick another --out"


def _dest_read_only_working_folder(ws, monkeypatch=None):
    """No --out: the default renders/<name> under the working folder."""
    if monkeypatch is None:
        ws.chmod(0o555)
    else:
        monkeypatch.setattr(os, "mkdir", _refuse(os.mkdir, "renders", errno.EACCES))
    return None, "cannot write the output folder: permission denied (renders); pick another --out"


def _dest_unreadable(ws, monkeypatch=None):
    """An earlier output folder this process may not list (--force would replace it)."""
    out = ws / "out"
    out.mkdir()
    (out / "report.json").write_text("{}")
    if monkeypatch is None:
        out.chmod(0)
    else:
        monkeypatch.setattr(os, "listdir", _refuse(os.listdir, out, errno.EACCES))
    return out, "cannot write the output folder: permission denied; pick another --out"


DESTINATIONS = {
    "parent is a file": (lambda ws, mp: _dest_parent_is_a_file(ws), None),
    "is a file": (lambda ws, mp: _dest_is_a_file(ws), None),
    "name too long": (lambda ws, mp: _dest_name_too_long(ws), None),
    "symlink loop": (lambda ws, mp: _dest_symlink_loop(ws), None),
    "broken symlink": (lambda ws, mp: _dest_broken_symlink(ws), None),
    "read-only parent": (lambda ws, mp: _dest_read_only_parent(ws), needs_permissions),
    "read-only parent (emulated EACCES)": (lambda ws, mp: _dest_read_only_parent(ws, mp, errno.EACCES), None),
    "read-only file system (emulated EROFS)": (lambda ws, mp: _dest_read_only_parent(ws, mp, errno.EROFS), None),
    "unreadable": (lambda ws, mp: _dest_unreadable(ws), needs_permissions),
    "unreadable (emulated EACCES)": (lambda ws, mp: _dest_unreadable(ws, mp), None),
    "read-only working folder": (lambda ws, mp: _dest_read_only_working_folder(ws), needs_permissions),
    "read-only working folder (emulated EACCES)": (lambda ws, mp: _dest_read_only_working_folder(ws, mp), None),
}
DESTINATION_CASES = [pytest.param(name, command, id=f"{command}-{name}", marks=mark or ())
                     for name, (_, mark) in DESTINATIONS.items() for command in ("run", "sweep")]


@pytest.mark.parametrize("name, command", DESTINATION_CASES)
def test_a_destination_the_file_system_refuses_is_one_line_and_exit_2(ws, monkeypatch, capsys, name, command):
    out, words = DESTINATIONS[name][0](ws, monkeypatch)
    if out is None:  # the default output folder
        out = Path("renders") / ("case1" if command == "run" else "sweeps/sweep")
        where = []
    else:
        where = ["--out", str(out)]
    args = (["run", "case1.yaml", "--no-video"] if command == "run" else ["sweep", "sweep.yaml", "--workers", "1"])
    before = files(ws)
    code, lines = call([*args, *where, "--quiet"], capsys)
    if name == "name too long" and lines != [f"error: {out}: {words}"]:
        # Refused by whatever looks at the folder first (the run's disk budget, say): the kernel's own limit.
        assert (code, lines) == (2, [f"error: {out}: name too long (300 characters; at most {name_max(ws)})"])
    else:
        assert (code, lines) == (2, [f"error: {out}: {words}"])
    assert files(ws) == before and leftovers(ws) == []


# --- a full disk while writing the outputs: exit 1, nothing half-written --------------------------------------------

@contextlib.contextmanager
def _file_size_limit(size: int = 0):
    """The kernel refuses every write to a regular file beyond `size` bytes (EFBIG) while the block runs, in this
    process and in those it starts (RLIMIT_FSIZE; SIGXFSZ ignored)."""
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    handler = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (size, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, handler)


def _partial_then_enospc(target_of):
    """A write function that writes the start of its file, then finds the disk full (as write(2) would)."""
    def fake(*args, **kwargs):
        target = target_of(args)
        if hasattr(target, "write"):
            target.write(b"PK\x03\x04 half a file")
        else:
            Path(target).write_bytes(b"half a file")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    return fake


@contextlib.contextmanager
def _enospc(primitive):
    """The lowest write simbench calls for a stage (owner, name, which argument is the file) writes part of its
    file, then meets ENOSPC."""
    owner, name, target_of = primitive
    real = getattr(owner, name)
    setattr(owner, name, _partial_then_enospc(target_of))
    try:
        yield
    finally:
        setattr(owner, name, real)


def during(monkeypatch, owner, name: str, fault):
    """owner.name with `fault()` active for the length of each call."""
    real = getattr(owner, name)

    def wrapped(*args, **kwargs):
        with fault():
            return real(*args, **kwargs)

    monkeypatch.setattr(owner, name, wrapped)


def _quick_plots(robot, traj, rec, result, folder, plot_format="png"):
    """write_plots' stand-in where plots are not the stage under test (not the stage under test)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "joints.png").write_bytes(b"\x89PNG stand-in")
    return ["joints.png"]


# stage: (where its fault goes, the lowest write it calls, the path the line names relative to out or "")
SAVE_PNG = (Figure, "savefig", lambda args: args[1])  # (figure, file name)
SAVEZ = (report, "savez_fast", lambda args: args[0])  # (open file, arrays)
WRITE_TEXT = (Path, "write_text", lambda args: args[0])  # (path, text)
RUN_STAGES = {
    "plots": ((pipeline, "write_plots"), SAVE_PNG, ""),
    "timeseries": ((pipeline, "write_timeseries"), SAVEZ, "timeseries.npz"),
    "report": ((pipeline, "write_report"), WRITE_TEXT, "report.json"),
    "marker": ((atomic, "mark"), WRITE_TEXT, ""),
}
FAULTS = {"EFBIG": (lambda primitive: _file_size_limit, EFBIG_WORDS),
          "ENOSPC": (lambda primitive: (lambda: _enospc(primitive)), ENOSPC_WORDS)}


@pytest.fixture(scope="module")
def previous(tmp_path_factory):
    """A complete earlier output of case1 (plots stood in for), to be replaced with --force."""
    out = tmp_path_factory.mktemp("previous") / "out"
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(pipeline, "write_plots", _quick_plots)
        assert main(["run", str(scenario_file("spherical_arm", "case1")), "--out", str(out), "--no-video",
                     "--quiet"]) == 0
    return out


@pytest.mark.parametrize("fault", FAULTS)
@pytest.mark.parametrize("stage", RUN_STAGES)
@pytest.mark.parametrize("earlier", ["none", "kept"], ids=["no earlier output", "earlier output"])
def test_a_full_disk_while_a_run_writes_is_one_line_and_exit_1(ws, monkeypatch, capsys, previous, stage, fault,
                                                              earlier):
    (owner, name), primitive, named = RUN_STAGES[stage]
    make_fault, words = FAULTS[fault]
    out = ws / "out"
    if earlier == "kept":
        shutil.copytree(previous, out)
    if stage != "plots":
        monkeypatch.setattr(pipeline, "write_plots", _quick_plots)
    during(monkeypatch, owner, name, make_fault(primitive))
    before = files(ws)
    code, lines = call(["run", "case1.yaml", "--out", str(out), "--no-video", "--quiet", "--force"], capsys)
    kept = f"the previous {out} is kept" if earlier == "kept" else f"nothing was written to {out}"
    assert (code, lines) == (1, [f"error: {out / named if named else out}: {words} (while writing the outputs; "
                                 f"{kept})"])
    assert files(ws) == before and leftovers(ws) == []  # the earlier output as it was, or none


def test_a_full_disk_while_the_video_is_encoded_is_one_line_and_exit_1(ws, monkeypatch, capsys, previous):
    out = ws / "out"
    shutil.copytree(previous, out)
    doc = yaml.safe_load((ws / "case1.yaml").read_text())
    doc["render"] = {"width": 160, "height": 120, "fps": 10}
    (ws / "case1.yaml").write_text(yaml.safe_dump(doc))
    monkeypatch.setattr(pipeline, "write_plots", _quick_plots)
    during(monkeypatch, pipeline, "render_video", lambda: _file_size_limit(2000))  # ffmpeg inherits the limit
    before = files(ws)
    code, lines = call(["run", "case1.yaml", "--out", str(out), "--quiet", "--force"], capsys)
    assert (code, lines) == (1, [f"error: {out / 'video.mp4'}: {EFBIG_WORDS} (while writing the outputs; the "
                                 f"previous {out} is kept)"])
    assert files(ws) == before and leftovers(ws) == []


def test_the_real_command_line_under_a_file_size_limit_prints_one_line(ws):
    """The whole process (and what it starts) under RLIMIT_FSIZE: the timeseries, the run's first write while its
    plots are drawn beside it, is refused."""
    script = ("import resource, signal, sys; signal.signal(signal.SIGXFSZ, signal.SIG_IGN); "
              "resource.setrlimit(resource.RLIMIT_FSIZE, (1000, resource.getrlimit(resource.RLIMIT_FSIZE)[1])); "
              "from simbench.cli import main; sys.exit(main(sys.argv[1:]))")
    before = files(ws)
    proc = subprocess.run([sys.executable, "-c", script, "run", "case1.yaml", "--out", "out", "--no-video"],
                          capture_output=True, text=True, cwd=ws, timeout=120)
    assert proc.returncode == 1 and proc.stdout == "" and "Traceback" not in proc.stderr
    assert proc.stderr.splitlines() == [f"error: out/timeseries.npz: {EFBIG_WORDS} (while writing the outputs; "
                                        "nothing was written to out)"]
    assert files(ws) == before and leftovers(ws) == []


SWEEP_STAGES = {  # stage: (where its fault goes, the lowest write it calls, the path the line names)
    "folder": ((sweep_store.Store, "_prepare"), WRITE_TEXT, "sweep.json"),
    "row": ((sweep_store.Store, "record"), WRITE_TEXT, "rows/r0000.json"),
    "table": ((sweep_table, "write_csv"), WRITE_TEXT, "results.csv"),
}


@pytest.mark.parametrize("fault", FAULTS)
@pytest.mark.parametrize("stage", SWEEP_STAGES)
def test_a_full_disk_while_a_sweep_writes_is_one_line_exit_1_and_resumes(ws, monkeypatch, capsys, stage, fault):
    (owner, name), primitive, named = SWEEP_STAGES[stage]
    make_fault, words = FAULTS[fault]
    out = ws / "out"
    args = ["sweep", "sweep.yaml", "--out", str(out), "--workers", "1", "--quiet"]
    with monkeypatch.context() as patch:
        during(patch, owner, name, make_fault(primitive))
        code, lines = call(args, capsys)
    kept = f"nothing was written to {out}" if stage == "folder" else SWEEP_KEPT
    assert (code, lines) == (1, [f"error: {out / named}: {words} (while writing the outputs; {kept})"])
    assert leftovers(ws) == []
    if stage == "folder":
        assert not out.exists()
    else:  # what is there is whole: the manifest, and the rows of the runs that finished
        assert json.loads((out / "sweep.json").read_text())["name"] == "sweep"
        assert all(json.loads(p.read_text())["status"] == "ok" for p in (out / "rows").glob("*.json"))
    assert call(args, capsys) == (0, [])  # the same command finishes the sweep
    assert len((out / "results.csv").read_text().splitlines()) == 3


def test_the_python_api_raises_the_same_errors(ws, monkeypatch):
    """simbench.run: ScenarioError for a destination refused before the run, OutputError (a RunError) for a
    full disk while writing."""
    scenario = simbench.load_scenario(ws / "case1.yaml")
    (ws / "notes").write_text("a file")
    with pytest.raises(ScenarioError, match="is a file, not a folder"):
        simbench.run(scenario, out=ws / "notes" / "out", video=False)
    monkeypatch.setattr(pipeline, "write_plots", _quick_plots)
    during(monkeypatch, pipeline, "write_report", _file_size_limit)
    with pytest.raises(OutputError) as caught:
        simbench.run(scenario, out=ws / "out", video=False)
    assert isinstance(caught.value, RunError) and caught.value.path == str(ws / "out" / "report.json")
    assert not (ws / "out").exists() and leftovers(ws) == []


# --- physics that fails: the line says where the report is --------------------------------------------------------

def _fails_while_settling(monkeypatch):
    """The simulation failing before the first tracked sample, as diverged physics while settling does."""
    def simulate(plant, trajectory, *args, **kwargs):
        raise PhysicsError(-0.0125, "joint 'q1' diverging", trajectory, None)
    monkeypatch.setattr(pipeline, "simulate", simulate)


def test_physics_failing_while_settling_says_where_the_report_is(ws, monkeypatch, capsys):
    _fails_while_settling(monkeypatch)
    code, lines = call(["run", "case1.yaml", "--quiet"], capsys)
    out = Path("renders") / "case1"
    assert (code, lines) == (1, ["run failed: physics failed while settling at the start pose (0.0125 s before the "
                                 f"start): joint 'q1' diverging; the report is in {out}"])
    assert json.loads((ws / out / "report.json").read_text())["status"] == "failed"
    assert leftovers(ws) == []


def test_a_full_disk_while_writing_a_failed_runs_report_is_one_line_and_exit_1(ws, monkeypatch, capsys):
    _fails_while_settling(monkeypatch)
    during(monkeypatch, pipeline, "write_report", _file_size_limit)
    code, lines = call(["run", "case1.yaml", "--out", "out", "--quiet"], capsys)
    assert (code, lines) == (1, [f"error: out/report.json: {EFBIG_WORDS} (while writing the outputs; nothing was "
                                 "written to out)"])
    assert not (ws / "out").exists() and leftovers(ws) == []


# --- the words themselves ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("code, words", [
    (errno.EACCES, "permission denied"), (errno.EROFS, "read-only file system"),
    (errno.ENOSPC, "no space left on the device"), (errno.EFBIG, "no space"), (errno.EDQUOT, "no space left"),
    (errno.ELOOP, "a symlink loop"), (errno.ENAMETOOLONG, "name too long"), (errno.ENOTDIR, "not a folder"),
    (errno.EIO, "input/output error"), (errno.ENOENT, "no such file"), (errno.EXDEV, "on another file system"),
])
def test_every_errno_has_its_words(tmp_path, code, words):
    (tmp_path / "notes").write_text("a file")
    assert words in os_words(OSError(code, os.strerror(code), str(tmp_path / "notes" / ("n" * 300))))


def test_an_errno_without_words_says_the_systems_own_in_one_line():
    """os.strerror's words, in lower case, whatever text the error came with (none, or two lines)."""
    assert os_words(OSError(errno.ETIMEDOUT, "Connection timed out\nsecond line")) == "connection timed out"
    assert os_words(OSError(errno.EBUSY, "")) == os.strerror(errno.EBUSY).lower()  # "device or resource busy"
    assert os_words(OSError(errno.EISDIR, "whatever a library said")) == os.strerror(errno.EISDIR).lower()


def test_an_integer_too_long_to_write_out_never_breaks_an_error_message():
    huge = int("f" * 4000, 16)  # about 4800 decimal digits: str() and repr() refuse it
    with pytest.raises(ValueError):
        repr(huge)
    assert shown(huge) == "an integer of about 4817 digits" and shown(-huge).startswith("-an integer")
    assert printable([huge]) == "a list too large to show"
    assert len(shown("t" * 1000)) == 200
    err = ScenarioError("s.yaml", "timing.duration", f"got {shown(huge)}")
    assert str(err) == "s.yaml: timing.duration: got an integer of about 4817 digits"


@pytest.mark.parametrize("text, expected", [
    ("timing:\n  duration: " + "1" * 5000 + "\n", "line 2, column 13: an integer of 5000 digits is too long (at "
                                                  "most 4300)"),
    ("timing:\n  duration: 0x" + "f" * 3800 + "\n", "line 2, column 13: an integer of about 4576 digits is too "
                                                    "long (at most 4300)"),
    ("timing: &t {law: quintic}\nother:\n  <<: *t\n", "line 3, column 3: YAML merge keys (<<) are not supported: "
                                                      "write the fields out"),
    ("robot: <<\n", "line 1, column 8: '<<' is YAML's merge key: write it in quotes ('<<') to mean the text"),
    ("? [a, b]\n: 1\n", "line 1, column 3: a list as a key is not supported: keys are field names"),
    ("? {a: 1}\n: 1\n", "line 1, column 3: a mapping as a key is not supported: keys are field names"),
    ("timing:\n  duration: 2024-13-45\n", "line 2, column 13: cannot read this timestamp: month must be in 1..12"),
])
def test_yaml_that_python_cannot_build_is_one_line_naming_line_and_column(tmp_path, capsys, text, expected):
    path = tmp_path / "s.yaml"
    path.write_text(text)
    for command in (["validate", str(path)], ["sweep", str(path), "--dry-run"]):
        assert call(command, capsys) == (2, [f"error: {path}: {expected}"])


def test_a_long_hexadecimal_integer_is_shown_cut_short(tmp_path, capsys):
    """Short enough to be read (3500 hex digits), too long to be shown whole."""
    path = tmp_path / "s.yaml"
    doc = yaml.safe_load(scenario_file("spherical_arm", "case1").read_text())
    path.write_text(yaml.safe_dump(doc).replace("duration: 4", "duration: 0x" + "f" * 3500))
    code, lines = call(["validate", str(path)], capsys)
    assert code == 2 and len(lines) == 1 and lines[0].endswith("...") and len(lines[0]) < 400
