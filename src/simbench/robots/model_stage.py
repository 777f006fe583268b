"""The stage a derived arm is shown on: the floor, light and camera its model lacks (robots.model_scene)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np

if TYPE_CHECKING:
    from simbench.robots.model_scene import DerivedArm

CAMERA = "simbench/view"
_FOVY = 45.0  # deg, the added camera's (MuJoCo's default)


def staging(model: mujoco.MjModel) -> tuple[tuple[str, ...], str]:
    """What the scene adds to the model (of floor, light and camera: those it lacks), and its camera, in words."""
    added = [what for what, missing in (("floor", not (model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE).any()),
                                        ("light", model.nlight == 0), ("camera", model.ncam == 0)) if missing]
    camera = (f"'{CAMERA}' (added, framing the reach)" if model.ncam == 0
              else f"'{model.camera(0).name}' (the model's, of {model.ncam})")
    return tuple(added), camera


def stage(spec: mujoco.MjSpec, model: mujoco.MjModel, arm: DerivedArm) -> None:
    """The floor, light and camera the model lacks (DerivedArm.added): the floor at the chain's root body, the
    camera at 2.6 reaches (the distance at which MuJoCo's 45 degree view holds a sphere of one reach) from the first
    joint, looking at it from the front right and above."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    first = model.joint(arm.chain.joints[0])
    centre = data.xanchor[first.id].copy()
    root = data.xpos[model.body_rootid[first.bodyid[0]]]
    reach = arm.chain.reach
    if "floor" in arm.added:
        spec.worldbody.add_geom(name="simbench/floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05],
                                pos=[centre[0], centre[1], root[2]], rgba=[0.35, 0.4, 0.45, 1], contype=0,
                                conaffinity=0)
    if "light" in arm.added:
        spec.worldbody.add_light(name="simbench/light", pos=centre + [0, 0, 3 * reach], dir=[0, 0, -1],
                                 type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)
    if "camera" in arm.added:
        away = np.array([1.0, -1.0, 0.7]) / np.linalg.norm([1.0, -1.0, 0.7])
        position = centre + away * reach / np.sin(np.deg2rad(_FOVY / 2))
        right = np.cross(-away, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, np.column_stack([right, np.cross(away, right), away]).ravel())
        spec.worldbody.add_camera(name=CAMERA, pos=position, quat=quat, fovy=_FOVY)
