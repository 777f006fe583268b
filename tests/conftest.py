"""Shared fixtures: shipped scenarios, their simulations cached for the session, Ctrl-C sent to a command, and the
distance of points from a segment (the brute-force truth of tests whose paths are lines)."""

import os
import signal
import subprocess
import time

os.environ.setdefault("MUJOCO_GL", "egl")

import pytest  # noqa: E402

import simbench  # noqa: E402
from benchmarks.common import segment_distance  # noqa: E402,F401  # the truth of a path that is a line
from simbench.core.resources import scenarios_dir  # noqa: E402


def scenario_file(robot: str, name: str):
    """Path of a shipped scenario."""
    return scenarios_dir() / robot / f"{name}.yaml"


SHIPPED = sorted(scenarios_dir().rglob("*.yaml"))


def interrupt(command: list[str], ready, cwd, timeout: float = 120,
              signum: int = signal.SIGINT) -> subprocess.CompletedProcess:
    """Run a command, send it Ctrl-C (SIGINT, or `signum`) once ready() is true, and wait for it (each within
    `timeout` s). A command whose output is still open `timeout` s after the signal fails the test saying why: where
    each of its threads was, if it still runs (Python's faulthandler, on SIGABRT), and which processes it started
    still hold its output (its own process group): a hang seen once in many runs says where it hung."""
    # A shell runs a background job with SIGINT ignored, and the child would inherit that: give it the default.
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=cwd,
                            env={**os.environ, "PYTHONFAULTHANDLER": "1"}, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + timeout
    while not ready():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.01)
    proc.send_signal(signum)
    try:
        stdout, stderr = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        pytest.fail(_hang(proc, command, signum, timeout))
    return subprocess.CompletedProcess(command, proc.returncode, stdout, stderr)


def _hang(proc: subprocess.Popen, command: list[str], signum: int, timeout: float) -> str:
    """Why `proc`'s output is still open after the signal: its threads' stacks if it still runs (SIGABRT:
    faulthandler), the other processes of its group; the group then killed."""
    import psutil

    running = proc.poll() is None
    if running:
        proc.send_signal(signal.SIGABRT)  # faulthandler writes every thread's stack to stderr, then the process ends
        time.sleep(1.0)
    group = []
    for process in psutil.process_iter(["pid", "cmdline"]):
        try:
            if process.pid != proc.pid and os.getpgid(process.pid) == proc.pid:
                group.append(f"{process.pid}: {' '.join(process.info['cmdline'] or [])[:200]}")
        except (OSError, psutil.Error):  # gone meanwhile
            continue
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    _, stderr = proc.communicate(timeout=timeout)
    state = "still running" if running else f"ended ({proc.returncode}) but its output was held open"
    return (f"{' '.join(map(str, command))}: {state} {timeout} s after signal {signum}; other processes of its group: "
            f"{group or 'none'}; its stderr:\n{stderr[-6000:]}")


@pytest.fixture(scope="session")
def evaluated():
    """evaluated(robot, name) -> (scenario, Evaluation), simulated once per session."""
    cache = {}

    def get(robot: str, name: str):
        key = (robot, name)
        if key not in cache:
            scenario = simbench.load_scenario(scenario_file(robot, name))
            cache[key] = (scenario, simbench.evaluate(scenario))
        return cache[key]

    return get


# An outside package's metric, as its module would read: joint 0's largest speed, every joint's, and the samples
# it was given (a window at a time). Tests register it in-process (peak_speed) or install it by an entry point.
PEAK_SPEED = '''
import numpy as np

from simbench.api import Metric


class PeakSpeed(Metric):
    name = "peak_speed"
    description = "the joints' largest measured speeds and the samples measured"

    def __init__(self):
        self.peaks, self.samples = None, 0

    def add(self, traj, rec, series):
        peaks = np.abs(rec.qd).max(axis=0)
        self.peaks = peaks if self.peaks is None else np.maximum(self.peaks, peaks)
        self.samples += rec.t.size

    def finish(self):
        return {"qd0_max": float(self.peaks[0]), "qd_max": self.peaks.tolist(), "samples": self.samples}
'''


@pytest.fixture
def peak_speed(monkeypatch):
    """The PEAK_SPEED metric registered for one test (as simbench.register_metric would), its class."""
    from simbench.api import registry

    namespace: dict = {}
    exec(PEAK_SPEED, namespace)
    metric = namespace["PeakSpeed"]
    registry.metrics()
    monkeypatch.setitem(registry._METRICS.objects, metric.name, metric)
    monkeypatch.setitem(registry._METRICS.origins, metric.name, "registered from Python")
    return metric
