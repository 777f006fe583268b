"""Headless video of a Recording: MuJoCo's offscreen renderer (EGL unless MUJOCO_GL says otherwise) into H.264 MP4.

Each frame draws the planned tool path (blue) and the tool's trace (red), simplified first (Ramer-Douglas-Peucker,
1 mm), since on a CPU a capsule costs about as much as a robot link. A thread feeds ffmpeg as frames render.
"""

from __future__ import annotations

import copy
import errno
import os
import queue
import shutil
import sys
import threading
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager, suppress
from pathlib import Path

import imageio.v2 as imageio
import mujoco
import numpy as np

from simbench.api import Decoration
from simbench.core.errors import RunError
from simbench.core.interrupts import held_back
from simbench.core.plant import compiled_scene
from simbench.outputs.drawn_planes import planes_drawn_finite
from simbench.physics.sim import Recording

_PLAN_RGBA = np.array([0.1, 0.45, 1.0, 1.0], np.float32)
_PLAN_PAST_RGBA = np.array([0.1, 0.45, 1.0, 0.2], np.float32)
_TRACE_RGBA = np.array([1.0, 0.15, 0.1, 1.0], np.float32)
_PLAN_WIDTH = 3.0  # pixels
_TRACE_RADIUS = 0.0035  # m
_SIMPLIFY_TOL = 1e-3
_QUEUED_FRAMES = 4
FREE_CAMERA = "free"  # the name a video of a scene without cameras gives the free camera it is seen from


class _Encoder:
    """An H.264 MP4 writer fed from a queue by its own thread, so encoding overlaps rendering."""

    def __init__(self, path: Path, fps: int):
        self._path = path
        self._writer = imageio.get_writer(path, format="FFMPEG", mode="I", fps=fps, codec="libx264",
                                          pixelformat="yuv420p", macro_block_size=2, ffmpeg_log_level="error",
                                          output_params=["-preset", "veryfast", "-crf", "23"])
        self._frames: queue.Queue = queue.Queue(maxsize=_QUEUED_FRAMES)
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._drain, name="simbench-encoder", daemon=True)
        self._thread.start()

    def _drain(self) -> None:
        while (frame := self._frames.get()) is not None:
            if self._error is None:
                try:
                    self._writer.append_data(frame)
                except BaseException as err:  # handed to the rendering thread at its next put or at close
                    self._error = err

    def put(self, frame: np.ndarray) -> None:
        """Queue a frame (blocks while the encoder is _QUEUED_FRAMES behind)."""
        if self._error is not None:
            raise self._error
        self._frames.put(frame)

    def abort(self) -> None:
        """Stop at once after a failure elsewhere: drop the queued frames and end ffmpeg, its complaints (a broken
        pipe, say) kept from masking the failure."""
        with suppress(queue.Empty):
            while True:
                self._frames.get_nowait()
        self._frames.put(None)
        self._thread.join()
        with suppress(OSError, RuntimeError):  # ffmpeg already gone: nothing left to save
            self._writer.close()

    def close(self) -> None:
        """Encode what is queued and finish the file; raises the encoder's error if it had one."""
        self._frames.put(None)
        self._thread.join()
        self._writer.close()
        if self._error is not None:
            raise self._error
        _check_finished(self._path)


def _check_finished(path: Path) -> None:
    """OSError if the MP4 lacks its index (`moov`, written last): imageio-ffmpeg does not pass on ffmpeg's failure
    on a full disk or a file-size limit."""
    with open(path, "rb") as f:
        if b"moov" in f.read():
            return
    if _at_file_size_limit(path.stat().st_size):
        raise OSError(errno.EFBIG, "ffmpeg stopped at the file-size limit", str(path))
    if shutil.disk_usage(path.parent).free < (1 << 20):
        raise OSError(errno.ENOSPC, "ffmpeg ran out of space", str(path))
    raise OSError(errno.EIO, "ffmpeg did not finish the video", str(path))


def _at_file_size_limit(size: int) -> bool:
    """Whether a file of `size` bytes has reached the process's file-size limit (RLIMIT_FSIZE; a platform without
    the `resource` module, Windows, has none to reach)."""
    try:
        import resource
    except ImportError:
        return False
    soft, _ = resource.getrlimit(resource.RLIMIT_FSIZE)
    return soft != resource.RLIM_INFINITY and size >= soft


