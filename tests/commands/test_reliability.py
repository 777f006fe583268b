"""Faults and interruptions: a run whose physics fails stops at the first sign, says when and why, exits 1 and
keeps what it recorded; Ctrl-C leaves the previous complete output or none; every shipped scenario is
bit-for-bit deterministic."""

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import mujoco
import numpy as np
import psutil
import pytest
import yaml

import simbench
from simbench.cli import main
from simbench.core import plant as plants
from simbench.core.errors import PhysicsError
from simbench.core.faults import MAX_SPEED
from simbench.physics import sim, switches
from tests.conftest import interrupt, scenario_file


def stiff_puma(tmp_path) -> Path:
    """The PUMA's line with q3's servo 1000 times stiffer and no force limits: explicit integration of a spring
    that stiff at 1 ms diverges."""
    doc = yaml.safe_load(scenario_file("puma600", "line").read_text())
    doc["sim"] = {"force_limits": False, "kp": [8000, 12000, 5.0e6, 800, 800, 600]}
    path = tmp_path / "stiff.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_diverging_run_stops_at_the_first_sign_and_keeps_its_timeseries(tmp_path, capsys):
    path, out = stiff_puma(tmp_path), tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    report = json.loads((out / "report.json").read_text())
    failure = report["failure"]
    assert report["status"] == "failed" and failure["stage"] == "simulate"
    assert err == [f"run failed: physics failed at t = {failure['t']:.4f} s: {failure['cause']}; the report and "
                   f"the timeseries up to then are in {out}"]
    assert "joint 'q3'" in failure["cause"] and "diverging" in failure["cause"]
    # no video
    assert sorted(p.name for p in out.iterdir()) == [".simbench", "index.html", "report.json", "timeseries.npz"]
    ts = np.load(out / "timeseries.npz")
    n = ts["t"].size
    assert n == report["samples"] > 10 and np.isclose(ts["t"][-1] + report["timestep"], failure["t"])
    assert ts["q_ref"].shape[0] == ts["q"].shape[0] == n
    # Every kept sample is sound, and one plain mj_step from the last of them is not: the run stopped at the
    # first sign, neither before nor after.
    assert np.isfinite(ts["qpos"]).all() and np.abs(ts["qd"]).max() <= MAX_SPEED
    sc = simbench.load_scenario(path)
    plant = plants.Plant.load(sc.robot_def, sc.sim.timestep, sc.sim.kp, sc.sim.kv, sc.sim.force_limits)
    data = mujoco.MjData(plant.model)
    data.qpos[:] = ts["qpos"][-1]
    data.qvel[plant.dof_adr] = ts["qd"][-1]
    data.ctrl[:] = ts["ctrl"][-1]
    mujoco.mj_step(plant.model, data)
    assert np.abs(data.qvel).max() > MAX_SPEED


def test_nan_state_mid_run_is_named_and_the_run_kept_up_to_it(monkeypatch):
    """NaN speeds injected into the RSMG at its third switch: MuJoCo's bad-velocity warning names the time of
    that switch, and the recording stops there."""
    scenario = simbench.load_scenario(scenario_file("rsmg", "three_turns"))
    calls = []
    real = switches.apply_switch

    def poisoned(model, data, switch):
        real(model, data, switch)
        calls.append(switch.t)
        if len(calls) == 3 + 4:  # the four grips at t = 0 come first
            data.qvel[:] = np.nan

    monkeypatch.setattr(switches, "apply_switch", poisoned)  # the grips at the start (switches.at_start)
    monkeypatch.setattr(sim, "apply_switch", poisoned)  # and those during the run
    with pytest.raises(PhysicsError) as caught:
        simbench.evaluate(scenario)
    err, t_switch = caught.value, calls[-1]
    assert "velocity NaN, infinite or huge" in err.cause and "mjWARN_BADQVEL" in err.cause
    dt = err.recording.timestep
    assert np.isclose(err.t, t_switch + dt) and np.isclose(err.recording.t[-1], t_switch)
    assert np.isfinite(err.recording.qpos).all()


