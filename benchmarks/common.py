"""Helpers shared by the benchmarks: shipped scenarios, the machine's description and paired, interleaved
timing."""

from __future__ import annotations

import os
import platform
import time
from datetime import date

import numpy as np

import simbench
from simbench.core.resources import scenarios_dir


def segment_distance(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (N,) of points x (N, d) from the segment a-b: the brute-force truth of a path that is a line (the
    tests' too)."""
    ab = b - a
    u = np.clip((x - a) @ ab / (ab @ ab), 0.0, 1.0)
    return np.linalg.norm(x - (a + u[:, None] * ab), axis=1)


def shipped(name: str) -> simbench.Scenario:
    """A shipped scenario by its path under scenarios/ without the suffix ('spherical_arm/demo')."""
    return simbench.load_scenario(scenarios_dir() / f"{name}.yaml")


def machine() -> str:
    """CPU model, core count, OS and Python: what the numbers were measured on."""
    cpu = platform.processor() or "unknown CPU"
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    system = f"{platform.system()} {platform.release()}"
    return f"{cpu}, {os.cpu_count()} cores, {system}, Python {platform.python_version()}"


# A Python expression, for the source of a child process, for its own peak resident size in bytes (the process
# image's high-water mark). Not getrusage's ru_maxrss: Linux carries that across exec, so a child started from a
# larger parent (python -m benchmarks.run, after the other benchmarks) reports the parent's size.
CHILD_PEAK_BYTES = ('next(int(line.split()[1]) * 1024 for line in open("/proc/self/status") '
                    'if line.startswith("VmHWM:"))')


def today() -> str:
    """The date of the measurement."""
    return date.today().isoformat()


def interleaved(a, b, repeats: int) -> tuple[np.ndarray, np.ndarray]:
    """Wall times of a() and b(), run in turn A B A B ..., after one warm-up of each."""
    a(), b()
    ta, tb = [], []
    for _ in range(repeats):
        for fn, out in ((a, ta), (b, tb)):
            start = time.perf_counter()
            fn()
            out.append(time.perf_counter() - start)
    return np.array(ta), np.array(tb)
