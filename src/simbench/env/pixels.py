"""Frames of an environment at the cost of their own size: the GL buffers sized to the largest frame asked so far,
not to the scene file's (simbench's scenes ask for a 1920x1080 buffer and a 4096 shadow map, for videos).

dm_control makes a physics' GL context once, with the model's `offwidth` x `offheight` offscreen buffer, its
`shadowsize` shadow map and its round geoms cut into `numslices` x `numstacks` facets (28 x 16 by default, made for
full-size videos); on a CPU renderer (Mesa llvmpipe) all three cost time in every frame, however small the frame
(an 84x84 frame of the PUMA about 2.5 times its fitted cost; the RSMG's 78 round geoms about 4 times). Here the
context is made for the frames asked: the buffer as large as the largest frame so far, the shadow map SHADOW_TEXELS
texels a pixel of its longer side (a power of two), round geoms with as many facets as keep the outline of one a
quarter of that side across within half a pixel of the true circle (`facets`), each at most the file's; a larger
frame remakes the context. The model's own settings are left as the file has them (a video made from the same model
renders as before).

dm_control's render also makes a Camera a frame, its MjvScene allocated for the model's every geom (a share of a
small frame's cost on a CPU renderer: BENCHMARKS.md, `bench_env_step`); here a frame's Camera is kept for the next
frame of the same size and camera (CAMERAS of them, made again with the context), and the frame handed out is a copy
of its buffer, which the next frame overwrites. A kept free camera (camera_id -1) is set again from the model's view
(its `vis.global_` azimuth and elevation, its extent and centre) before each frame, as a new one is; a Camera holds
its physics weakly (so that a physics no longer used is freed at once, GL context and all); one frame at a time is
drawn on a physics.
"""

from __future__ import annotations

import math
import threading
import weakref
from typing import Any

import mujoco
from dm_control.mujoco import engine

from simbench.outputs.drawn_planes import planes_drawn_finite

SHADOW_TEXELS = 3
"""Shadow-map texels a pixel of the largest frame's longer side (dm_control's reacher: 2048 for 640x480)."""


OUTLINE_SHARE = 1 / 4
"""The widest round geom drawn true to half a pixel, as a share of the frame's longer side."""

CAMERAS = 4
"""Cameras kept, one a frame size and camera (the oldest dropped first)."""


def facets(longer: int) -> int:
    """Slices of a round geom whose polygonal outline stays within half a pixel of its circle, for a geom
    OUTLINE_SHARE of a frame `longer` pixels wide: a chord's sagitta r (1 - cos(pi / n)) at most 0.5 px (28, MuJoCo's
    default, at 640 pixels; 11 at 84)."""
    radius = max(1.0, OUTLINE_SHARE * longer / 2)
    return math.ceil(math.pi / math.acos(1 - 0.5 / radius))


class FittedRendering(engine.Physics):
    """dm_control's Physics whose GL context fits the frames it renders (the module's docstring says how)."""

    _fitted: tuple[int, int, int, int, int] | None = None  # buffer width, height, shadow map size, slices, stacks
    _cameras: dict[tuple[int, int, int | str], engine.Camera]  # (height, width, camera_id) -> its Camera

    def _reload_from_data(self, data: Any) -> None:
        """dm_control's reload (which frees the GL context), the context then fitted anew at the next frame."""
        self._fitted, self._cameras, self._drawing = None, {}, threading.Lock()
        super()._reload_from_data(data)

    def render(self, height: int = 240, width: int = 320, camera_id: int | str = -1, overlays: Any = (),
               depth: bool = False, segmentation: bool = False, scene_option: Any = None,
               render_flag_overrides: Any = None, scene_callback: Any = None):
        """dm_control's render (same arguments and image), the GL context first fitted to the frame, infinite planes
        drawn finite (simbench.outputs.drawn_planes), the frame's Camera kept for the next of its size."""
        with self._drawing, planes_drawn_finite(self.model.ptr):  # both where the GL context is made and in the frame
            self._fit(int(width), int(height))
            if scene_callback is not None:  # (a Camera holds its callback: made for this frame alone)
                return super().render(height, width, camera_id, overlays, depth, segmentation, scene_option,
                                      render_flag_overrides, scene_callback)
            image = self._camera(height, width, camera_id).render(
                overlays=overlays, depth=depth, segmentation=segmentation, scene_option=scene_option,
                render_flag_overrides=render_flag_overrides)
            return image.copy()  # (a view of the Camera's buffer, which its next frame overwrites)

    def _camera(self, height: int, width: int, camera_id: int | str) -> engine.Camera:
        """The Camera of frames of this size and camera: kept, or made (the oldest of CAMERAS dropped)."""
        key = (height, width, camera_id)
        camera = self._cameras.pop(key, None)
        if camera is None:
            camera = engine.Camera(weakref.proxy(self), height, width, camera_id)
        elif camera_id == -1:  # the view a new free camera takes (the model's may have changed)
            mujoco.mjv_defaultFreeCamera(self.model.ptr, camera._render_camera)
        if len(self._cameras) >= CAMERAS:
            del self._cameras[next(iter(self._cameras))]
        self._cameras[key] = camera  # (the newest last)
        return camera

    def _fit(self, width: int, height: int) -> None:
        """Remake the GL context if this frame needs a larger buffer or shadow map than the one it has."""
        vis = self.model.ptr.vis
        ceiling = (vis.global_.offwidth, vis.global_.offheight, vis.quality.shadowsize, vis.quality.numslices,
                   vis.quality.numstacks)
        old = self._fitted or (0, 0, 0, 0, 0)
        wide, high = min(max(width, old[0]), ceiling[0]), min(max(height, old[1]), ceiling[1])
        shadow = min(ceiling[2], 1 << max(0, SHADOW_TEXELS * max(wide, high) - 1).bit_length()) if ceiling[2] else 0
        slices = min(ceiling[3], facets(max(wide, high)))
        stacks = min(ceiling[4], math.ceil(slices * ceiling[4] / max(1, ceiling[3])))  # the file's proportion
        fitted = (wide, high, shadow, slices, stacks)
        if self._fitted is not None and fitted == old:
            return
        self._cameras = {}  # (made with the context)
        with self._contexts_lock:
            if self._contexts:
                self._free_rendering_contexts()
            self._set_quality(fitted)
            try:
                self._make_rendering_contexts()
            finally:
                self._set_quality(ceiling)
        self._fitted = fitted

    def _set_quality(self, settings: tuple[int, int, int, int, int]) -> None:
        """The model's buffer size, shadow map size, slices and stacks (the order of `_fitted`)."""
        vis = self.model.ptr.vis
        (vis.global_.offwidth, vis.global_.offheight, vis.quality.shadowsize, vis.quality.numslices,
         vis.quality.numstacks) = settings
