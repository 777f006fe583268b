"""What simbench reads from an arm's MJCF model's arrays: the chain of hinge and slide joints from the world to the
tool (a joint without a range is continuous), the tool, the reach, and each actuator's kind, read from its gain and
bias, never assumed:

    position servo   force = kp ctrl - kp q - kv qd   (gain fixed kp, bias affine [0, -kp, -kv], unit gear)
    velocity servo   force = kv ctrl - kv qd          (gain fixed kv, bias affine [0, 0, -kv])
    motor            force = gear ctrl                (gain fixed, no bias)

and anything else (activation dynamics, a non-unit gear on a servo) is a general actuator. Errors are ArmError.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import mujoco
import numpy as np

from simbench.api import PRISMATIC, REVOLUTE

_KINDS = {int(mujoco.mjtJoint.mjJNT_HINGE): REVOLUTE, int(mujoco.mjtJoint.mjJNT_SLIDE): PRISMATIC}


class ArmError(ValueError):
    """A model or a robot mapping that does not make an arm: the mapping's field at fault, and why."""

    def __init__(self, field: str, message: str):
        self.field = field
        super().__init__(message)


class SeveralEnds(ArmError):
    """A model whose longest chain ends in several bodies (`ends`, by name), none named the tool: `inspect` lists
    them for the user to choose one."""

    def __init__(self, ends: tuple[str, ...]):
        self.ends = ends
        super().__init__("tool", f"no single end of the model's longest chain ({', '.join(ends)}): name the tool, "
                                 "tool: {site: NAME} or {body: NAME, offset: [x, y, z]}")


