"""An arm's MJCF model made into a scene simbench runs (MjSpec), with what was done to it said.

Every chain joint (robots.chain) ends with exactly one position servo of unit gear: the model's own, kept; else one
added with gains Kp = I w^2, Kd = 2 zeta I w (computed_torque.pd_gains), I the joint's effective inertia at the
start (the joint-space inertia's diagonal at qpos0 clipped into the ranges), w the `bandwidth` (rad/s) and zeta the
`damping_ratio`. Any other actuator on a chain joint is replaced by such a servo, its force bound carried over (a
motor's control range times its gear), as is the joint's own. The scene also gets a tool site where needed, a
`framepos` sensor on it, gravity compensation on the bodies the chain moves (unless turned off), and where the
model lacks them a floor, a light and a camera framing the reach (robots.model_stage).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from simbench.computed_torque import pd_gains
from simbench.robots.chain import ArmError, Chain, Tool, actuator_kind, actuators_of, chain_of, qpos0_outside
from simbench.robots.model_file import read_spec
from simbench.robots.model_stage import stage, staging

TOOL_SITE = "simbench/tool"  # the site added at a tool given by body and offset
TOOL_SENSOR = "simbench/tool_pos"


@dataclass(frozen=True)
class ArmOptions:
    """A robot mapping's choices about its model (SI): the tool, the joints (None: the chain's), per-joint force
    limits (None: the model's), the added servos' bandwidth (rad/s) and damping ratio, gravity compensation, and a
    URDF's package folders (name, absolute path; robots.model_file)."""

    tool: Tool | None = None
    joints: tuple[str, ...] | None = None
    force_limits: tuple[float, ...] | None = None
    bandwidth: float = 50.0
    damping_ratio: float = 1.0
    gravity_compensation: bool = True
    packages: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True)
class Drive:
    """How one joint of the chain is driven: `action` kept, added or replaced; `found` what actuated it in the model
    ('' for nothing); `keep` the model's position servo kept (None: one is added); `removed` the model's actuators
    taken off it; the servo's gains (SI) and force bound (inf: none)."""

    joint: str
    action: str
    found: str
    keep: int | None
    removed: tuple[int, ...]
    kp: float
    kv: float
    force_limit: float

    def describe(self) -> str:
        bound = "no force limit" if np.isinf(self.force_limit) else f"force limit {self.force_limit:g}"
        servo = f"position servo kp {self.kp:.4g}, kv {self.kv:.4g} ({bound})"
        if self.action == "kept":
            return f"kept its {servo}"
        if self.action == "added":
            return f"no actuator: added a {servo}"
        if self.keep is not None:
            return f"kept its {servo}; removed its {self.found}"
        return f"{self.found} replaced by a {servo}"


@dataclass(frozen=True)
class DerivedArm:
    """What simbench made of a model file: its chain, how each joint is driven, what the scene adds, and what was
    dropped from the file (`dropped`: robots.model_file's notes)."""

    path: str
    name: str
    chain: Chain
    drives: tuple[Drive, ...]
    camera: str
    added: tuple[str, ...]
    outside: tuple[str, ...]
    options: ArmOptions
    dropped: tuple[str, ...] = ()

    def notes(self) -> list[str]:
        """One line for each actuator the scene does not run as the model has it."""
        return [f"{d.joint}: {d.describe()}" for d in self.drives if d.action != "kept"]

    def spec(self) -> mujoco.MjSpec:
        """The scene (built anew at each call: compiling changes a spec)."""
        return _scene(self)


def derive(path: str, options: ArmOptions) -> DerivedArm:
    """The arm in the MJCF or URDF at `path` (absolute), as `options` ask; ArmError naming the field at fault."""
    spec, dropped = read_spec(path, options.packages)
    name = spec.modelname or Path(path).stem
    try:
        model = spec.compile()
    except ValueError as err:
        raise ArmError("model", f"MuJoCo cannot load it: {str(err).strip().splitlines()[0]}") from None
    chain = chain_of(model, options.tool, options.joints)
    limits = _force_limits(options, chain)
    inertia = _start_inertia(model, chain)
    drives = tuple(_drive(model, name, inertia[i], options, limits[i]) for i, name in enumerate(chain.joints))
    added, camera = staging(model)
    return DerivedArm(path=path, name=name, chain=chain, drives=drives, camera=camera, added=added,
                      outside=tuple(qpos0_outside(model, chain)), options=options, dropped=dropped)


def _force_limits(options: ArmOptions, chain: Chain) -> tuple[float | None, ...]:
    """The force limits asked for, one per joint (None: the model's)."""
    if options.force_limits is None:
        return (None,) * len(chain.joints)
    if len(options.force_limits) != len(chain.joints):
        raise ArmError("force_limits", f"expected {len(chain.joints)} values, one per joint "
                                       f"({', '.join(chain.joints)}), got {len(options.force_limits)}")
    return options.force_limits


