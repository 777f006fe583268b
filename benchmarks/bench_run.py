"""A whole `simbench run` with video against its raw parts, measured in one run (project issue 14).

The whole run: `simbench.run` of the scenario with video into a fresh folder (its wall time, and report.json's
per-stage split). Its raw parts, what no run can do without: the model loaded, the plan and the simulation
(`Plant.load`, the planner, `sim.simulate`), the same frames drawn by a plain `mujoco.Renderer` (the same rows,
size and camera, the default preset's settings: no multisampling, shadows or reflections; no overlay), and those
frames encoded to H.264 with the same encoder settings, one stage after the other. Whole runs and raw parts
alternate; the ratio is the median of the pairwise ratios, so that a busy machine slows both alike. Target: at
most 2.0.
"""

from __future__ import annotations

import copy
import itertools
import tempfile
import time
from pathlib import Path

import imageio.v2 as imageio
import mujoco
import numpy as np

import simbench
from benchmarks.common import interleaved, shipped
from simbench.core.plant import Plant, compiled_scene
from simbench.outputs.render import _frame_rows
from simbench.physics.sim import simulate

REPEATS = 5


def _plan_and_simulate(sc: simbench.Scenario):
    """The recording of the scenario, made with nothing else: load, plan, simulate."""
    robot, sim = sc.robot_def, sc.sim
    controller = sc.controller_def.from_scenario(sc)
    plant = Plant.load(robot, sim.timestep, sim.kp, sim.kv, sim.force_limits, sim.gravity_compensation,
                       controller.actuation)
    traj = sc.planner_def.plan(sc, robot, float(plant.model.opt.timestep))
    return simulate(plant, traj, controller, settle=sim.settle)


def _raw_frames(sc: simbench.Scenario, rec) -> list[np.ndarray]:
    """The video's frames drawn by a plain renderer: each row posed, seen from the camera, no overlay."""
    r = sc.render
    model = copy.copy(compiled_scene(str(sc.robot_def.scene)))
    model.vis.global_.offwidth, model.vis.global_.offheight = r.width, r.height
    model.vis.quality.offsamples, model.vis.quality.shadowsize = 0, 0
    renderer = mujoco.Renderer(model, height=r.height, width=r.width)
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
    data = mujoco.MjData(model)
    frames = []
    for row in _frame_rows(rec.t, r.fps):
        data.qpos[:] = rec.qpos[row]
        mujoco.mj_forward(model, data)
        renderer.update_scene(data, camera=r.camera or model.camera(0).name)
        frames.append(renderer.render())
    renderer.close()
    return frames


def _raw_encode(frames: list[np.ndarray], path: Path, fps: int) -> None:
    """The frames into an H.264 MP4 with the video's encoder settings, in this thread."""
    writer = imageio.get_writer(path, format="FFMPEG", mode="I", fps=fps, codec="libx264", pixelformat="yuv420p",
                                macro_block_size=2, ffmpeg_log_level="error",
                                output_params=["-preset", "veryfast", "-crf", "23"])
    for frame in frames:
        writer.append_data(frame)
    writer.close()


def _raw_parts(sc: simbench.Scenario, path: Path) -> list[float]:
    """Seconds of each raw part in turn: plan and simulate, the plain frames, their encoding into `path`."""
    marks = [time.perf_counter()]
    rec = _plan_and_simulate(sc)
    marks.append(time.perf_counter())
    frames = _raw_frames(sc, rec)
    marks.append(time.perf_counter())
    _raw_encode(frames, path, sc.render.fps)
    marks.append(time.perf_counter())
    return [float(seconds) for seconds in np.diff(marks)]


def measure(name: str = "spherical_arm/demo") -> dict:
    """Median wall times of the whole run and of its raw parts, REPEATS of each in alternation, and the median
    of the pairwise ratios whole / raw."""
    sc = shipped(name)
    stages: dict[str, list[float]] = {}
    frames = []
    parts: dict[str, list[float]] = {"plan + simulate": [], "frames": [], "encode": []}
    with tempfile.TemporaryDirectory() as tmp:
        count = itertools.count()

        def whole():
            report = simbench.run(sc, out=Path(tmp) / f"run{next(count)}", video=True).report
            for stage, seconds in report["wall_time"].items():
                stages.setdefault(stage, []).append(seconds)
            frames.append(report["outputs"]["video_info"]["frames"])

        def raw():
            for key, seconds in zip(parts, _raw_parts(sc, Path(tmp) / f"raw{next(count)}.mp4")):
                parts[key].append(seconds)

        t_whole, t_raw = interleaved(whole, raw, REPEATS)
    return {"scenario": name, "frames": frames[0], "size": f"{sc.render.width}x{sc.render.height}",
            "whole": float(np.median(t_whole)), "raw": float(np.median(t_raw)),
            "ratio": float(np.median(t_whole / t_raw)), "pairs": [float(x) for x in t_whole / t_raw],
            "stages": {k: float(np.median(v[1:])) for k, v in stages.items()},  # the warm-up left out
            "parts": {k: float(np.median(v[1:])) for k, v in parts.items()}}


def markdown(r: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    stages = [f"| {stage} | {seconds:.3f} |" for stage, seconds in r["stages"].items()]
    parts = [f"| {part} | {seconds:.3f} |" for part, seconds in r["parts"].items()]
    return "\n".join([
        f"### Whole run with video against its raw parts: `{r['scenario']}` ({r['frames']} frames of {r['size']}, "
        f"{REPEATS} interleaved pairs)",
        "",
        "`python -m benchmarks.bench_run`.",
        "",
        "| whole run: stage (report.json) | seconds (median) |",
        "|---|---|",
        *stages,
        "",
        "| raw part | seconds (median) |",
        "|---|---|",
        *parts,
        "",
        f"Whole run {r['whole']:.3f} s, raw parts {r['raw']:.3f} s (medians); whole / raw, median of the pairs: "
        f"{r['ratio']:.2f} (pairs: {', '.join(f'{x:.2f}' for x in r['pairs'])}). Target: at most 2.0.",
    ])


if __name__ == "__main__":
    print(markdown(measure()))
