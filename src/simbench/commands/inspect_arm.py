"""`simbench inspect MODEL|ROBOT_FILE|SCENARIO [--at Q] [--units U] [--json]`: what simbench derives from an arm's
model, before a run, in words or as JSON: its joints and speed limits, drives, tool and reach, and where the tool
is at a configuration (the model's reference pose qpos0, a scenario's task.start, or --at): its position, its
orientation and the singular measures there. A model whose longest chain ends in several bodies (no tool named)
lists its joints and the candidate tools, with where each is, for the user to choose one."""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from pydantic import ValidationError

from simbench.api.recording import Recording
from simbench.core.errors import ScenarioError, printable
from simbench.core.frozen import SimbenchModel
from simbench.robots.chain import ArmError, SeveralEnds, Tool, chain_of
from simbench.robots.model_arm import ModelArm
from simbench.robots.model_file import compiled, is_urdf, read_spec, urdf_limits
from simbench.robots.model_scene import ArmOptions, DerivedArm
from simbench.scenario import robot_mapping
from simbench.scenario.schema import JointVector, Units
from simbench.scenario.validation import describe as describe_error
from simbench.scenario.validation import read_yaml

MEASURES = ("sigma_min", "sigma_min_unit", "manipulability", "inverse_condition")  # report.json's names
_UNIT_WORDS = {"rad": "angle", "deg": "angle", "m": "length", "mm": "length"}


@dataclass(frozen=True)
class Joints:
    """The joints inspected (SI ranges, +-inf: continuous) and their speed limits (SI; None where none is
    stated): what a task's joint values are checked against (schema.JointVector reads these names)."""

    joints: tuple[str, ...]
    kinds: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    qd_max: tuple[float | None, ...]

    @property
    def dof(self) -> int:
        return len(self.joints)


@dataclass(frozen=True)
class Frame:
    """A tool's pose at the joint values inspected: the robot file's `tool:` that names it, its position (m) and
    rotation (world frame; columns: the tool frame's axes), and the singular measures there (None: a candidate)."""

    tool: str
    position: np.ndarray
    rotation: np.ndarray
    measures: dict[str, float] | None = None


@dataclass(frozen=True)
class Inspection:
    """What `inspect` shows: the arm derived (None where the chain has several ends), its joints, where the speed
    limits come from (None: a robot file's), the joint values `q` (SI), what they are (`given`) and the units they
    are written in, and the tool's pose there (each candidate's, where the chain has several ends)."""

    name: str
    path: str
    arm: DerivedArm | None
    joints: Joints
    speeds_note: str | None
    given: str
    q: np.ndarray
    units: Units
    frames: tuple[Frame, ...]


class _JointValues(SimbenchModel):
    """Joint values checked as a task's `start` is: one per joint, each in the file's unit and within its range."""

    q: JointVector


def inspect(path: Path, at: str | None = None, units: str | None = None, as_json: bool = False) -> str:
    """What `simbench inspect` prints for `path` (an MJCF or URDF, a robot file or a scenario), the tool posed at
    `at` (joint values, comma-separated, in `units` or else the file's), as text or JSON; ScenarioError for bad
    input."""
    found = inspected(path, at, units)
    return to_json(found) if as_json else text(found)