def _start_inertia(model: mujoco.MjModel, chain: Chain) -> np.ndarray:
    """Each chain joint's effective inertia at the start (the module's docstring; armature included)."""
    data = mujoco.MjData(model)
    for name, lo, hi in zip(chain.joints, chain.lower, chain.upper):
        adr = model.joint(name).qposadr[0]
        data.qpos[adr] = np.clip(data.qpos[adr], lo, hi)
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    dofs = [model.joint(name).dofadr[0] for name in chain.joints]
    return full[dofs, dofs]


def _drive(model: mujoco.MjModel, joint: str, inertia: float, options: ArmOptions, limit: float | None) -> Drive:
    """How `joint` is driven: its position servo kept, or one added in place of what it has."""
    found = actuators_of(model, joint)
    kinds = [actuator_kind(model, i) for i in found]
    if "position" in kinds:
        keep = found[kinds.index("position")]
        removed = tuple(i for i in found if i != keep)
        bound = limit if limit is not None else min(_bound(model, keep), _joint_bound(model, joint))
        return Drive(joint, "replaced" if removed else "kept", _names(model, removed), keep, removed,
                     float(model.actuator_gainprm[keep, 0]), float(-model.actuator_biasprm[keep, 2]), bound)
    kp, kv = pd_gains(np.array([inertia]), options.bandwidth, options.damping_ratio)
    bound = limit if limit is not None else min([_bound(model, i) for i in found] + [_joint_bound(model, joint)])
    return Drive(joint, "replaced" if found else "added", _names(model, tuple(found)), None, tuple(found),
                 float(kp[0]), float(kv[0]), bound)


def _joint_bound(model: mujoco.MjModel, joint: str) -> float:
    """The joint's actuatorfrcrange bound (a URDF's `effort`); inf where unbounded."""
    j = model.joint(joint).id
    return float(np.abs(model.jnt_actfrcrange[j]).min()) if model.jnt_actfrclimited[j] else float(np.inf)


_WORDS = {"position": "position servo", "velocity": "velocity servo", "motor": "motor", "general": "general actuator"}


def _names(model: mujoco.MjModel, which: tuple[int, ...]) -> str:
    """The actuators `which`, each as its kind and name."""
    return " and ".join(f"{_WORDS[actuator_kind(model, i)]} '{model.actuator(i).name or i}'" for i in which)


def _bound(model: mujoco.MjModel, i: int) -> float:
    """Actuator i's force bound: its force range, else a motor's control range times its gear; else inf."""
    if model.actuator_forcelimited[i]:
        return float(np.abs(model.actuator_forcerange[i]).min())
    if actuator_kind(model, i) == "motor" and model.actuator_ctrllimited[i]:
        return float(np.abs(model.actuator_ctrlrange[i]).min() * abs(model.actuator_gear[i, 0]))
    return float(np.inf)


def _scene(arm: DerivedArm) -> mujoco.MjSpec:
    """The scene of DerivedArm.spec."""
    spec = read_spec(arm.path, arm.options.packages)[0]
    model = spec.compile()
    actuators = list(spec.actuators)
    for i in sorted({i for drive in arm.drives for i in drive.removed}, reverse=True):
        spec.delete(actuators[i])
    taken = {a.name for a in spec.actuators}
    for drive, lo, hi in zip(arm.drives, arm.chain.lower, arm.chain.upper):
        if drive.keep is not None:
            actuator = actuators[drive.keep]
        else:
            actuator = spec.add_actuator(name=drive.joint if drive.joint not in taken else f"simbench/{drive.joint}",
                                         target=drive.joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
            actuator.set_to_position(kp=drive.kp, kv=drive.kv)
            actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE if np.isfinite(hi - lo) else 0
            actuator.ctrlrange = [lo, hi] if np.isfinite(hi - lo) else [0, 0]
        if np.isfinite(drive.force_limit):
            actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            actuator.forcerange = [-drive.force_limit, drive.force_limit]
    site = arm.chain.tool.site
    if site is None:
        site = TOOL_SITE
        spec.body(arm.chain.tool.body).add_site(name=site, pos=list(arm.chain.tool.offset))
    spec.add_sensor(name=TOOL_SENSOR, type=mujoco.mjtSensor.mjSENS_FRAMEPOS, objtype=mujoco.mjtObj.mjOBJ_SITE,
                    objname=site)
    if arm.options.gravity_compensation:  # on the first joint's body and every body below it
        moved = spec.body(model.body(model.jnt_bodyid[model.joint(arm.chain.joints[0]).id]).name)
        for body in [moved, *moved.find_all(mujoco.mjtObj.mjOBJ_BODY)]:
            body.gravcomp = 1.0
    stage(spec, model, arm)
    return spec
