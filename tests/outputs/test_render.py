"""The video (simbench.outputs.render), read back from the MP4 by imageio's ffmpeg reader, as a viewer would see it:
one frame every 1/fps s at the size asked, each the recorded pose drawn as MuJoCo draws it through the camera
with the preset's settings, and the plan, the trace and the decorations where the camera's own projection puts
them (a pinhole model built here from the camera's pose and field of view)."""

import dataclasses
import errno
import math
import os
import threading
from pathlib import Path

import imageio.v2 as imageio
import mujoco
import numpy as np
import pytest
import yaml
from scipy import ndimage

import simbench
from simbench.api import Decoration
from simbench.outputs.render import _check_finished, add_polyline, render_video
from simbench.scenario import parse_scenario
from tests.conftest import scenario_file

DURATION, HOLD = 0.5, 0.12  # s: case 1's line, fast, so that a video is a handful of frames
ENCODING_NOISE = 4.0  # mean |difference| per channel (0-255) that H.264 at CRF 23 leaves on a small frame


@pytest.fixture(scope="module")
def short():
    """Table 2 case 1 shortened to DURATION + HOLD s, planned and simulated once: (scenario, evaluation)."""
    doc = yaml.safe_load(scenario_file("spherical_arm", "case1").read_text())
    doc["timing"].update(duration=DURATION, hold=HOLD)
    scenario = parse_scenario(doc, "short")
    return scenario, simbench.evaluate(scenario)


def frames_of(path: Path) -> np.ndarray:
    """Every frame of the MP4, decoded (imageio-ffmpeg), as int RGB (frames, height, width, 3)."""
    reader = imageio.get_reader(path)
    try:
        return np.array([frame for frame in reader]).astype(int)  # list(reader) asks len(): inf frames
    finally:
        reader.close()


def still(rec, planned_point) -> np.ndarray:
    """A planned path that stays at one point: nothing of it is drawn (every segment has zero length)."""
    return np.repeat(np.asarray(planned_point, float)[None], len(rec.t), axis=0)


class Camera:
    """The pinhole model of a MuJoCo camera: its pose from mj_forward, focal length from its vertical fovy; the
    camera looks along its -z axis with y up, and image rows grow downwards."""

    def __init__(self, scene: Path, name: str, width: int, height: int):
        model = mujoco.MjModel.from_xml_path(str(scene))
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        cam = model.camera(name).id
        self.pos, self.rot = data.cam_xpos[cam].copy(), data.cam_xmat[cam].reshape(3, 3).copy()
        self.width, self.height = width, height
        self.focal = (height / 2) / math.tan(math.radians(model.cam_fovy[cam]) / 2)

    def project(self, point) -> np.ndarray:
        """(column, row) in pixels of a world point."""
        x, y, z = self.rot.T @ (np.asarray(point, float) - self.pos)
        return np.array([self.width / 2 + self.focal * x / -z, self.height / 2 - self.focal * y / -z])

    def unproject(self, column: float, row: float, depth: float) -> np.ndarray:
        """The world point at `depth` m in front of the camera that projects to (column, row)."""
        x = (column - self.width / 2) / self.focal * depth
        y = -(row - self.height / 2) / self.focal * depth
        return self.pos + self.rot @ np.array([x, y, -depth])


def reds(frame: np.ndarray) -> np.ndarray:
    """The trace's red (1.0, 0.15, 0.1): not the orange links, the grey floor or the sky."""
    return (frame[..., 0] > 180) & (frame[..., 1] < 90) & (frame[..., 2] < 90)


def blues(frame: np.ndarray) -> np.ndarray:
    """The solid plan's blue (0.1, 0.45, 1.0): not the faint part behind the reference, nor the sky."""
    return (frame[..., 2] > 200) & (frame[..., 0] < 80) & (frame[..., 1] < 170)


# What the README says each preset is: `fast` no shadows, reflections or multisampling; `pretty` all three, 4x.
PRESETS = {"fast": {"samples": 0, "shadows": False, "reflections": False},
           "pretty": {"samples": 4, "shadows": True, "reflections": True}}


