"""report.json and timeseries.npz: what a run found, in SI units, for a reader and for a script."""

from __future__ import annotations

import json
import math
import platform
import zipfile
from collections.abc import Mapping
from pathlib import Path

import mujoco
import numpy as np

from simbench.analysis import Analysis
from simbench.api.trajectory import JointTrajectory
from simbench.core.atomic import staged_file, write_text
from simbench.core.version import __version__
from simbench.physics.sim import Recording


def plain(value):
    """JSON-ready copy: NumPy to Python, NaN and infinities to null, mappings (Event, Violation) to dicts."""
    if isinstance(value, Mapping):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, (np.integer, np.bool_)):
        return value.item()
    return value


def versions() -> dict:
    """Versions of what produced the numbers."""
    return {"simbench": __version__, "mujoco": mujoco.__version__, "numpy": np.__version__,
            "python": platform.python_version()}


def _head(scenario, timestep: float, source: str | None) -> dict:
    """What every report starts with: which scenario, what ran it, with what time settings."""
    timing = scenario.timing
    return {
        "scenario": {"name": scenario.name, "file": source, "description": scenario.description},
        "robot": scenario.robot,
        "planner": scenario.planner,
        "control": {"controller": scenario.control.controller},
        "versions": versions(),
        "timestep": timestep,
        "duration": timing.duration,
        "hold": timing.hold,
        "settle": scenario.sim.settle,
        "record_every": scenario.sim.record_every,  # timeseries.npz keeps every record_every-th sample and the last
        "time_law": timing.law,
    }


def build_failure_report(scenario, err, wall_time: dict, outputs: dict, source: str | None) -> dict:
    """report.json of a run whose physics failed (a PhysicsError): when and why, and how much was recorded."""
    rec, traj = err.recording, err.trajectory
    return plain({
        # the recording's timestep: a strided run's error carries the plan at its kept rows only
        **_head(scenario, float(traj.dt) if rec is None else rec.timestep, source),
        "status": "failed",
        "failure": {"stage": "simulate", "t": err.t, "cause": err.cause},
        # the samples simulated soundly, err.t = samples x dt (a strided run's recording holds fewer rows)
        "samples": 0 if rec is None else int(round(err.t / rec.timestep)),
        "warnings": [] if rec is None else list(rec.warnings),
        "plan": {**traj.info, "warnings": list(traj.warnings)},
        "wall_time": wall_time,
        "outputs": outputs,
        "config": scenario.model_dump(mode="json"),
    })


def build_report(scenario, ev, wall_time: dict, outputs: dict, source: str | None) -> dict:
    """The report.json document of a pipeline.Evaluation, with its verdict."""
    traj, rec, result = ev.trajectory, ev.recording, ev.analysis
    return plain({
        **_head(scenario, rec.timestep, source),
        **ev.verdict.to_report(),
        "control": ev.control,
        "samples": result.samples,
        "tracking": result.tracking,
        **({"metrics": result.metrics} if result.metrics else {}),
        "singularity_events": result.singularity_events,
        "limit_events": result.limit_events,
        "warnings": list(rec.warnings),
        "plan": {**traj.info, "warnings": list(traj.warnings)},
        "waypoints": list(traj.waypoints),
        "wall_time": wall_time,
        "outputs": outputs,
        **_with_servos(result.extra, ev.control.get("servo_design")),
        "config": scenario.model_dump(mode="json"),
    })


def _with_servos(extra: dict, design: list | None) -> dict:
    """The robot's report entries, a derived arm's with the servos designed for the run (`derived_arm.servos`)."""
    if not design or "derived_arm" not in extra:
        return extra
    return {**extra, "derived_arm": {**extra["derived_arm"], "servos": design}}


def write_report(report: dict, path: Path) -> None:
    """Write report.json (strict JSON: no NaN), in one step."""
    write_text(path, json.dumps(report, indent=2, allow_nan=False) + "\n")


def write_timeseries(robot, traj: JointTrajectory, rec: Recording, result: Analysis | None, path: Path) -> None:
    """Write timeseries.npz in one step: one row per (kept) control sample, SI units."""
    rows = rec.t.size
    arrays = {
        "t": rec.t, "s": traj.s[:rows], "joints": np.array(robot.joints),
        "q_ref": traj.q_ref[:rows], "qd_ref": traj.qd_ref[:rows], "q": rec.q, "qd": rec.qd, "qpos": rec.qpos,
        "ctrl": rec.ctrl, "actuator_force": rec.force, "tool_ref": traj.tool_ref[:rows], "tool": rec.tool,
    }
    arrays.update({name: series[:rows] for name, series in traj.series.items()})
    if result is not None:
        arrays.update(result.series)
    with staged_file(path) as tmp, open(tmp, "wb") as f:
        savez_fast(f, arrays)


def savez_fast(f, arrays: dict[str, np.ndarray]) -> None:
    """`arrays` into the open file f as np.savez_compressed writes them, but at zlib's fastest level (faster for
    a slightly larger file: BENCHMARKS.md)."""
    with zipfile.ZipFile(f, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1, allowZip64=True) as archive:
        for name, value in arrays.items():
            with archive.open(f"{name}.npy", "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(value), allow_pickle=False)
