"""Rendered and encoded video frames against raw `mujoco.Renderer` frames, on the same recording in one run.

simbench's video (`render.render_video`: pose, plan and trace overlays, paint hook, H.264 encoding on its own
thread) is timed whole, start-up included, against what a script would write to get the same pictures with
nothing added: a `mujoco.Renderer` with the same size and look (no shadows, reflections or multisampling: the
`fast` preset), posed at the same recorded states, each frame read back and dropped. Pairs run in alternation.
Target (issue 6): at least 0.8 of raw frames per second.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import mujoco
import numpy as np

import simbench
from benchmarks.common import interleaved, shipped
from simbench.outputs.render import render_video

REPEATS = 3
CASES = (("spherical_arm", "demo"), ("puma600", "weld_seam"), ("rsmg", "three_turns"))


def _raw(scene: Path, qpos: np.ndarray, camera: str, width: int, height: int) -> None:
    model = mujoco.MjModel.from_xml_path(str(scene))
    data = mujoco.MjData(model)
    model.vis.global_.offwidth, model.vis.global_.offheight = width, height
    model.vis.quality.offsamples = 0
    model.vis.quality.shadowsize = 0
    with mujoco.Renderer(model, height=height, width=width) as renderer:
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        for row in qpos:
            data.qpos[:] = row
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, camera=camera)
            renderer.render()


def measure_case(robot_name: str, scenario: str) -> dict:
    """Frames per second of simbench's video and of raw frames, and the median pairwise ratio."""
    sc = shipped(f"{robot_name}/{scenario}")
    ev = simbench.evaluate(sc)
    rec, traj, r = ev.recording, ev.trajectory, sc.render
    robot = sc.robot_def
    decorations = sc.planner_def.decorations(sc) if sc.planner_def.decorations else []
    camera = r.camera or robot.cameras()[0]
    rows = np.clip(np.searchsorted(rec.t, np.arange(0.0, rec.t[-1] + 1e-9, 1.0 / r.fps)), 0, len(rec.t) - 1)
    with tempfile.TemporaryDirectory() as tmp:
        def ours():
            render_video(robot.scene, rec, traj.tool_ref, Path(tmp) / "video.mp4", width=r.width, height=r.height,
                         fps=r.fps, camera=camera, quality="fast", trace=r.trace, decorations=decorations,
                         paint=robot.paint)

        def raw():
            _raw(robot.scene, rec.qpos[rows], camera, r.width, r.height)

        t_ours, t_raw = interleaved(ours, raw, REPEATS)
    return {"case": f"{robot_name}/{scenario}", "frames": int(rows.size), "size": f"{r.width}x{r.height}",
            "ours_fps": rows.size / np.median(t_ours), "raw_fps": rows.size / np.median(t_raw),
            "ratio": float(np.median(t_raw / t_ours))}


def measure() -> list[dict]:
    """Every case."""
    return [measure_case(*case) for case in CASES]


def markdown(results: list[dict]) -> str:
    """The result as a BENCHMARKS.md section."""
    rows = [f"| `{r['case']}` | {r['frames']} ({r['size']}) | {r['ours_fps']:.1f} | {r['raw_fps']:.1f} | "
            f"{r['ratio']:.2f} |" for r in results]
    return "\n".join([
        f"### Video: rendered and encoded frames against raw `mujoco.Renderer` frames ({REPEATS} interleaved pairs)",
        "",
        "| scenario | frames | simbench video, frames/s (overlays + H.264) | raw Renderer frames/s | ratio |",
        "|---|---|---|---|---|",
        *rows,
        "",
        "Both include opening the renderer. Target: at least 0.8.",
    ])


if __name__ == "__main__":
    print(markdown(measure()))