def _scene_with_memory(monkeypatch, memory: int) -> None:
    """Compile every scene with an arena of `memory` bytes (MuJoCo's <size memory>), to overflow it."""
    def compiled(scene: str) -> mujoco.MjModel:
        spec = plants.scene_spec(scene)
        spec.memory = memory
        return spec.compile()

    monkeypatch.setattr(plants, "compiled_scene", compiled)


@pytest.mark.parametrize("memory, expected", [(3000, "the constraint buffer is full (the model's <size memory> is "
                                                      "too small) (mjWARN_CNSTRFULL)"),
                                              (12000, "MuJoCo stopped: mj_stackAlloc: out of memory")])
def test_overflowing_mujocos_memory_is_reported(monkeypatch, memory, expected):
    _scene_with_memory(monkeypatch, memory)
    with pytest.raises(PhysicsError, match="physics failed while settling") as caught:
        simbench.evaluate(simbench.load_scenario(scenario_file("rsmg", "three_turns")))
    assert expected in caught.value.cause and caught.value.recording is None


def test_a_fault_prints_one_line_and_leaves_no_mujoco_log(tmp_path):
    """MuJoCo would print its warning and append it to MUJOCO_LOG.TXT in the working folder."""
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "simbench", "run", str(stiff_puma(tmp_path)), "--out", str(out)],
                          capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 1 and proc.stderr.count("\n") == 1 and proc.stderr.startswith("run failed: ")
    assert "Traceback" not in proc.stderr and "WARNING" not in proc.stdout + proc.stderr
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def _importing_mujoco() -> bool:
    """Whether a child of this process has MuJoCo's shared library mapped (it is importing MuJoCo, or past it)."""
    for child in psutil.Process().children():
        try:
            if any("libmujoco" in Path(m.path).name for m in child.memory_maps(grouped=True)):
                return True
        except psutil.Error:  # ended, or not yet readable
            continue
    return False


def test_ctrl_c_while_the_command_line_is_read_is_interrupted_not_a_traceback(monkeypatch, capsys):
    """Ctrl-C in the first moments, while argparse reads the command line, ends as any other press: one line,
    exit 130 (it used to escape main as a KeyboardInterrupt traceback)."""
    import simbench.cli as cli

    parser = cli._parser()

    def pressed(argv):
        signal.raise_signal(signal.SIGINT)
        return parser.parse_args(argv)

    monkeypatch.setattr(cli, "_parser", lambda: type("P", (), {"parse_args": staticmethod(pressed)})())
    assert main(["list"]) == 130
    assert capsys.readouterr().err == "interrupted\n"


def test_ctrl_c_leaves_the_previous_output_or_none(tmp_path):
    out = tmp_path / "demo"
    command = [sys.executable, "-m", "simbench", "run", str(scenario_file("spherical_arm", "demo")), "--out",
               str(out), "--quiet"]
    staging = lambda: list(tmp_path.glob(".demo.partial-*"))  # noqa: E731 - the outputs are being written
    # Interrupted while its outputs are being written, into a fresh folder: nothing is left.
    done = interrupt(command, staging, tmp_path)
    assert (done.returncode, done.stderr) == (130, "interrupted\n")
    assert list(tmp_path.iterdir()) == []
    # A complete run, then a forced rerun interrupted mid-video: the complete output is untouched.
    assert subprocess.run(command, cwd=tmp_path).returncode == 0
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    done = interrupt(command + ["--force"], lambda: any(p.glob("video.mp4") for p in staging()), tmp_path)
    assert (done.returncode, done.stderr) == (130, "interrupted\n")
    assert [p.name for p in tmp_path.iterdir()] == ["demo"]
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before
    # Interrupted while it starts (importing MuJoCo and the rest): no traceback either. Pressed once MuJoCo's library
    # is mapped into the child, not after a fixed delay, which on a loaded machine can come before simbench runs.
    done = interrupt(command + ["--force"], _importing_mujoco, tmp_path)
    assert (done.returncode, done.stderr) == (130, "interrupted\n")
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before



