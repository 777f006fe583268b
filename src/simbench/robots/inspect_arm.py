"""`simbench inspect MODEL_OR_SCENARIO`: what simbench derives from an arm's model, in words, before a run."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from simbench.errors import ScenarioError, printable
from simbench.robots import robot_mapping
from simbench.robots.chain import ArmError
from simbench.robots.model_scene import ArmOptions, DerivedArm
from simbench.schema import Units
from simbench.validation import read_yaml


def inspect(path: Path) -> str:
    """The derived arm of an MJCF or URDF file (its default tool, no speed limits), of a robot file, or of a
    scenario's robot mapping; ScenarioError for anything else."""
    source = str(path)
    if path.suffix.lower() in (".xml", ".urdf"):
        try:
            model = robot_mapping.model_path(str(path.absolute()), source, "")
            return describe(robot_mapping.derived(model, ArmOptions()), None)
        except ArmError as err:
            raise ScenarioError(source, err.field, str(err)) from None
    raw = read_yaml(path)
    value = raw.get("robot", raw) if isinstance(raw, dict) and "model" not in raw else raw
    if not robot_mapping.is_mapping(value):
        raise ScenarioError(source, "robot", "expected a robot mapping (model, tool, speed_limits), an MJCF or a URDF "
                                             "file: a registered robot is described by `simbench list`")
    units = robot_mapping.units_of(raw, source) or Units()
    robot = robot_mapping.load_robot(value if value is not raw else str(path.absolute()), source, units)
    return describe(robot.arm, robot.qd_max)


def describe(arm: DerivedArm, qd_max: np.ndarray | None) -> str:
    """The arm in lines: its joints with kind and range, how each is driven, the tool, the camera, the reach, what
    the scene adds, what was dropped from the file, and whether qpos0 lies inside the ranges; each line printable
    (the model's names hold any character: a line break in one cannot start a line, an ESC cannot drive the tty)."""
    chain = arm.chain
    lines = [f"{arm.name}: {len(chain.joints)} joints from {arm.path}", "joints (SI: rad or m):"]
    for i, (name, kind, lo, hi) in enumerate(zip(chain.joints, chain.kinds, chain.lower, chain.upper)):
        span = "continuous" if not np.isfinite(hi - lo) else f"[{lo:.6g}, {hi:.6g}]"
        speed = "" if qd_max is None else f", speed limit {qd_max[i]:.6g}/s"
        lines.append(f"  {name:12s} {kind:9s} {span}{speed}")
    lines.append("actuators (an added servo's gains are designed for each run's plan; here at the reference pose, "
                 "at rest):")
    rest = dict(zip(arm.chain.joints, rest_design(arm)))
    lines += [f"  {d.joint:12s} {_drive(d, rest.get(d.joint))}" for d in arm.drives]
    limits = [d.force_limit for d in arm.drives]
    lines.append("force limits: " + (", ".join("none" if np.isinf(f) else f"{f:g}" for f in limits)
                                     if np.isfinite(limits).any() else "none (the model gives none)"))
    lines.append(f"tool: {chain.tool.describe()}")
    lines.append(f"camera: {arm.camera}")
    lines.append(f"reach L: {chain.reach:.4g} m (the unit-consistent Jacobian's characteristic length)")
    lines.append(f"scene adds: {', '.join(arm.added) or 'nothing'}; gravity compensation "
                 f"{'on' if arm.options.gravity_compensation else 'off'}")
    lines.append(f"integrator: {arm.integrator}")
    lines.append(f"locked at their reference position: {', '.join(arm.locked) or 'no joint'}")
    lines.append("excluded from collision (touching at the reference pose): "
                 + ("; ".join(f"{a} and {b}" for a, b in arm.excluded) or "no pair"))
    lines += [f"dropped: {note}" for note in arm.dropped]
    lines.append("qpos0: inside the ranges" if not arm.outside else
                 f"qpos0: outside the range of {', '.join(arm.outside)} (a scenario's start must lie inside)")
    return "\n".join(printable(line) for line in lines)


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
    from simbench.plant import Plant
    from simbench.robots.model_arm import ModelArm
    from simbench.scenario import Thresholds
    from simbench.servo_design import design, plan_dynamics
    from simbench.trajectory import JointTrajectory

    robot = ModelArm(arm, np.ones(len(arm.chain.joints)))
    plant = Plant.load(robot)
    q0 = plant.model.qpos0[plant.qpos_adr]
    q = np.tile(np.clip(q0, arm.chain.lower, arm.chain.upper), (2, 1))
    rest = JointTrajectory(t=np.array([0.0, plant.model.opt.timestep]), s=np.zeros(2), q_ref=q, qd_ref=np.zeros_like(q),
                           tool_ref=robot.fk(q))
    return design(plant, rest, plan_dynamics(plant, rest), arm.designed, Thresholds(), arm.options.bandwidth,
                  arm.options.damping_ratio)
