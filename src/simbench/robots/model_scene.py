"""An arm's MJCF model made into a scene simbench runs (MjSpec), with what was done to it said: a plant a controls
engineer would sign off, the model's kinematics and inertias untouched.

Every chain joint (robots.chain) ends with exactly one position servo of unit gear: the model's own, kept; else one
added (no control range: the joint's own range holds the joint, and the servo's feed-forward may command past it).
A run designs the added servos' gains for its plan (simbench.robots.servo_design); the scene's own, used where no plan
is given (`inspect`), are Kp = I w^2, Kd = 2 zeta I w, I the joint's inertia at the reference pose (qpos0 clipped
into the ranges), w the `bandwidth` (DEFAULT_BANDWIDTH unless asked) and zeta the `damping_ratio`. Any other
actuator on a chain joint is replaced by such a servo, its force bound carried over (a motor's control range times
its gear), as is the joint's own.

The scene also:
  - locks every other joint of the arm's trees (a gripper's fingers, a joint `joints:` leaves out) at its
    reference position: a joint nothing drives would swing free, its tiny inertia making the servos' coupled
    dynamics stiff;
  - integrates with `implicitfast` where the model leaves MuJoCo's default Euler, so that the servos' damping is
    implicit and stable at any gain, as MuJoCo Menagerie's arms do;
  - excludes from collision every pair of bodies whose geoms touch at the reference pose (qpos0 and a `home`
    keyframe), as Menagerie's models exclude touching meshes: a URDF's base and shoulder meshes often overlap in
    every configuration, a pair with the world body MuJoCo does not filter;
  - gets a tool site where needed (at a body's offset, or where the tool's frame is turned: the site's own frame,
    or the body's, times the rotation, so that the tool's orientation everywhere is the turned frame), a
    `framepos` sensor on it, gravity compensation on the bodies the chain moves
    (unless turned off), and where the model lacks them a floor, sky, lights and camera (robots.model_stage).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import mujoco
import numpy as np

from simbench.core.faults import quiet_mujoco
from simbench.robots.chain import (ArmError, Chain, Tool, actuator_kind, actuators_of, chain_of, on_joint,
                                   qpos0_outside)
from simbench.robots.contacts import Contacts
from simbench.robots.model_file import compiled, read_spec
from simbench.robots.model_stage import stage, staging
from simbench.robots.servo_design import DEFAULT_BANDWIDTH, pd_gains

TOOL_SITE = "simbench/tool"  # the site added at a tool given by body and offset, or turned
TOOL_SENSOR = "simbench/tool_pos"


@dataclass(frozen=True)
class ArmOptions:
    """A robot mapping's choices about its model (SI): the arm's name (None: the model's own, else its file's
    stem), the tool, the joints (None: the chain's), per-joint force limits (None: the model's), the added servos'
    least bandwidth (rad/s; None: DEFAULT_BANDWIDTH) and damping ratio, gravity compensation, a URDF's package
    folders (name, absolute path; robots.model_file), and the digest of the model's files
    (robots.model_file.fingerprint) the arm was derived from: so that whatever is keyed by the options (the derived
    arm, its registered scene) is made anew when a file changes."""

    name: str | None = None
    tool: Tool | None = None
    joints: tuple[str, ...] | None = None
    force_limits: tuple[float, ...] | None = None
    bandwidth: float | None = None
    damping_ratio: float = 1.0
    gravity_compensation: bool = True
    packages: tuple[tuple[str, str], ...] = ()
    digest: str = ""


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
        if self.keep is None:
            servo = f"position servo ({bound}; its gains designed for each plan: simbench.robots.servo_design)"
            return f"no actuator: added a {servo}" if self.action == "added" else f"{self.found} replaced by a {servo}"
        servo = f"position servo kp {self.kp:.4g}, kv {self.kv:.4g} ({bound})"
        return f"kept its {servo}" if self.action == "kept" else f"kept its {servo}; removed its {self.found}"


@dataclass(frozen=True)
class DerivedArm:
    """What simbench made of a model file: its chain, how each joint is driven, what the scene adds, what was
    dropped from the file (`dropped`: robots.model_file's notes), the joints locked, the body pairs excluded from
    collision (touching at the reference pose) and the integrator, in words (the module's docstring)."""

    path: str
    name: str
    chain: Chain
    drives: tuple[Drive, ...]
    camera: str
    added: tuple[str, ...]
    outside: tuple[str, ...]
    options: ArmOptions
    dropped: tuple[str, ...] = ()
    locked: tuple[str, ...] = ()
    excluded: tuple[tuple[str, str], ...] = ()
    integrator: str = ""

    def notes(self) -> list[str]:
        """One line for each actuator the scene does not run as the model has it."""
        return [f"{d.joint}: {d.describe()}" for d in self.drives if d.action != "kept"]

    @property
    def designed(self) -> np.ndarray:
        """Which chain joints' servos simbench added (their gains designed for each plan), (dof,) bool."""
        return np.array([d.keep is None for d in self.drives])

    @property
    def tool_site(self) -> str:
        """The scene's site at the tool: the model's own where the tool is one, unturned; else the one added."""
        tool = self.chain.tool
        return tool.site if tool.site is not None and not tool.rotated else TOOL_SITE

    def contacts(self, model: mujoco.MjModel) -> Contacts:
        """Contact queries of the arm on its compiled scene `model`."""
        return Contacts(model, self.chain.joints)

    def spec(self) -> mujoco.MjSpec:
        """The scene (built anew at each call: compiling changes a spec)."""
        return _scene(self)


def derive(path: str, options: ArmOptions) -> DerivedArm:
    """The arm in the MJCF or URDF at `path` (absolute), as `options` ask; ArmError naming the field at fault."""
    spec, dropped = read_spec(path, options.packages)
    name = options.name or spec.modelname or Path(path).stem
    model = compiled(spec)
    chain = chain_of(model, options.tool, options.joints)
    limits = _force_limits(options, chain)
    with quiet_mujoco():
        inertia = _start_inertia(model, chain)
    actuators = actuators_of(model, chain.joints)
    drives = tuple(_drive(model, name, actuators[name], inertia[i], options, limits[i])
                   for i, name in enumerate(chain.joints))
    added, camera = staging(model)
    euler = model.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER
    named = mujoco.mjtIntegrator(model.opt.integrator).name.removeprefix("mjINT_").lower()
    integrator = ("implicitfast (the model's: Euler, whose servo damping is explicit)" if euler
                  else f"{named} (the model's)")
    arm = DerivedArm(path=path, name=name, chain=chain, drives=drives, camera=camera, added=added,
                     outside=tuple(qpos0_outside(model, chain)), options=options, dropped=dropped,
                     locked=_locked(model, chain), integrator=integrator)
    return replace(arm, excluded=_touching(arm))


def _locked(model: mujoco.MjModel, chain: Chain) -> tuple[str, ...]:
    """The joints of the arm's trees that the chain does not drive (module docstring), by name (or index)."""
    roots = {model.body_rootid[model.joint(name).bodyid[0]] for name in chain.joints}
    return tuple(model.joint(j).name or str(j) for j in range(model.njnt)
                 if model.body_rootid[model.jnt_bodyid[j]] in roots and model.joint(j).name not in chain.joints)


def _touching(arm: DerivedArm) -> tuple[tuple[str, str], ...]:
    """The body pairs of the arm's own geoms touching at the reference pose: qpos0, and a `home` keyframe's (not
    the floor's: an arm whose reference pose dips into the floor keeps colliding with it)."""
    model = compiled(arm.spec())
    contacts = arm.contacts(model)
    homes = [model.key_qpos[k] for k in range(model.nkey) if model.key(k).name == "home"]
    with quiet_mujoco():
        return tuple(sorted({tuple(sorted(touch.bodies)) for qpos in [model.qpos0, *homes]
                             for touch in contacts.at_qpos(qpos) if touch.within}))


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


def _drive(model: mujoco.MjModel, joint: str, found: list[int], inertia: float, options: ArmOptions,
           limit: float | None) -> Drive:
    """How `joint` is driven: its position servo kept, or one added in place of what it has (`found`: the
    actuators that move it, chain.actuators_of)."""
    kinds = [actuator_kind(model, i) if on_joint(model, i) else "tendon or site" for i in found]
    if "position" in kinds:
        keep = found[kinds.index("position")]
        removed = tuple(i for i in found if i != keep)
        bound = limit if limit is not None else min(_bound(model, keep), _joint_bound(model, joint))
        return Drive(joint, "replaced" if removed else "kept", _names(model, removed), keep, removed,
                     float(model.actuator_gainprm[keep, 0]), 0.0 - float(model.actuator_biasprm[keep, 2]), bound)
    kp, kv = pd_gains(np.array([inertia]), options.bandwidth or DEFAULT_BANDWIDTH, options.damping_ratio)
    bound = limit if limit is not None else min([_bound(model, i) for i in found] + [_joint_bound(model, joint)])
    return Drive(joint, "replaced" if found else "added", _names(model, tuple(found)), None, tuple(found),
                 float(kp[0]), float(kv[0]), bound)


def _joint_bound(model: mujoco.MjModel, joint: str) -> float:
    """The joint's actuatorfrcrange bound (a URDF's `effort`); inf where unbounded."""
    j = model.joint(joint).id
    return float(np.abs(model.jnt_actfrcrange[j]).min()) if model.jnt_actfrclimited[j] else float(np.inf)


_WORDS = {"position": "position servo", "velocity": "velocity servo", "motor": "motor", "general": "general actuator"}


def _names(model: mujoco.MjModel, which: tuple[int, ...]) -> str:
    """The actuators `which`, each as its kind and name (and what it drives, where that is not the joint)."""
    def named(i: int) -> str:
        words = f"{_WORDS[actuator_kind(model, i)]} '{model.actuator(i).name or i}'"
        if on_joint(model, i):
            return words
        trn = mujoco.mjtTrn(model.actuator_trntype[i]).name.removeprefix("mjTRN_").lower()
        return f"{words} (on a {trn} that moves it)"
    return " and ".join(named(i) for i in which)


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
    model = compiled(spec)
    actuators = list(spec.actuators)  # by the file's indices (Drive.keep, Drive.removed), before any is deleted
    _lock(spec, model, arm.locked)
    if model.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER:
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    for body1, body2 in arm.excluded:
        spec.add_exclude(bodyname1=body1, bodyname2=body2)
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
            actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        if np.isfinite(drive.force_limit):
            actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            actuator.forcerange = [-drive.force_limit, drive.force_limit]
    if arm.tool_site == TOOL_SITE:
        _add_tool_site(spec, model, arm.chain.tool)
    spec.add_sensor(name=TOOL_SENSOR, type=mujoco.mjtSensor.mjSENS_FRAMEPOS, objtype=mujoco.mjtObj.mjOBJ_SITE,
                    objname=arm.tool_site)
    if arm.options.gravity_compensation:  # on the first joint's body and every body below it
        moved = spec.body(model.body(model.jnt_bodyid[model.joint(arm.chain.joints[0]).id]).name)
        for body in [moved, *moved.find_all(mujoco.mjtObj.mjOBJ_BODY)]:
            body.gravcomp = 1.0
    stage(spec, model, arm)
    return spec


def _add_tool_site(spec: mujoco.MjSpec, model: mujoco.MjModel, tool: Tool) -> None:
    """TOOL_SITE on the tool's body: at the offset, turned by the rotation; or, for a site, at the site's place in
    its body (the compiled model's, whatever frames or Euler angles the file states it with) and its orientation
    times the rotation."""
    pos, quat = np.array(tool.offset), np.array(tool.rotation)
    if tool.site is not None:
        site = model.site(tool.site)
        pos = site.pos.copy()
        mujoco.mju_mulQuat(quat, site.quat, np.array(tool.rotation))
    spec.body(tool.body).add_site(name=TOOL_SITE, pos=pos, quat=quat)


def _lock(spec: mujoco.MjSpec, model: mujoco.MjModel, locked: tuple[str, ...]) -> None:
    """Delete the locked joints (their bodies stay where the joints' reference positions put them), with what
    refers to them: tendons over them, actuators on them or on those tendons, equalities and sensors of any of
    these; and their entries in every keyframe, whose controls are dropped with the actuators the scene changes."""
    joints = [model.joint(name).id if not name.isdigit() else int(name) for name in locked]
    if not joints:
        return
    tendons = [t for t in range(model.ntendon) if any(
        model.wrap_type[w] == mujoco.mjtWrap.mjWRAP_JOINT and model.wrap_objid[w] in joints
        for w in range(model.tendon_adr[t], model.tendon_adr[t] + model.tendon_num[t]))]
    on = {int(mujoco.mjtTrn.mjTRN_JOINT): joints, int(mujoco.mjtTrn.mjTRN_JOINTINPARENT): joints,
          int(mujoco.mjtTrn.mjTRN_TENDON): tendons}
    actuators = [a for a in range(model.nu) if model.actuator_trnid[a, 0] in on.get(int(model.actuator_trntype[a]), [])]
    of = {int(mujoco.mjtEq.mjEQ_JOINT): joints, int(mujoco.mjtEq.mjEQ_TENDON): tendons}
    equalities = [e for e in range(model.neq)
                  if {model.eq_obj1id[e], model.eq_obj2id[e]} & set(of.get(int(model.eq_type[e]), []))]
    kinds = {int(mujoco.mjtObj.mjOBJ_JOINT): joints, int(mujoco.mjtObj.mjOBJ_TENDON): tendons,
             int(mujoco.mjtObj.mjOBJ_ACTUATOR): actuators}
    sensors = [i for i in range(model.nsensor) if model.sensor_objid[i] in kinds.get(int(model.sensor_objtype[i]), [])]
    _keyframes(spec, model, joints)
    for elements, ids in ((spec.sensors, sensors), (spec.equalities, equalities), (spec.actuators, actuators),
                          (spec.tendons, tendons), (spec.joints, joints)):
        listed = list(elements)
        for i in sorted(ids, reverse=True):
            spec.delete(listed[i])


def _keyframes(spec: mujoco.MjSpec, model: mujoco.MjModel, joints: list[int]) -> None:
    """Every keyframe without the entries of `joints` (ids) and without controls."""
    keep_qpos, keep_qvel = np.ones(model.nq, bool), np.ones(model.nv, bool)
    for j in joints:
        nq, nv = _sizes(model.jnt_type[j])
        keep_qpos[model.jnt_qposadr[j]:model.jnt_qposadr[j] + nq] = False
        keep_qvel[model.jnt_dofadr[j]:model.jnt_dofadr[j] + nv] = False
    for key in spec.keys:
        if len(key.qpos):
            key.qpos = np.asarray(key.qpos)[keep_qpos]
        if len(key.qvel):
            key.qvel = np.asarray(key.qvel)[keep_qvel]
        key.ctrl = []


def _sizes(kind: int) -> tuple[int, int]:
    """A joint type's (qpos, qvel) sizes."""
    return {mujoco.mjtJoint.mjJNT_FREE: (7, 6), mujoco.mjtJoint.mjJNT_BALL: (4, 3)}.get(kind, (1, 1))