def direct_renders(scene: Path, poses: np.ndarray, width: int, height: int, *, samples: int, shadows: bool,
                   reflections: bool) -> list[np.ndarray]:
    """The scene at each qpos through camera `front`, drawn by a plain mujoco.Renderer with `samples`-fold
    multisampling and shadows and reflections on or off."""
    model = mujoco.MjModel.from_xml_path(str(scene))
    model.vis.global_.offwidth, model.vis.global_.offheight = width, height
    model.vis.quality.offsamples = samples
    data = mujoco.MjData(model)
    renderer = mujoco.Renderer(model, height=height, width=width)
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = shadows
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = reflections
    drawn = []
    try:
        for qpos in poses:
            data.qpos[:] = qpos
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, camera="front")
            drawn.append(renderer.render().astype(int))
    finally:
        renderer.close()
    return drawn


@pytest.mark.parametrize("fps, width, height", [(10, 128, 96), (50, 96, 128)])
def test_one_frame_every_1_over_fps_s_at_the_size_asked(short, tmp_path, fps, width, height):
    """Frames at 0, 1/fps, ... up to the end of the recording, the end included when it falls on a frame time
    (0.62 s at 50 fps: 32 frames); each shows the recorded sample of its time, within one timestep."""
    scenario, ev = short
    rec, shown = ev.recording, []
    info = render_video(scenario.robot_def.scene, rec, ev.trajectory.tool_ref, tmp_path / "v.mp4", width=width,
                        height=height, fps=fps, paint=lambda model, rec, row: shown.append(row))
    frames = frames_of(tmp_path / "v.mp4")
    expected = math.floor((DURATION + HOLD) * fps + 1e-6) + 1
    assert len(frames) == len(shown) == info["frames"] == expected
    assert frames.shape[1:] == (height, width, 3)
    with imageio.get_reader(tmp_path / "v.mp4") as reader:
        assert reader.get_meta_data()["fps"] == fps
    times = rec.t[shown]
    assert np.all(np.abs(times - np.arange(expected) / fps) <= rec.timestep + 1e-9)
    assert info == {"frames": expected, "fps": fps, "width": width, "height": height, "camera": "front",
                    "quality": "fast"}  # the scene's first camera, models/spherical_arm/scene.xml


@pytest.mark.parametrize("quality", ["fast", "pretty"])
def test_each_frame_is_the_recorded_pose_drawn_with_the_presets_settings(short, tmp_path, quality):
    """With nothing drawn over it, a frame equals MuJoCo's own drawing of the pose recorded at its time with the
    preset's settings, up to the encoder's noise: where the arm moved, it is the pose of its own time and not of
    the other frame's; where multisampling or shadows change the drawing, it has them as the preset says.
    (Reflections change nothing in this scene: its floor reflects nothing.)"""
    scenario, ev = short
    rec, scene, (width, height) = ev.recording, scenario.robot_def.scene, (128, 96)
    render_video(scene, rec, still(rec, [5.0, 5.0, 5.0]), tmp_path / "v.mp4", width=width, height=height, fps=2,
                 quality=quality, trace=False)
    frames = frames_of(tmp_path / "v.mp4")
    rows = [int(np.argmin(np.abs(rec.t - k / 2))) for k in range(len(frames))]  # 0 and 0.5 s
    preset = PRESETS[quality]
    drawn = direct_renders(scene, rec.qpos[rows], width, height, **preset)
    moved = np.abs(drawn[0] - drawn[-1]).sum(axis=-1) > 60  # pixels the arm's motion changes
    assert len(frames) == 2 and moved.sum() > 20
    for k in range(2):
        assert np.abs(frames[k] - drawn[k]).mean() < ENCODING_NOISE
        pose_error = np.abs(frames[k] - drawn[k])[moved].mean()
        assert pose_error < 0.5 * np.abs(frames[k] - drawn[1 - k])[moved].mean()
    for toggled in ({"samples": 4 - preset["samples"]}, {"shadows": not preset["shadows"]}):
        other = direct_renders(scene, rec.qpos[rows[:1]], width, height, **{**preset, **toggled})[0]
        differs = np.abs(drawn[0] - other).sum(axis=-1) > 30
        assert differs.sum() > 50, toggled
        assert np.abs(frames[0] - drawn[0])[differs].mean() < 0.5 * np.abs(frames[0] - other)[differs].mean()