def inspected(path: Path, at: str | None = None, units: str | None = None) -> Inspection:
    """The Inspection of `path` (inspect)."""
    source = str(path)
    asked = _units_option(units, source)
    if path.suffix.lower() in (".xml", ".urdf"):
        model = robot_mapping.model_path(str(path.absolute()), source, "")
        try:
            arm = robot_mapping.derived(model, ArmOptions())
        except SeveralEnds as err:
            return _ends(model, err, at, asked or Units(), source)
        except ArmError as err:
            raise ScenarioError(source, err.field, str(err)) from None
        stated = urdf_limits(model) if is_urdf(model) else {}
        speeds = tuple(stated.get(joint, (None, None))[0] for joint in arm.chain.joints)
        robot = ModelArm(arm, np.ones(len(speeds)))  # its kinematics alone are asked for
        return _posed(robot, speeds, _speeds_note(speeds, arm.chain.joints, model), None, at, asked or Units(),
                      source)
    raw = read_yaml(path)
    value = raw.get("robot", raw) if isinstance(raw, dict) and "model" not in raw else raw
    if not robot_mapping.is_mapping(value):
        raise ScenarioError(source, "robot", "expected a robot mapping (model, tool, speed_limits), an MJCF or a URDF "
                                             "file: a registered robot is described by `simbench list`")
    file_units = robot_mapping.units_of(raw, source) or Units()
    robot = robot_mapping.load_robot(value if value is not raw else str(path.absolute()), source, file_units)
    task = raw.get("task") if value is not raw else None
    start = task.get("start") if isinstance(task, dict) else None
    scenario_start = None if start is None else (_checked(start, robot, file_units, source, "task.start"), file_units)
    return _posed(robot, tuple(robot.qd_max), None, scenario_start, at, asked or file_units, source)


def _units_option(text: str | None, source: str) -> Units | None:
    """The units --units asks for ('deg', 'mm', 'deg,mm'...), None where not given."""
    if text is None:
        return None
    words = [word.strip() for word in text.split(",")]
    kinds = [_UNIT_WORDS.get(word) for word in words]
    if None in kinds or len(set(kinds)) != len(kinds):
        raise ScenarioError(source, "--units", f"expected an angle unit (rad or deg), a length unit (m or mm) or "
                                               f"both, e.g. deg,mm; got {text!r}")
    return Units.model_validate(dict(zip(kinds, words)))


def _posed(robot: ModelArm, speeds: tuple, speeds_note: str | None, start: tuple[np.ndarray, Units] | None,
           at: str | None, units: Units, source: str) -> Inspection:
    """The Inspection of a derived arm (`robot`), posed at --at, else at the scenario's start, else at qpos0."""
    arm = robot.arm
    chain = arm.chain
    joints = Joints(chain.joints, chain.kinds, chain.lower, chain.upper, speeds)
    if at is not None:
        q, given = _at(at, joints, units, source), "--at"
    elif start is not None:
        (q, units), given = start, "task.start"
    else:
        q, given = _qpos0(compiled(arm.spec()), chain.joints), "qpos0, the model's reference pose"
    rows = q[None]
    frame = Frame(chain.tool.describe(), robot.fk(rows)[0], robot.tool_rotation(rows)[0],
                  {name: float(value[0]) for name, value in robot.measures(_held(robot, rows)).items()})
    return Inspection(arm.name, arm.path, arm, joints, speeds_note, given, q, units, (frame,))


def _ends(path: str, several: SeveralEnds, at: str | None, units: Units, source: str) -> Inspection:
    """The Inspection of a model whose longest chain ends in several bodies: the joints to any of them, and each
    end (its body, and each site on it) posed at --at, else at qpos0. An end without a name cannot be chosen: the
    model is refused as a run would refuse it."""
    spec, _ = read_spec(path)
    name = spec.modelname or Path(path).stem
    model = compiled(spec)
    ends = several.ends
    try:
        if any(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, end) < 0 for end in ends):
            raise several
        chains = [chain_of(model, Tool(body=end), None) for end in ends]
    except ArmError as err:
        raise ScenarioError(source, err.field, str(err)) from None
    found = {joint: (kind, lo, hi) for chain in chains
             for joint, kind, lo, hi in zip(chain.joints, chain.kinds, chain.lower, chain.upper)}
    names = tuple(sorted(found, key=lambda joint: model.joint(joint).id))
    stated = urdf_limits(path) if is_urdf(path) else {}
    speeds = tuple(stated.get(joint, (None, None))[0] for joint in names)
    joints = Joints(names, tuple(found[j][0] for j in names), np.array([found[j][1] for j in names]),
                    np.array([found[j][2] for j in names]), speeds)
    q = _at(at, joints, units, source) if at is not None else _qpos0(model, names)
    data = mujoco.MjData(model)
    data.qpos[[model.joint(joint).qposadr[0] for joint in names]] = q
    mujoco.mj_kinematics(model, data)
    frames = []
    for end in ends:
        body = model.body(end).id
        frames.append(Frame(f"{{body: {end}}}", data.xpos[body].copy(), data.xmat[body].reshape(3, 3).copy()))
        frames += [Frame(f"{{site: {model.site(s).name}}}", data.site_xpos[s].copy(),
                         data.site_xmat[s].reshape(3, 3).copy())
                   for s in np.flatnonzero(model.site_bodyid == body) if model.site(s).name]
    given = "--at" if at is not None else "qpos0, the model's reference pose"
    return Inspection(name, path, None, joints, _speeds_note(speeds, names, path), given, q, units, tuple(frames))


