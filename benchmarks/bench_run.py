"""Wall time of a whole `simbench run` with video, split by stage (median of several runs)."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

import simbench
from benchmarks.common import shipped

REPEATS = 3


def measure(robot_name: str = "spherical_arm", scenario: str = "demo") -> dict:
    """Median seconds per stage over REPEATS runs of the scenario with video."""
    sc = shipped(f"{robot_name}/{scenario}")
    stages: dict[str, list[float]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(REPEATS):
            report = simbench.run(sc, out=Path(tmp) / f"run{i}", video=True).report
            for stage, seconds in report["wall_time"].items():
                stages.setdefault(stage, []).append(seconds)
    frames = report["outputs"]["video_info"]["frames"]
    return {"scenario": f"{robot_name}/{scenario}", "frames": frames, "samples": report["samples"],
            "stages": {k: float(np.median(v)) for k, v in stages.items()}}


def markdown(r: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    rows = [f"| {stage} | {seconds:.3f} |" for stage, seconds in r["stages"].items()]
    video = r["stages"].get("video", 0.0)
    return "\n".join([
        f"### Whole run with video: `{r['scenario']}` ({r['samples']} control samples, {r['frames']} frames of "
        f"640x480, median of {REPEATS})",
        "",
        "| stage | seconds |",
        "|---|---|",
        *rows,
        "",
        f"Video: {1e3 * video / r['frames']:.1f} ms a frame (render and H.264 encode).",
    ])


if __name__ == "__main__":
    print(markdown(measure()))