def test_the_plan_and_the_trace_land_where_the_camera_projects_them(short, tmp_path):
    """A planned line and a tool trace 0.4 m in front of the camera, laid where a pinhole model puts them at a
    quarter and three quarters of the height: the solid blue of the plan ahead of the reference and the red the
    trace adds (to the same video without it; the tool's tip is red too) cover those image lines, and nothing
    else is that blue or is made red."""
    scenario, ev = short
    rec, scene, (width, height) = ev.recording, scenario.robot_def.scene, (320, 240)
    cam = Camera(scene, "front", width, height)
    left, right = 0.2 * width, 0.8 * width
    plan_row, trace_row = 0.25 * height, 0.75 * height

    def line(row: float) -> np.ndarray:  # from left to right at `row`, one point a sample
        start, end = cam.unproject(left, row, 0.4), cam.unproject(right, row, 0.4)
        return start + np.linspace(0.0, 1.0, len(rec.t))[:, None] * (end - start)

    planned, traced = line(plan_row), dataclasses.replace(rec, tool=line(trace_row))
    for name, trace in (("trace", True), ("bare", False)):
        render_video(scene, traced, planned, tmp_path / f"{name}.mp4", width=width, height=height, fps=10,
                     trace=trace)
    frames, bare = frames_of(tmp_path / "trace.mp4"), frames_of(tmp_path / "bare.mp4")
    added_red = [reds(f) & ~ndimage.binary_dilation(reds(b), iterations=3) for f, b in zip(frames, bare)]

    def only_along(mask: np.ndarray, row: float, start: float, end: float) -> None:
        rr, cc = np.nonzero(mask)
        assert len(rr) > 0 and np.all(np.abs(rr - row) <= 5) and cc.min() >= start - 5 and cc.max() <= end + 5
        assert all(mask[int(row) - 5:int(row) + 6, c].any() for c in np.arange(int(start) + 6, int(end) - 6))

    only_along(blues(frames[0]), plan_row, left, right)  # at the start the whole plan lies ahead
    assert not added_red[0].any()  # and the trace is one point
    middle = len(frames) // 2
    here = cam.project(planned[int(np.argmin(np.abs(rec.t - middle / 10)))])[0]
    only_along(blues(frames[middle]), plan_row, here, right)  # behind the reference the plan is faint
    only_along(added_red[middle], trace_row, left, here)
    only_along(added_red[-1], trace_row, left, right)  # at the end the trace covers the tool's whole path