def simplify(points: np.ndarray, tol: float) -> np.ndarray:
    """Indices of the vertices Ramer-Douglas-Peucker keeps: every dropped point lies within tol of the result."""
    keep = np.zeros(len(points), bool)
    keep[[0, -1]] = True
    stack = [(0, len(points) - 1)]
    while stack:
        i, j = stack.pop()
        if j <= i + 1:
            continue
        a, ab = points[i], points[j] - points[i]
        rel = points[i + 1:j] - a
        denom = ab @ ab
        if denom > 0:
            u = np.clip(rel @ ab / denom, 0.0, 1.0)
            dist = np.linalg.norm(rel - u[:, None] * ab, axis=1)
        else:
            dist = np.linalg.norm(rel, axis=1)
        k = int(np.argmax(dist))
        if dist[k] > tol:
            keep[i + 1 + k] = True
            stack += [(i, i + 1 + k), (i + 1 + k, j)]
    return np.flatnonzero(keep)


def add_polyline(scene: mujoco.MjvScene, points: np.ndarray, rgba: np.ndarray, width: float,
                 kind: int = mujoco.mjtGeom.mjGEOM_LINE) -> None:
    """Append unshaded lines (`width` pixels) or capsules (radius `width` m) joining consecutive points."""
    for a, b in zip(points[:-1], points[1:]):
        if scene.ngeom >= scene.maxgeom:
            return
        if np.linalg.norm(b - a) < 1e-9:
            continue
        geom = scene.geoms[scene.ngeom]
        mujoco.mjv_initGeom(geom, kind, np.zeros(3), np.zeros(3), np.eye(3).ravel(), rgba)
        mujoco.mjv_connector(geom, kind, width, a, b)
        geom.category = mujoco.mjtCatBit.mjCAT_DECOR
        geom.emission = 1.0  # drawn in its own colour, unshaded
        scene.ngeom += 1