CTRL_C_PROBE = """
import os, signal, time
from simbench.core import interrupts

def ctrl_c():
    os.kill(os.getpid(), signal.SIGINT)

with interrupts.raising_interrupted() as seen:
    try:
        with interrupts.held_back():
            ctrl_c()
            time.sleep(0.2)
            inside = "not raised inside"
    except interrupts.Interrupted:
        after = "raised after"
    try:
        exec("ctrl_c()\\ntime.sleep(5)")  # as scipy does while it is imported
    except KeyboardInterrupt as err:
        kind = type(err).__name__
print(inside, after, kind, seen.pressed)
raise SystemExit(130)
"""


def test_ctrl_c_is_held_back_on_request_and_survives_an_exec(tmp_path):
    """Ctrl-C inside held_back() is delivered when the block ends; one that leaves an exec() of a string and is
    caught still gives exit 130 (CPython 3.11 would kill the process with SIGINT after a plain KeyboardInterrupt)."""
    (tmp_path / "probe.py").write_text(CTRL_C_PROBE)
    done = subprocess.run([sys.executable, "-m", "probe"], capture_output=True, text=True, cwd=tmp_path, timeout=60,
                          preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # as conftest.interrupt
    assert (done.returncode, done.stdout, done.stderr) == (130, "not raised inside raised after Interrupted True\n",
                                                           "")


def test_a_signal_in_a_deferred_block_is_handled_after_it_and_not_inside():
    """interrupts.deferred: os.fork's at-fork hooks (logging's lock) must not be cut by Ctrl-C; one that comes
    inside the block is raised as the block ends, as the handler in force would have raised it."""
    import logging
    import os

    from simbench.core import interrupts

    reached_end = False
    with pytest.raises(KeyboardInterrupt):
        with interrupts.deferred():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)  # the handler would have run by now
            reached_end = True
    assert reached_end and signal.getsignal(signal.SIGINT) is signal.default_int_handler
    # SIGTERM under a handler that raises: inside the block, logging's at-fork hook runs whole (as in os.fork).
    def raising(signum, frame):
        raise InterruptedError

    original = signal.signal(signal.SIGTERM, raising)
    try:
        with pytest.raises(InterruptedError):
            with interrupts.deferred():
                os.kill(os.getpid(), signal.SIGTERM)
                logging._acquireLock()  # type: ignore[attr-defined]  # what the fork's hook does
                time.sleep(0.05)
                logging._releaseLock()  # type: ignore[attr-defined]
        assert signal.getsignal(signal.SIGTERM) is raising
        assert logging._lock.acquire(blocking=False)  # type: ignore[attr-defined]  # not left taken
        logging._lock.release()  # type: ignore[attr-defined]
    finally:
        signal.signal(signal.SIGTERM, original)


def test_ctrl_c_at_any_moment_of_a_runs_outputs_leaves_nothing_and_never_hangs(tmp_path):
    """Ctrl-C while the outputs are being written, the plots' process forked beside the video: exit 130 with
    nothing left, however early (a few tries: the moment varies)."""
    for attempt in range(3):
        out = tmp_path / f"try{attempt}" / "demo"
        out.parent.mkdir()
        command = [sys.executable, "-m", "simbench", "run", str(scenario_file("spherical_arm", "demo")), "--out",
                   str(out), "--quiet"]
        done = interrupt(command, lambda: any(out.parent.glob(".demo.partial-*")), tmp_path, timeout=60)
        assert (done.returncode, done.stderr) == (130, "interrupted\n")
        assert list(out.parent.iterdir()) == []


def test_a_ctrl_c_handled_as_the_staging_folder_is_made_leaves_nothing(tmp_path, monkeypatch):
    """The Ctrl-C of the test above, sent as soon as `.demo.partial-PID` appears, may be handled right as mkdir
    returns, before the block that removes the folder on the way out was entered (it left the folder, now and
    then, on a loaded machine): made here deterministic, an interrupt raised just after the folder is made."""
    from pathlib import Path

    from simbench.core import atomic

    made = Path.mkdir

    def mkdir_then_interrupted(self, *args, **kwargs):
        made(self, *args, **kwargs)
        if ".partial-" in self.name:
            raise KeyboardInterrupt

    monkeypatch.setattr(Path, "mkdir", mkdir_then_interrupted)
    with pytest.raises(KeyboardInterrupt), atomic.staged_folder(tmp_path / "demo"):
        pass
    assert list(tmp_path.iterdir()) == []