IDENTITY = (1.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Tool:
    """The tool frame: an existing site of the model, or a point `offset` (m, body frame) on a body, turned by
    `rotation` (a unit quaternion w x y z) after the site's or the body's frame; simbench adds a site for a body's
    point or a turned frame (robots.model_scene)."""

    body: str
    site: str | None = None
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple[float, float, float, float] = IDENTITY

    @property
    def rotated(self) -> bool:
        return self.rotation != IDENTITY

    def describe(self) -> str:
        turned = f", turned by quat {[round(v, 9) for v in self.rotation]} (w x y z)" if self.rotated else ""
        if self.site is not None:
            return f"site '{self.site}' (on body '{self.body}'){turned}"
        return f"body '{self.body}' at offset {list(self.offset)} m{turned}"


@dataclass(frozen=True)
class Chain:
    """The joints from the world to the tool (in the order a robot file's `joints:` gives) with their kinds and
    ranges (SI; +-inf: continuous), the tool, the joint nearest the world (`base`: whatever the order, the reach is
    measured from its anchor, which none of the joints moves), and the reach L that makes the Jacobian's units
    consistent (robots.model_arm): the polyline through the joints' anchors, from the world on, to the tool point at
    qpos0, plus each slide joint's stroke."""

    joints: tuple[str, ...]
    kinds: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    tool: Tool
    reach: float
    base: str


def chain_of(model: mujoco.MjModel, tool: Tool | None, joints: tuple[str, ...] | None) -> Chain:
    """The chain to `tool` (None: the end of the model's longest chain, its first site if it has one), or the
    joints `joints` of that chain in the order given."""
    tool = _tool(model, tool)
    on_chain = _joints_to(model, model.body(tool.body).id)
    if joints is not None:
        names = [model.joint(j).name for j in on_chain]
        for name in joints:
            if name not in names:
                raise ArmError("joints", f"'{name}' is not a joint of the chain from the world to the tool "
                                         f"({', '.join(names) or 'none'})")
        if len(set(joints)) != len(joints):
            raise ArmError("joints", "names a joint twice")
        on_chain = [model.joint(name).id for name in joints]
    if not on_chain:
        raise ArmError("tool", f"no hinge or slide joint moves the tool ({tool.describe()})")
    for j in on_chain:
        if int(model.jnt_type[j]) not in _KINDS:
            kind = mujoco.mjtJoint(model.jnt_type[j]).name.removeprefix("mjJNT_").lower()
            raise ArmError("tool", f"joint '{model.joint(j).name}' on the chain to the tool is a {kind} joint: "
                                   "simbench drives hinge and slide joints")
        if not model.joint(j).name:
            raise ArmError("model", f"joint {j} on the chain to the tool has no name: name it in the model")
    limited = model.jnt_limited[on_chain].astype(bool)
    ranges = model.jnt_range[on_chain]
    return Chain(joints=tuple(model.joint(j).name for j in on_chain),
                 kinds=tuple(_KINDS[int(model.jnt_type[j])] for j in on_chain),
                 lower=np.where(limited, ranges[:, 0], -np.inf), upper=np.where(limited, ranges[:, 1], np.inf),
                 tool=tool, reach=_reach(model, sorted(on_chain), tool),  # (ids rise from the world to the tool)
                 base=model.joint(min(on_chain)).name)


def _joints_to(model: mujoco.MjModel, body: int) -> list[int]:
    """The joints between the world and `body`, from the world on (a body's own in their order in the model)."""
    found: list[int] = []
    while body > 0:
        first, count = model.body_jntadr[body], model.body_jntnum[body]
        found[:0] = range(first, first + count)
        body = model.body_parentid[body]
    return found


def _tool(model: mujoco.MjModel, tool: Tool | None) -> Tool:
    """The tool as asked (checked against the model), or the default one."""
    if tool is None:
        return _default_tool(model)
    if tool.site is not None:
        site = _named(model, mujoco.mjtObj.mjOBJ_SITE, tool.site, "tool.site", "site")
        body = model.body(model.site_bodyid[site]).name
        if tool.rotated and not body:
            raise ArmError("tool.site", f"site '{tool.site}' is on a body without a name: name the body in the "
                                        "model for the tool's frame to be turned on it")
        return replace(tool, body=body)
    _named(model, mujoco.mjtObj.mjOBJ_BODY, tool.body, "tool.body", "body")
    return tool


def _named(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str, field: str, what: str) -> int:
    """The id of the model's `what` called `name`; ArmError naming `field` if there is none."""
    found = mujoco.mj_name2id(model, kind, name)
    if found < 0:
        raise ArmError(field, f"no {what} '{name}' in the model")
    return found


def _default_tool(model: mujoco.MjModel) -> Tool:
    """The body with the most joints between it and the world (the one deepest in the tree where several have as
    many) at its first site, or at its origin; ArmError where two chains are as long (a hand's fingers)."""
    depth = np.zeros(model.nbody, int)
    joints = np.zeros(model.nbody, int)
    for b in range(1, model.nbody):
        parent = model.body_parentid[b]
        depth[b], joints[b] = depth[parent] + 1, joints[parent] + model.body_jntnum[b]
    best = [b for b in range(1, model.nbody) if joints[b] == joints.max()]
    best = [b for b in best if depth[b] == depth[best].max()]
    if joints.max() == 0:
        raise ArmError("tool", "no hinge or slide joint in the model: nothing moves a tool")
    if len(best) > 1:
        raise SeveralEnds(tuple(model.body(b).name or f"body {b}" for b in best))
    body = best[0]
    sites = np.flatnonzero(model.site_bodyid == body)
    if len(sites) and model.site(sites[0]).name:
        return Tool(body=model.body(body).name, site=model.site(sites[0]).name)
    return Tool(body=model.body(body).name)


def _reach(model: mujoco.MjModel, joints: list[int], tool: Tool) -> float:
    """The chain's length at qpos0, and the slide joints' strokes (Chain.reach); at least 1 mm."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    if tool.site is not None:
        end = data.site(tool.site).xpos
    else:
        end = data.body(tool.body).xpos + data.body(tool.body).xmat.reshape(3, 3) @ np.asarray(tool.offset)
    points = np.vstack([data.xanchor[joints], end])
    length = float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())
    for j in joints:
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE and model.jnt_limited[j]:
            length += float(np.ptp(model.jnt_range[j]))
    return max(length, 1e-3)


def actuator_kind(model: mujoco.MjModel, i: int) -> str:
    """What actuator i is, from its dynamics, gain, bias and gear: 'position', 'velocity', 'motor' or 'general'."""
    if (model.actuator_dyntype[i] != mujoco.mjtDyn.mjDYN_NONE
            or model.actuator_gaintype[i] != mujoco.mjtGain.mjGAIN_FIXED):
        return "general"
    gain, bias = model.actuator_gainprm[i, 0], model.actuator_biasprm[i, :3]
    if model.actuator_biastype[i] == mujoco.mjtBias.mjBIAS_NONE:
        return "motor"
    if model.actuator_biastype[i] != mujoco.mjtBias.mjBIAS_AFFINE or bias[0] != 0 or gain == 0:
        return "general"
    unit_gear = model.actuator_gear[i, 0] == 1
    if unit_gear and np.isclose(bias[1], -gain) and bias[2] <= 0:
        return "position"
    if bias[1] == 0 and np.isclose(bias[2], -gain):
        return "velocity"
    return "general"


def actuators_of(model: mujoco.MjModel, joints: tuple[str, ...]) -> dict[str, list[int]]:
    """Each joint's actuators, those that move it: the ones whose transmission is the joint, and those whose
    transmission is something else (a tendon, a site) with a moment on the joint's DOF at qpos0 (MuJoCo's
    actuator_moment, found once for all the joints)."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    moment = np.zeros((model.nu, model.nv))
    mujoco.mju_sparse2dense(moment, data.actuator_moment, data.moment_rownnz, data.moment_rowadr,
                            data.moment_colind)
    found = {}
    for joint in joints:
        j = model.joint(joint).id
        dof = model.jnt_dofadr[j]
        found[joint] = [i for i in range(model.nu) if (model.actuator_trnid[i, 0] == j if on_joint(model, i)
                                                       else moment[i, dof] != 0)]
    return found


def on_joint(model: mujoco.MjModel, i: int) -> bool:
    """Whether actuator i's transmission is a joint (the one servo of a joint simbench may keep)."""
    return model.actuator_trntype[i] == mujoco.mjtTrn.mjTRN_JOINT


def qpos0_outside(model: mujoco.MjModel, chain: Chain) -> list[str]:
    """The chain's joints whose reference position (qpos0) lies outside their range."""
    q0 = np.array([model.qpos0[model.joint(name).qposadr[0]] for name in chain.joints])
    return [name for name, q, lo, hi in zip(chain.joints, q0, chain.lower, chain.upper) if not lo <= q <= hi]