def _at(text: str, joints: Joints, units: Units, source: str) -> np.ndarray:
    """--at's joint values (comma-separated, in `units`) in SI, checked as a task's start is."""
    try:
        values = [float(word) for word in text.split(",")]
    except ValueError:
        values = [np.nan]
    if not np.isfinite(values).all():
        raise ScenarioError(source, "--at", f"expected {joints.dof} finite numbers separated by commas, one per "
                                            f"joint ({', '.join(joints.joints)}), got {text!r}")
    return _checked(values, joints, units, source, "--at")


def _checked(values, joints, units: Units, source: str, field: str) -> np.ndarray:
    """Joint values (a list as a file or --at gives it) in SI; ScenarioError naming `field` unless each is a
    number within its joint's range, one per joint (schema.JointVector)."""
    document = {"q": values}
    try:
        return np.array(_JointValues.model_validate(document, context={"robot": joints, "units": units}).q)
    except ValidationError as err:
        where, message = describe_error(err, _JointValues, document)
        if field == "--at":  # the command line's remedy, not a file's
            message = message.replace("units: {angle: deg}", "--units deg").replace("units: {length: mm}",
                                                                                    "--units mm")
        raise ScenarioError(source, field + where.removeprefix("q"), message) from None


def _qpos0(model: mujoco.MjModel, joints: tuple[str, ...]) -> np.ndarray:
    """The joints' reference positions (MuJoCo's qpos0)."""
    return np.array([model.qpos0[model.joint(joint).qposadr[0]] for joint in joints])


def _held(robot: ModelArm, rows: np.ndarray) -> Recording:
    """The arm held still at each row of `rows` (N, dof), as a recording: what Robot.measures reads (its qpos: the
    chain's joints)."""
    still = np.zeros_like(rows)
    return Recording(t=np.zeros(len(rows)), qpos=rows, q=rows, qd=still, ctrl=still, tool=robot.fk(rows),
                     timestep=0.0, force=still, force_limit=np.full(rows.shape[1], np.inf))


def _speeds_note(speeds: tuple, joints: tuple[str, ...], path: str) -> str:
    """Where a bare model's speed limits come from, in words."""
    missing = [joint for joint, v in zip(joints, speeds) if v is None]
    if not missing:
        return "the URDF's joint velocity limits (a robot file's speed_limits replaces them)"
    stated = "" if len(missing) == len(joints) else f" for {', '.join(missing)}"
    return (f"{Path(path).name} states none{stated}: a robot file gives them, speed_limits: [one per joint] (the "
            "file's units per second)")


def _zyx(rotation: np.ndarray) -> np.ndarray:
    """[yaw, pitch, roll] (rad) with R = Rz(yaw) Ry(pitch) Rx(roll), as a task's orientation {convention: zyx}
    writes it (schema.Orientation); roll 0 at gimbal lock."""
    from scipy.spatial.transform import Rotation

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy's gimbal-lock warning: the angles returned are still R's
        return Rotation.from_matrix(rotation).as_euler("ZYX")


def _quat(rotation: np.ndarray) -> np.ndarray:
    """[w, x, y, z], w >= 0."""
    from simbench.maths.rotations import matrix_to_quat

    return matrix_to_quat(rotation)[0]


def text(found: Inspection) -> str:
    """The Inspection in lines, each printable (the model's names hold any character)."""
    lines = describe(found.arm, found.joints, found.speeds_note) if found.arm is not None else _ends_lines(found)
    lines += _pose_lines(found)
    return "\n".join(printable(line) for line in lines)


