"""The stage a derived arm is shown on (robots.model_scene): what the model lacks of what the shipped scenes have
(models/common/scene_assets.xml, models/*/scene.xml), so that its video is lit and shows the arm large. Each part is
added only where the model has none of its own:
  - floor: a checker floor at the chain's root body's height, colliding with the arm;
  - sky: a gradient skybox and haze;
  - lights: a key and a fill light, directional, and the shipped scenes' headlight;
  - camera: one from the front right and above, as near as frames the arm at its reference pose and half its reach
    about the first joint; MuJoCo's free camera (a dm_control render's default) shows the same view where the model
    leaves its `<statistic>` unset.
"""

from __future__ import annotations

from itertools import product
from typing import TYPE_CHECKING

import mujoco
import numpy as np

if TYPE_CHECKING:
    from simbench.robots.model_scene import DerivedArm

CAMERA = "simbench/view"
FLOOR = "simbench/floor"
_FOVY = 45.0  # deg, the added camera's (MuJoCo's default)
_AWAY = np.array([1.0, -1.0, 0.5]) / np.linalg.norm([1.0, -1.0, 0.5])  # from the arm to the camera
_FILL = 0.9  # the share of the frame's half-height (and half-width) the framed points may take
_ASPECT = 4 / 3  # the frame's width over its height (a video's, 640 by 480 unless its scenario says otherwise)
_ROOM = 0.5  # reaches: the radius about the first joint the camera frames besides the arm, room for it to move
_VISIBLE_GROUPS = 3  # MuJoCo draws geom groups 0 to 2 unless told otherwise


def staging(model: mujoco.MjModel) -> tuple[tuple[str, ...], str]:
    """What the scene adds to the model (of floor, sky, lights and camera: those it lacks), and its camera, in
    words."""
    lacks = {"floor": not (model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE).any(),
             "sky": not (model.tex_type == mujoco.mjtTexture.mjTEXTURE_SKYBOX).any(),
             "lights": model.nlight == 0, "camera": model.ncam == 0}
    camera = (f"'{CAMERA}' (added, framing the arm at its reference pose and half its reach)" if model.ncam == 0
              else f"'{model.camera(0).name}' (the model's, of {model.ncam})")
    return tuple(what for what, missing in lacks.items() if missing), camera


def stage(spec: mujoco.MjSpec, model: mujoco.MjModel, arm: DerivedArm) -> None:
    """Add to `spec` what DerivedArm.added names, as the module's docstring says."""
    data = _reference(model, arm)
    root = model.body_rootid[model.joint(arm.chain.joints[0]).bodyid[0]]
    if {"floor", "sky"} & set(arm.added):
        _keep_textures(spec)
    if "floor" in arm.added:
        _floor(spec, data.xpos[root])
    if "sky" in arm.added:
        _sky(spec)
    if "lights" in arm.added:
        _lights(spec, data.xpos[root], arm.chain.reach)
    if "camera" in arm.added:
        anchor = data.xanchor[model.joint(arm.chain.base).id]
        _camera(spec, np.vstack([_arm_corners(model, data, root), _room(anchor, arm.chain.reach, data.xpos[root][2])]))


def _keep_textures(spec: mujoco.MjSpec) -> None:
    """Discard now what the model's `discardvisual` (which MuJoCo's URDF reader sets) would discard when compiling,
    its visual geoms, materials and textures, and clear it, so that the compile keeps the stage's textures."""
    if not spec.compiler.discardvisual:
        return
    for element in [*(g for g in spec.geoms if not (g.contype or g.conaffinity)), *spec.materials, *spec.textures]:
        spec.delete(element)
    for geom in spec.geoms:
        geom.material = ""
    spec.compiler.discardvisual = False


def _floor(spec: mujoco.MjSpec, base: np.ndarray) -> None:
    """An endless checker floor (the shipped scenes' groundplane) through the root body's origin `base`; it collides
    with the arm (contype and conaffinity 1), so that the arm touching it is a contact."""
    spec.add_texture(name=FLOOR, type=mujoco.mjtTexture.mjTEXTURE_2D, builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
                     mark=mujoco.mjtMark.mjMARK_EDGE, rgb1=[0.2, 0.3, 0.4], rgb2=[0.1, 0.2, 0.3],
                     markrgb=[0.8, 0.8, 0.8], width=300, height=300)
    material = spec.add_material(name=FLOOR, texuniform=True, texrepeat=[5, 5], reflectance=0.2)
    material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = FLOOR
    spec.worldbody.add_geom(name=FLOOR, type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05], pos=base,
                            material=FLOOR, contype=1, conaffinity=1)