def add_cone(scene: mujoco.MjvScene, axis: np.ndarray, half_angle: float, length: float, rgba: np.ndarray,
             lines: int = 8) -> None:
    """A cone from the origin: its base as a thin translucent disc at `length` along `axis`, and lines to its rim."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    radius = length * np.tan(half_angle)
    seed = np.eye(3)[np.argmin(np.abs(axis))]
    e1 = np.cross(axis, seed)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    if scene.ngeom < scene.maxgeom:
        frame = np.column_stack([e1, e2, axis])
        mujoco.mjv_initGeom(scene.geoms[scene.ngeom], mujoco.mjtGeom.mjGEOM_CYLINDER, np.array([radius, 1e-4, 0.0]),
                            axis * length, frame.ravel(), np.asarray(rgba, np.float32))
        scene.ngeom += 1
    angles = np.linspace(0.0, 2 * np.pi, lines, endpoint=False)
    rim = axis * length + radius * (np.cos(angles)[:, None] * e1 + np.sin(angles)[:, None] * e2)
    edge = np.asarray(rgba, np.float32).copy()
    edge[3] = min(1.0, edge[3] * 2)
    for point in rim:
        add_polyline(scene, np.array([np.zeros(3), point]), edge, 1.0)


def egl_by_default() -> bool:
    """Whether simbench draws through EGL (offscreen, no display needed): on Linux, unless the user chose a backend
    with MUJOCO_GL. Elsewhere MuJoCo's and dm_control's defaults draw offscreen themselves."""
    return sys.platform == "linux" and not os.environ.get("MUJOCO_GL")


def choose_dm_control_backend() -> None:
    """dm_control's Physics.render through EGL where egl_by_default, else through the user's MUJOCO_GL, whichever
    imported dm_control first; nothing is set for the process.

    dm_control picks its backend once, when first imported: with MUJOCO_GL unset, GLFW first, which cannot draw
    without a display. Imported here first, it gets EGL; imported before (by shimmy, say), a choice other than
    the one wanted is replaced before any context is made."""
    if egl_by_default() and "dm_control._render" not in sys.modules:
        os.environ["MUJOCO_GL"] = "egl"  # GLFW not even tried: it complains of the missing display
        try:
            import dm_control._render  # noqa: F401
        finally:
            del os.environ["MUJOCO_GL"]
    from dm_control import _render

    wanted = "egl" if egl_by_default() else os.environ.get("MUJOCO_GL", "").lower()
    for names, import_renderer in _render._ALL_RENDERERS:  # (names, importer), the canonical name first
        if wanted in names and _render.BACKEND not in names:
            _render.Renderer, _render.BACKEND = import_renderer(), names[0]


@contextmanager
def _egl_unless_chosen() -> Iterator[None]:
    """MuJoCo's Renderers made within draw through EGL (offscreen, no display) unless the user chose MUJOCO_GL;
    nothing is set for the process."""
    if not egl_by_default():
        yield
        return
    from mujoco import egl

    gl_context = sys.modules[mujoco.Renderer.__module__].gl_context  # where the Renderer finds its context class
    chosen = getattr(gl_context, "GLContext", None)
    gl_context.GLContext = egl.GLContext
    try:
        yield
    finally:
        gl_context.GLContext = chosen


@contextmanager
def _beside_dm_control() -> Iterator[None]:
    """The video's EGL context made beside dm_control's, which draws an environment's frames on the calling thread.

    The context current on this thread is made current again once the video is done: dm_control, believing its
    own still current, would draw into the video's context, or into none once that is freed (noise). And MuJoCo
    takes dm_control's display (the same device's, already initialised) rather than initialise it again: it would
    end it at exit before dm_control frees its contexts on it (a traceback at exit)."""
    chosen = os.environ.get("MUJOCO_GL", "").lower()
    if not (egl_by_default() or (sys.platform == "linux" and chosen == "egl")):
        yield
        return
    from mujoco import egl
    from OpenGL import EGL  # PyOpenGL's EGL platform, as MuJoCo's and dm_control's EGL contexts load it

    dm_control_egl = sys.modules.get("dm_control._render.pyopengl.egl_renderer")
    if egl.EGL_DISPLAY is None and dm_control_egl is not None:
        egl.EGL_DISPLAY = dm_control_egl.EGL_DISPLAY
    display, context = EGL.eglGetCurrentDisplay(), EGL.eglGetCurrentContext()
    surfaces = EGL.eglGetCurrentSurface(EGL.EGL_DRAW), EGL.eglGetCurrentSurface(EGL.EGL_READ)
    try:
        yield
    finally:
        if context:
            EGL.eglMakeCurrent(display, *surfaces, context)


def _open_renderer(model: mujoco.MjModel, width: int, height: int, quality: str) -> mujoco.Renderer:
    """An offscreen renderer of exactly this size (a larger buffer costs time on a CPU) and preset."""
    pretty = quality == "pretty"
    model.vis.global_.offwidth, model.vis.global_.offheight = width, height
    model.vis.quality.offsamples = 4 if pretty else 0
    if not pretty:
        model.vis.quality.shadowsize = 0  # no shadow map to allocate: a third of the renderer's start-up
    try:
        # cut halfway, a Renderer has no GL context and its __del__ prints a traceback
        with held_back(), _egl_unless_chosen():
            renderer = mujoco.Renderer(model, height=height, width=width, max_geom=4000)
    except Exception as err:  # the GL backend reports its own failure types
        chosen = os.environ.get("MUJOCO_GL")
        backend = f"MUJOCO_GL={chosen}" if chosen else "EGL"
        raise RunError(f"cannot open an offscreen renderer through {backend} ({type(err).__name__}: {err}); "
                       "install EGL (Debian: libegl1 libgl1-mesa-dri) and leave MUJOCO_GL unset or set it to egl, "
                       "or pass --no-video") from None
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = pretty
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = pretty
    return renderer


_DRAW = {"cone": lambda scene, item: add_cone(scene, item.axis, item.half_angle, item.length, item.rgba)}
"""How each kind of simbench.api.Decoration is drawn."""


def _check_decorations(decorations: Sequence[Decoration]) -> None:
    """ValueError naming a decoration of a kind simbench cannot draw, before any frame is made."""
    for item in decorations:
        if item.kind not in _DRAW:
            raise ValueError(f"cannot draw a decoration of kind {item.kind!r} (known: {', '.join(_DRAW)})")


def _frame_rows(t: np.ndarray, fps: int) -> np.ndarray:
    """The recorded row of each frame (every 1/fps s): the first at or after its time."""
    frame_t = np.arange(0.0, t[-1] + 1e-9, 1.0 / fps)
    return np.clip(np.searchsorted(t, frame_t), 0, len(t) - 1)


class _Overlay:
    """What is drawn over the model in every frame: decorations, planned path and the tool's trace so far."""

    def __init__(self, planned: np.ndarray, tool: np.ndarray | None, decorations: Sequence[Decoration]):
        self.planned, self.tool, self.decorations = planned, tool, decorations
        self.plan_idx = simplify(planned, _SIMPLIFY_TOL)
        self.trace_idx = simplify(tool, _SIMPLIFY_TOL) if tool is not None else np.zeros(0, int)

    def draw(self, scene: mujoco.MjvScene, row: int) -> None:
        """Append the overlay of the frame showing recorded row `row` to the scene."""
        for item in self.decorations:
            _DRAW[item.kind](scene, item)
        planned, idx = self.planned, self.plan_idx
        here = planned[row:row + 1]
        add_polyline(scene, np.vstack([here, planned[idx[idx > row]]]), _PLAN_RGBA, _PLAN_WIDTH)
        add_polyline(scene, np.vstack([planned[idx[idx <= row]], here]), _PLAN_PAST_RGBA, _PLAN_WIDTH)
        if self.tool is not None:
            upto = self.trace_idx[self.trace_idx <= row]
            add_polyline(scene, np.vstack([self.tool[upto], self.tool[row:row + 1]]), _TRACE_RGBA, _TRACE_RADIUS,
                         mujoco.mjtGeom.mjGEOM_CAPSULE)