def _ends_lines(found: Inspection) -> list[str]:
    """The joints and the candidate tools of a model whose chain has several ends, and how to choose one."""
    ends = [frame.tool for frame in found.frames]
    return [f"{found.name}: {found.joints.dof} joints from {found.path}",
            *_joint_lines(found.joints, found.speeds_note),
            f"tool: not chosen: the longest chain ends in several bodies; the candidates: {', '.join(ends)}",
            "  choose one in a robot file, and inspect that file:",
            f"    model: {Path(found.path).name}", f"    tool: {ends[-1]}"]


def _joint_lines(joints: Joints, speeds_note: str | None) -> list[str]:
    """The joints with kind, range and speed limit."""
    lines = ["joints (SI: rad or m):"]
    for name, kind, lo, hi, speed in zip(joints.joints, joints.kinds, joints.lower, joints.upper, joints.qd_max):
        span = "continuous" if not np.isfinite(hi - lo) else f"[{lo:.6g}, {hi:.6g}]"
        limit = "" if speed is None else f", speed limit {speed:.6g}/s"
        lines.append(f"  {name:12s} {kind:9s} {span}{limit}")
    return lines + ([f"speed limits: {speeds_note}"] if speeds_note else [])


def describe(arm: DerivedArm, joints: Joints, speeds_note: str | None) -> list[str]:
    """The arm in lines: its joints with kind, range and speed limit, how each is driven, the tool, the camera, the
    reach, what the scene adds, what was dropped from the file, and whether qpos0 lies inside the ranges."""
    lines = [f"{arm.name}: {joints.dof} joints from {arm.path}", *_joint_lines(joints, speeds_note)]
    lines.append("actuators (an added servo's gains are designed for each run's plan; here at the reference pose, "
                 "at rest):")
    rest = {servo.joint: servo for servo in rest_design(arm)}  # (the designed joints' alone)
    lines += [f"  {d.joint:12s} {_drive(d, rest.get(d.joint))}" for d in arm.drives]
    limits = [d.force_limit for d in arm.drives]
    lines.append("force limits: " + (", ".join("none" if np.isinf(f) else f"{f:g}" for f in limits)
                                     if np.isfinite(limits).any() else "none (the model gives none)"))
    lines.append(f"tool: {arm.chain.tool.describe()}")
    lines.append(f"camera: {arm.camera}")
    lines.append(f"reach L: {arm.chain.reach:.4g} m (the unit-consistent Jacobian's characteristic length)")
    lines.append(f"scene adds: {', '.join(arm.added) or 'nothing'}; gravity compensation "
                 f"{'on' if arm.options.gravity_compensation else 'off'}")
    lines.append(f"integrator: {arm.integrator}")
    lines.append(f"locked at their reference position: {', '.join(arm.locked) or 'no joint'}")
    lines.append("excluded from collision (touching at the reference pose): "
                 + ("; ".join(f"{a} and {b}" for a, b in arm.excluded) or "no pair"))
    lines += [f"dropped: {note}" for note in arm.dropped]
    lines.append("qpos0: inside the ranges" if not arm.outside else
                 f"qpos0: outside the range of {', '.join(arm.outside)} (a scenario's start must lie inside)")
    return lines