def _sky(spec: mujoco.MjSpec) -> None:
    """The shipped scenes' gradient skybox and haze."""
    spec.add_texture(name="simbench/sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, rgb1=[0.3, 0.5, 0.7], rgb2=[0, 0, 0], width=512,
                     height=3072)
    spec.visual.rgba.haze = [0.15, 0.25, 0.35, 1]


def _lights(spec: mujoco.MjSpec, base: np.ndarray, reach: float) -> None:
    """The shipped scenes' key light (casting shadows) and fill light, directional, placed a few reaches from the
    root body's origin `base` (where their shadows are cast from), and their headlight."""
    for name, where, towards, diffuse, shadow in (("key", [1, -1, 2], [-0.4, 0.4, -1], 0.7, True),
                                                   ("fill", [-1, 1, 1.5], [0.5, -0.3, -1], 0.3, False)):
        spec.worldbody.add_light(name=f"simbench/{name}", type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
                                 pos=base + reach * np.array(where), dir=towards, diffuse=[diffuse] * 3,
                                 castshadow=shadow)
    headlight = spec.visual.headlight
    headlight.diffuse, headlight.ambient, headlight.specular = [0.6] * 3, [0.3] * 3, [0.0] * 3


def _camera(spec: mujoco.MjSpec, points: np.ndarray) -> None:
    """A camera from the front right and above, aimed at the middle of `points` (n, 3) and as near as holds them
    within _FILL of its view (of aspect _ASPECT); the free camera made the same where the model leaves its statistic
    unset (MuJoCo's free camera looks at the statistic's centre from 1.5 extents)."""
    right = np.cross(-_AWAY, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    axes = np.column_stack([right, np.cross(_AWAY, right), _AWAY])
    local = points @ axes
    centre = axes @ ((local.min(axis=0) + local.max(axis=0)) / 2)
    x, y, z = ((points - centre) @ axes).T
    half_view = _FILL * np.tan(np.deg2rad(_FOVY / 2))
    distance = float(np.max(z + np.maximum(np.abs(x) / _ASPECT, np.abs(y)) / half_view))
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, axes.ravel())
    spec.worldbody.add_camera(name=CAMERA, pos=centre + _AWAY * distance, quat=quat, fovy=_FOVY)
    if np.isnan(spec.stat.extent):
        spec.stat.center, spec.stat.extent = centre, distance / 1.5
        spec.visual.global_.fovy = _FOVY
        spec.visual.global_.azimuth = float(np.rad2deg(np.arctan2(-_AWAY[1], -_AWAY[0])))
        spec.visual.global_.elevation = float(np.rad2deg(np.arcsin(-_AWAY[2])))


def _arm_corners(model: mujoco.MjModel, data: mujoco.MjData, root: int) -> np.ndarray:
    """The corners of the boxes of the arm's visible geoms (those of the tree of body `root`, but planes) where
    `data` puts them, (n, 3)."""
    ours = (model.body_rootid[model.geom_bodyid] == root) & (model.geom_group < _VISIBLE_GROUPS) & (
        model.geom_type != mujoco.mjtGeom.mjGEOM_PLANE)
    corners = [np.zeros((0, 3))]
    for g in np.flatnonzero(ours):
        middle, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        box = np.array(list(product(*zip(middle - half, middle + half))))
        corners.append(data.geom_xpos[g] + box @ data.geom_xmat[g].reshape(3, 3).T)
    return np.vstack(corners)


def _room(anchor: np.ndarray, reach: float, floor: float) -> np.ndarray:
    """Points of the sphere of _ROOM reaches about the first joint's `anchor`, those below the height `floor` raised
    to it, (26, 3): where the arm works, framed so that moving it stays in view."""
    ways = np.array([way for way in product((-1, 0, 1), repeat=3) if any(way)], float)
    points = anchor + _ROOM * reach * ways / np.linalg.norm(ways, axis=1, keepdims=True)
    points[:, 2] = np.maximum(points[:, 2], floor)
    return points


def _reference(model: mujoco.MjModel, arm: DerivedArm) -> mujoco.MjData:
    """The model's kinematics at its reference pose (qpos0), the chain's joints clipped into their ranges."""
    data = mujoco.MjData(model)
    for name, lo, hi in zip(arm.chain.joints, arm.chain.lower, arm.chain.upper):
        adr = model.joint(name).qposadr[0]
        data.qpos[adr] = np.clip(data.qpos[adr], lo, hi)
    mujoco.mj_kinematics(model, data)
    return data
