"""Infinite planes drawn as large finite squares: the same picture at a fraction of the cost on a CPU renderer.

MuJoCo draws a plane whose size is 0 in x or y (a floor, in simbench's scenes and most others) as an infinite
grid, which Mesa's llvmpipe renders at about twice the cost of the rest of a scene (an 84x84 frame of the PUMA;
BENCHMARKS.md, bench_env_step). A square reaching the far clipping distance (`vis.map.zfar` times `stat.extent`)
in each infinite direction, in TILES x TILES quads, shows the same floor up to the haze at the horizon. The sizes
are put back when the block ends, so the physics never sees them. MuJoCo reads them twice: where a GL context is made
(its plane grids)
and where a frame's scene is updated (the texture's repeats), so both must happen inside the block.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import mujoco
import numpy as np

TILES = 20
"""Quads a drawn side is cut into (a plane's third size is the spacing of its drawn grid)."""


@contextmanager
def planes_drawn_finite(model: mujoco.MjModel) -> Iterator[None]:
    """Inside the block, the model's infinite planes have a finite drawn size (the module's docstring says why).

    Args:
        model: The model drawn; its other sizes, and these once the block ends, are left as they were.
    """
    planes = np.flatnonzero((model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE)
                            & (model.geom_size[:, :2] <= 0).any(axis=1))
    saved = model.geom_size[planes].copy()
    far = float(model.vis.map.zfar * model.stat.extent)
    sizes = saved.copy()
    sizes[:, :2] = np.where(saved[:, :2] <= 0, far, saved[:, :2])
    sizes[:, 2] = np.maximum(saved[:, 2], 2 * sizes[:, :2].max(axis=1) / TILES)
    model.geom_size[planes] = sizes
    try:
        yield
    finally:
        model.geom_size[planes] = saved