def _frames(model: mujoco.MjModel, renderer: mujoco.Renderer, rec: Recording, rows: np.ndarray,
            camera: str | None, overlay: _Overlay, paint) -> Iterator[np.ndarray]:
    """Each frame's pixels, seen from `camera` (None: the free camera)."""
    data = mujoco.MjData(model)
    for row in rows:
        data.qpos[:] = rec.qpos[row]
        mujoco.mj_forward(model, data)
        if paint is not None:
            paint(model, rec, row)
        renderer.update_scene(data, camera=-1 if camera is None else camera)
        overlay.draw(renderer.scene, row)
        yield renderer.render()


def _encode(path: Path, fps: int, frames: Iterable[np.ndarray]) -> None:
    """Encode the frames into an MP4 at `path` as they come; on any failure (Ctrl-C included) stop ffmpeg."""
    encoder = _Encoder(path, fps)
    try:
        for frame in frames:
            encoder.put(frame)
    except BaseException:
        encoder.abort()
        raise
    encoder.close()


def render_video(scene: Path, rec: Recording, planned: np.ndarray, path: Path, *, width: int = 640,
                 height: int = 480, fps: int = 30, camera: str | None = None, quality: str = "fast",
                 trace: bool = True, decorations: Sequence[Decoration] = (), paint=None) -> dict:
    """Write the MP4 and return its frames, fps, size, camera and quality. `paint(model, rec, row)` may recolour
    the model for each frame; a scene without cameras is seen from MuJoCo's free camera."""
    _check_decorations(decorations)
    model = copy.copy(compiled_scene(str(scene)))  # the run's own compilation; the copy's sizes are set below
    camera = camera or (model.camera(0).name if model.ncam else None)
    rows = _frame_rows(rec.t, fps)
    overlay = _Overlay(planned, rec.tool if trace else None, decorations)
    with _beside_dm_control(), planes_drawn_finite(model):  # the GL context draws the planes as they are now
        renderer = _open_renderer(model, width, height, quality)
        try:
            _encode(path, fps, _frames(model, renderer, rec, rows, camera, overlay, paint))
        finally:
            renderer.close()
    return {"frames": int(len(rows)), "fps": fps, "width": width, "height": height, "camera": camera or FREE_CAMERA,
            "quality": quality}