def test_a_cone_decoration_is_drawn_within_its_projection(short, tmp_path):
    """A cone from the world origin (simbench.api.Decoration): the pixels it changes lie within the projected
    box of its apex and rim, and it changes the pixels around its base's centre."""
    scenario, ev = short
    rec, scene, (width, height) = ev.recording, scenario.robot_def.scene, (160, 120)
    cam = Camera(scene, "front", width, height)
    tip = cam.unproject(0.25 * width, 0.3 * height, 1.0)
    length = 0.6 * np.linalg.norm(tip)
    axis = tip / np.linalg.norm(tip)
    half_angle = math.radians(15)
    cone = Decoration("cone", tuple(axis), half_angle, float(length), (0.1, 0.9, 0.2, 0.6))
    planned = still(rec, rec.tool[0])
    common = dict(width=width, height=height, fps=2, trace=False)
    render_video(scene, rec, planned, tmp_path / "cone.mp4", decorations=[cone], **common)
    render_video(scene, rec, planned, tmp_path / "bare.mp4", **common)
    changed = np.abs(frames_of(tmp_path / "cone.mp4")[0] - frames_of(tmp_path / "bare.mp4")[0]).sum(axis=-1) > 60
    e1 = np.cross(axis, [0.0, 0.0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    rim = [axis * length + length * math.tan(half_angle) * (math.cos(a) * e1 + math.sin(a) * e2)
           for a in np.linspace(0, 2 * math.pi, 36)]
    corners = np.array([cam.project(p) for p in [np.zeros(3), *rim]])
    (c0, r0), (c1, r1) = corners.min(axis=0) - 3, corners.max(axis=0) + 3
    rows, cols = np.nonzero(changed)
    assert len(rows) > 30
    assert rows.min() >= r0 and rows.max() <= r1 and cols.min() >= c0 and cols.max() <= c1
    centre_col, centre_row = np.round(cam.project(axis * length)).astype(int)
    assert changed[centre_row - 2:centre_row + 3, centre_col - 2:centre_col + 3].any()


def test_an_unknown_decoration_kind_is_refused_before_anything_is_written(short, tmp_path):
    scenario, ev = short
    sphere = Decoration("sphere", (0.0, 0.0, 1.0), 0.1, 0.2, (1.0, 0.0, 0.0, 1.0))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="cannot draw a decoration of kind 'sphere' \\(known: cone\\)"):
        render_video(scenario.robot_def.scene, ev.recording, ev.trajectory.tool_ref, tmp_path / "v.mp4",
                     width=128, height=96, fps=5, decorations=[sphere])
    assert list(tmp_path.iterdir()) == []


def _children() -> set[int]:
    """The pids of this process's live child processes (Linux: each /proc/<pid>/stat names its parent)."""
    pids = set()
    for entry in Path("/proc").iterdir():
        try:
            stat = (entry / "stat").read_text() if entry.name.isdigit() else ""
        except OSError:  # gone meanwhile
            continue
        if stat and int(stat.rsplit(")", 1)[1].split()[1]) == os.getpid():
            pids.add(int(entry.name))
    return pids


def test_a_failure_mid_video_is_raised_as_itself_and_ends_the_encoder(short, tmp_path):
    """A frame that cannot be made (here the paint hook fails at the third) stops the video: that error, not
    ffmpeg's broken pipe, reaches the caller, and neither the encoder's thread nor ffmpeg outlive the call."""
    scenario, ev = short
    before = _children()
    calls = []

    def paint(model, rec, row):
        calls.append(row)
        if len(calls) == 3:
            raise RuntimeError("the third frame's paint failed")

    with pytest.raises(RuntimeError, match="the third frame's paint failed"):
        render_video(scenario.robot_def.scene, ev.recording, ev.trajectory.tool_ref, tmp_path / "v.mp4",
                     width=128, height=96, fps=10, paint=paint)
    assert len(calls) == 3
    assert not [t for t in threading.enumerate() if t.name == "simbench-encoder"]
    assert _children() <= before


def test_a_video_cut_short_is_detected(short, tmp_path):
    """ffmpeg writes the MP4's index (its `moov` box) last: a file without it is refused as unfinished (EIO when
    neither a file-size limit nor a full disk explains it), and the whole file passes."""
    scenario, ev = short
    path = tmp_path / "v.mp4"
    render_video(scenario.robot_def.scene, ev.recording, ev.trajectory.tool_ref, path, width=128, height=96, fps=5)
    whole = path.read_bytes()
    _check_finished(path)
    cut = whole[:whole.index(b"moov") - 8]  # up to the index box's header
    path.write_bytes(cut)
    with pytest.raises(OSError) as caught:
        _check_finished(path)
    assert caught.value.errno == errno.EIO and caught.value.filename == str(path)


def test_polylines_skip_zero_length_segments_and_stop_when_the_scene_is_full():
    """add_polyline appends a line from each point to the next, none for a repeated point, as many as the scene
    holds and no more. (A MuJoCo line starts at its pos and runs size[2] along its frame's z axis.)"""
    points = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 0], [1, 1, 0], [1, 1, 1], [2, 1, 1]], float)
    segments = [(points[i], points[i + 1]) for i in (0, 2, 3, 4)]  # the second point is repeated
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>")
    roomy = mujoco.MjvScene(model, maxgeom=10)
    add_polyline(roomy, points, np.ones(4, np.float32), 2.0)
    assert roomy.ngeom == len(segments)
    for geom, (start, end) in zip(roomy.geoms, segments):
        assert np.allclose(geom.pos, start)
        assert np.allclose(geom.pos + geom.mat.reshape(3, 3)[:, 2] * geom.size[2], end)
    cramped = mujoco.MjvScene(model, maxgeom=3)
    add_polyline(cramped, points, np.ones(4, np.float32), 2.0)
    assert cramped.ngeom == 3