def _pose_lines(found: Inspection) -> list[str]:
    """Where the tool is (each candidate, where the chain has several ends) at the joint values inspected."""
    units = found.units
    shown = [v / units.factor(kind) for v, kind in zip(found.q, found.joints.kinds)]
    unit = " and ".join(dict.fromkeys(units.name(kind) for kind in found.joints.kinds))
    lines = [f"pose at {found.given}: q = {_row(shown, '.6g')} {unit}"]
    for frame in found.frames:
        zyx = _zyx(frame.rotation)
        lines += [f"  tool: {frame.tool}",
                  f"    position: {_row(frame.position, '.6f')} m"
                  + (f" ({_row(frame.position * 1e3, '.3f')} mm)" if units.length == "mm" else ""),
                  "    rotation (world frame; columns: the tool frame's x, y, z axes):",
                  *(f"      {_row(row, '.6f')}" for row in frame.rotation),
                  (f"    zyx [yaw, pitch, roll]: {_row(np.degrees(zyx), '.4f')} deg, R = Rz(yaw) Ry(pitch) Rx(roll); "
                   f"as a task's orientation: {{convention: zyx, value: "
                   f"{_row(zyx / units.angle_factor, '.4f' if units.angle == 'deg' else '.6f')}}} ({units.angle})"),
                  f"    quat [w, x, y, z]: {_row(_quat(frame.rotation), '.6f')}"]
        if frame.measures is not None:
            lines.append("    " + ", ".join(f"{name} {frame.measures[name]:.6g}" for name in MEASURES)
                         + " (report.json's names; sigma_min of [Jp; Jr], SI)")
    return lines + ["(--json gives every number in full precision)"]


def _row(values, spec: str) -> str:
    """Numbers as [a, b, c], a negative zero (or a rounding's) shown as 0."""
    digits = int(spec[1:-1]) if spec.endswith("f") else None
    return "[" + ", ".join(f"{(round(v, digits) if digits is not None else v) + 0.0:{spec}}" for v in values) + "]"


def to_json(found: Inspection) -> str:
    """The Inspection as a JSON object, SI and full precision (null for no bound); 'tool' the tool's pose, or
    null where the chain has several ends and 'candidates' holds each end's."""
    def finite(value: float | None) -> float | None:
        return None if value is None or not np.isfinite(value) else float(value)

    def frame(f: Frame) -> dict:
        entry = {"tool": f.tool, "position": f.position.tolist(), "rotation": f.rotation.tolist(),
                 "quat_wxyz": _quat(f.rotation).tolist(), "zyx_deg": np.degrees(_zyx(f.rotation)).tolist()}
        return entry if f.measures is None else {**entry, "measures": f.measures}

    joints = found.joints
    document: dict[str, object] = {
        "name": found.name, "model": found.path,
        "joints": [{"name": name, "kind": kind, "lower": finite(lo), "upper": finite(hi), "speed_limit": finite(v)}
                   for name, kind, lo, hi, v in zip(joints.joints, joints.kinds, joints.lower, joints.upper,
                                                    joints.qd_max)],
        "at": {"given": found.given, "q": found.q.tolist()},
    }
    if found.arm is not None:
        document |= {"reach": found.arm.chain.reach, "tool": frame(found.frames[0])}
    else:
        document |= {"tool": None, "candidates": [frame(f) for f in found.frames]}
    return json.dumps(document, indent=2)


def _drive(drive, servo) -> str:
    """A joint's actuator in words, with its servo designed at rest where simbench adds it."""
    if servo is None:
        return drive.describe()
    bound = "no force limit" if np.isinf(drive.force_limit) else f"force limit {drive.force_limit:g}"
    what = "no actuator: added" if drive.action == "added" else f"{drive.found} replaced by"
    return f"{what} a position servo, {servo.describe()} ({bound})"


def rest_design(arm: DerivedArm) -> list:
    """The added servos as servo_design designs them for a plan that holds the reference pose (qpos0 clipped into
    the ranges), under the default tolerances: what `inspect` shows before any plan."""
    from simbench.api.trajectory import JointTrajectory
    from simbench.core.plant import Plant
    from simbench.robots.servo_design import design, plan_dynamics
    from simbench.scenario import Thresholds

    robot = ModelArm(arm, np.ones(len(arm.chain.joints)))
    plant = Plant.load(robot)
    q0 = plant.model.qpos0[plant.qpos_adr]
    q = np.tile(np.clip(q0, arm.chain.lower, arm.chain.upper), (2, 1))
    rest = JointTrajectory(t=np.array([0.0, plant.model.opt.timestep]), s=np.zeros(2), q_ref=q, qd_ref=np.zeros_like(q),
                           tool_ref=robot.fk(q))
    return design(plant, rest, plan_dynamics(plant, rest), arm.designed, Thresholds(), arm.options.bandwidth,
                  arm.options.damping_ratio)
