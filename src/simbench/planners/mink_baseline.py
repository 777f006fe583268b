"""The standard baseline beside the papers' planners: differential inverse kinematics with mink (any serial arm).

It follows the Cartesian reference of another planner's plan, so that the two can be compared on the same path:

    planner: mink_baseline
    task:
      follow: decoupled_path          # the planner whose plan is the reference
      task: {path: ..., ...}          # that planner's own task, written as its scenarios write it
      damping: 1.0e-3                 # Levenberg-Marquardt damping of every step's QP
      position_cost: 1                # FrameTask weights (1/m and 1/rad)
      orientation_cost: 1             # default 1 for an arm of 6 joints or more or a task that asks an orientation
      posture_cost: 1.0e-3            # PostureTask towards the first configuration: settles the redundancy
      solver: daqp                    # the QP solver (qpsolvers' name)

or, without `follow`, a path of its own: cartesian_path's task written directly beside the QP's fields
(`task: {start: [...], path: [...], orientation: hold, damping: 1.0e-3}`), cartesian_path's plan the reference.

The followed plan's tool points and, at its joint references, the MuJoCo tool site's orientation make the
reference pose X_k at every control step. From its first configuration q_0, each step k solves mink's QP

    min_dq  |W (J(q_k) dq - e(q_k, X_{k+1}))|^2 + c^2 |dq + q_k - q_0|^2 + damping |dq|^2
    s.t.    the joints' ranges (ConfigurationLimit), |dq| <= qd_max dt (VelocityLimit)

with e the FrameTask's pose error and W its costs, then q_{k+1} = q_k + dq and qd_k = dq / dt, clipped to the speed
limit (the QP holds it only to its tolerance). A step whose QP has no solution (a start outside the joint ranges) is
solved again with the speed limits alone, with a warning. The method knows nothing of the robot's singular sets:
where the Jacobian loses rank the tool leaves the path instead, which the plan reports (`off_path`).
"""

from __future__ import annotations

import copy
import re
from typing import Annotated, Any

import mujoco
import numpy as np
from pydantic import Field, PrivateAttr, ValidationError, ValidationInfo, field_validator, model_validator
from pydantic_core import InitErrorDetails, PydanticCustomError

from simbench.api import Planner, Robot, registry
from simbench.api.trajectory import JointTrajectory
from simbench.core import extras
from simbench.core.errors import RunError
from simbench.core.plant import compiled_scene
from simbench.scenario.schema import SimbenchModel, Weight
from simbench.scenario.validation import describe

NAME = "mink_baseline"
DIRECT = "cartesian_path"  # the planner that plans a path written directly in the task
_SPEED_SHARE = 1.0 - 1e-9  # a joint at least this share of its speed limit counts as held at it


class Task(SimbenchModel):
    """`task:` of the mink baseline: the planner followed, its own task, and the QP's weights."""

    follow: str = Field(description="the planner whose plan gives the Cartesian reference")
    task: Any = Field(description="the followed planner's task, checked against that planner's own schema")
    damping: Annotated[float, Field(ge=0, le=10)] = 1e-3
    position_cost: Weight = 1.0
    orientation_cost: Weight | None = Field(None, description="default: 1 for 6 or more joints or a task asking an "
                                                              "orientation, 0 for the point alone on fewer")
    posture_cost: Weight = 1e-3
    solver: str = Field("daqp", description="daqp (installed with mink) or another QP solver qpsolvers finds")
    _direct: bool = PrivateAttr(False)

    @model_validator(mode="wrap")
    @classmethod
    def _path_of_its_own(cls, value: Any, handler, info: ValidationInfo) -> Task:
        """The direct form (no `follow`, no `task`): its path fields are DIRECT's task, their errors located at
        this task's own fields."""
        if not isinstance(value, dict) or "follow" in value or "task" in value:
            return handler(value)
        own, path = _split(value)
        task = handler({**own, "follow": DIRECT, "task": _validated(DIRECT, path, info.context)})
        task._direct = True
        return task

    @property
    def direct(self) -> bool:
        """Whether the path is written in this task itself (the direct form), not in a followed planner's task."""
        return self._direct

    @field_validator("follow")
    @classmethod
    def _known_planner(cls, name: str, info: ValidationInfo) -> str:
        planners = registry.planners()
        if name == NAME:
            raise ValueError(f"'{NAME}' follows another planner's plan, not its own")
        if name not in planners:
            raise ValueError(f"unknown planner {name!r} (expected one of: "
                             f"{', '.join(sorted(set(planners) - {NAME}))})")
        robot = (info.context or {}).get("robot")
        refusal = planners[name].refuses(robot) if robot is not None else None
        if refusal:
            raise ValueError(refusal)
        return name

    @field_validator("solver")
    @classmethod
    def _installed(cls, name: str) -> str:
        if name != "daqp":  # mink's own: always there (qpsolvers is slow to look for the others)
            import qpsolvers

            if name not in qpsolvers.available_solvers:
                raise ValueError(f"QP solver {name!r} is not installed (installed: "
                                 f"{', '.join(qpsolvers.available_solvers)})")
        return name

    @field_validator("task")
    @classmethod
    def _followed_task(cls, value: Any, info: ValidationInfo) -> Any:
        follow = info.data.get("follow")
        if follow is None or isinstance(value, SimbenchModel):  # `follow` failed (its error is reported); direct form
            return value
        if not isinstance(value, dict):
            raise ValueError(f"expected a mapping: the task of '{follow}', as its own scenarios write it")
        return _validated(follow, value, info.context)

    def cost(self, robot: Robot) -> tuple[float, float]:
        """(position, orientation) costs of the FrameTask for `robot`: the orientation's by default 1 where the arm
        has 6 joints or more or the followed task asks an orientation (cartesian_path's `hold` or a goal: a planar
        arm holds it about its plane's normal), 0 where the point alone is asked of a smaller arm."""
        asks = getattr(self.task, "orientation", "free") != "free"
        default = 1.0 if robot.dof >= 6 or asks else 0.0
        return self.position_cost, default if self.orientation_cost is None else self.orientation_cost


def _split(task: dict) -> tuple[dict, dict]:
    """A direct-form task's fields: (the QP's own, the path's)."""
    own = set(Task.model_fields) - {"follow", "task"}
    return ({key: v for key, v in task.items() if key in own}, {key: v for key, v in task.items() if key not in own})


def _validated(planner: str, value: dict, context: dict | None) -> SimbenchModel:
    """`value` as the planner's task; its first error worded against that task's schema, located inside `task.task`
    (pydantic prefixes the outer path)."""
    schema = registry.planners()[planner].task
    try:
        return schema.model_validate(value, context=context)
    except ValidationError as err:
        where, message = describe(err, schema, value)
    loc = tuple(int(index) if index else key for key, index in re.findall(r"([^.\[\]]+)|\[(\d+)\]", where))
    raise ValidationError.from_exception_data("Task", [InitErrorDetails(
        type=PydanticCustomError("value_error", "Value error, {message}", {"message": message}),
        loc=loc, input=value)]) from None


def followed(scenario) -> Any:
    """The scenario as the followed planner sees it: its name and its own task (the rest unchanged)."""
    task: Task = scenario.task
    return scenario.model_copy(update={"planner": task.follow, "task": task.task})


def scene_model(robot: Robot) -> mujoco.MjModel:
    """A copy of the robot's compiled scene whose joints' ranges are the robot's (unlimited where infinite)."""
    model = copy.copy(compiled_scene(str(robot.scene)))
    for name, lo, hi in zip(robot.joints, robot.lower, robot.upper):
        joint = model.joint(name).id
        limited = bool(np.isfinite(lo) and np.isfinite(hi))
        model.jnt_limited[joint] = limited
        if limited:
            model.jnt_range[joint] = (lo, hi)
    return model


def reference_poses(model: mujoco.MjModel, robot: Robot, q_ref: np.ndarray, tool_ref: np.ndarray) -> np.ndarray:
    """The reference pose (N, 7) [w, x, y, z, x, y, z] of every sample: the followed tool point, and the tool
    site's orientation at the followed joints."""
    data = mujoco.MjData(model)
    adr = np.array([model.joint(name).qposadr[0] for name in robot.joints])
    site = model.site(robot.tool_site).id
    poses = np.empty((len(q_ref), 7))
    poses[:, 4:] = tool_ref
    for k, q in enumerate(q_ref):
        data.qpos[adr] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mju_mat2Quat(poses[k, :4], data.site_xmat[site])
    return poses


def _orientation_gap(quat: np.ndarray, quat_ref: np.ndarray) -> np.ndarray:
    """Angle (N,) between two series of unit quaternions (rad)."""
    return 2 * np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", quat, quat_ref)), 0.0, 1.0))


def solve(model: mujoco.MjModel, robot: Robot, dt: float, poses: np.ndarray, q_start: np.ndarray, damping: float,
          costs: tuple[float, float], posture_cost: float, solver: str) -> tuple[np.ndarray, np.ndarray, dict]:
    """q (N, dof), qd (N, dof) by mink's QPs along the poses (N, 7) from q_start, on scene_model's `model`, and what
    the solve met: the tool's position and orientation (N, 3), (N, 4) at each q, and the steps whose QP failed."""
    mink = extras.require("mink", "mink_baseline")  # here: `simbench list` and validation do not pay for it

    qpos_adr = np.array([model.joint(name).qposadr[0] for name in robot.joints])
    dof_adr = np.array([model.joint(name).dofadr[0] for name in robot.joints])
    qpos0 = model.qpos0.copy()
    qpos0[qpos_adr] = q_start

    configuration = mink.Configuration(model, qpos0)
    position_cost, orientation_cost = costs
    frame = mink.FrameTask(robot.tool_site, "site", position_cost=position_cost, orientation_cost=orientation_cost)
    tasks: list = [frame]
    if posture_cost > 0:
        posture = mink.PostureTask(model, cost=posture_cost)
        posture.set_target(qpos0)
        tasks.append(posture)
    velocity = mink.VelocityLimit(model, dict(zip(robot.joints, robot.qd_max)))
    limits = [mink.ConfigurationLimit(model), velocity]
    qd_max = np.full(model.nv, np.inf)
    qd_max[dof_adr] = robot.qd_max

    n = len(poses)
    q, qd = np.empty((n, robot.dof)), np.empty((n, robot.dof))
    tool, quat = np.empty((n, 3)), np.empty((n, 4))
    site = model.site(robot.tool_site).id
    failed: list[int] = []
    for k in range(n):
        q[k] = configuration.q[qpos_adr]
        tool[k] = configuration.data.site_xpos[site]
        mujoco.mju_mat2Quat(quat[k], configuration.data.site_xmat[site])
        frame.set_target(mink.SE3(wxyz_xyz=poses[min(k + 1, n - 1)]))
        try:
            v = mink.solve_ik(configuration, tasks, dt, solver, damping=damping, limits=limits)
        except mink.NoSolutionFound:
            failed.append(k)
            try:  # the joint ranges cannot be met (a followed start outside them): keep the speed limits only
                v = mink.solve_ik(configuration, tasks, dt, solver, damping=damping, limits=[velocity])
            except mink.NoSolutionFound:
                v = np.zeros(model.nv)
        v = np.clip(v, -qd_max, qd_max)  # the QP's solution holds the limit to its tolerance; held exactly here
        qd[k] = v[dof_adr]
        if k + 1 < n:
            configuration.integrate_inplace(v, dt)
    return q, qd, {"tool": tool, "quat": quat, "failed": failed}


class MinkBaseline(Planner[Task]):
    """Differential inverse kinematics with mink along another planner's Cartesian reference (any serial arm)."""

    name = NAME
    description = "baseline: differential IK with mink (QP per step) along another planner's path (serial arms)"
    seconds_per_sample = 1e-3  # the cost estimate's planning time a control step: mink sets up a QP in Python each step
    task = Task
    needs = ("fk",)

    def followed_raw(self, task: dict) -> tuple[Any, Any]:
        """The followed planner and its task, as written, of a `task:` mapping of either form."""
        if "follow" in task or "task" in task:
            return task.get("follow"), task.get("task")
        return DIRECT, _split(task)[1]

    def refuses(self, robot: Robot) -> str | None:
        """A robot without forward kinematics, or one whose scene has more than its actuated joints (a closed
        chain's passive joints, a free part) or equality constraints: mink would move what the joints cannot."""
        refusal = super().refuses(robot)
        if refusal:
            return refusal
        model = compiled_scene(str(robot.scene))
        kinds = {int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)}
        serial = (model.nv == robot.dof and model.neq == 0
                  and all(int(model.jnt_type[model.joint(name).id]) in kinds for name in robot.joints))
        if not serial:
            return (f"'{NAME}' works with serial arms whose every degree of freedom is an actuated hinge or slide; "
                    f"'{robot.name}' has {model.nv} degrees of freedom for its {robot.dof} joints and {model.neq} "
                    "equality constraints in its scene (a closed chain)")
        return None

    def plan(self, scenario, robot: Robot, dt: float) -> JointTrajectory:
        """The followed planner's plan, then mink along its poses, on the same time grid and with its tool_ref."""
        from simbench.maths.path_distance import path_deviation  # the analysis's measure of distance from a path

        task: Task = scenario.task
        inner = followed(scenario)
        reference = inner.planner_def.plan(inner, robot, dt)
        if reference.switches or reference.initial or reference.feedback is not None:
            raise RunError(f"'{task.follow}' switches, assembles or re-plans during its run; '{NAME}' follows only a "
                           "plan of joint references")
        model, costs = scene_model(robot), task.cost(robot)
        poses = reference_poses(model, robot, reference.q_ref, reference.tool_ref)
        q, qd, met = solve(model, robot, dt, poses, reference.q_ref[0], task.damping, costs, task.posture_cost,
                           task.solver)
        t, tool_ref = reference.t, reference.tool_ref
        tool_error = np.linalg.norm(met["tool"] - tool_ref, axis=1)
        orientation_error = _orientation_gap(met["quat"], poses[:, :4])
        deviation = path_deviation(tool_ref, met["tool"])
        held = np.abs(qd) >= _SPEED_SHARE * robot.qd_max
        k_dev = int(np.argmax(deviation))
        info = {
            "method": "differential inverse kinematics with mink: per control step, a QP for the joint step towards "
                      "the next pose of the followed plan (FrameTask, PostureTask; joint ranges and speed limits)",
            "follows": {"planner": task.follow, "plan": reference.info, "warnings": list(reference.warnings)},
            "solver": task.solver,
            "damping": task.damping,
            "costs": {"position": costs[0], "orientation": costs[1], "posture": task.posture_cost},
            "qp_failures": len(met["failed"]),
            "plan_path_deviation_max": float(deviation[k_dev]),
            "plan_tool_error_max": float(tool_error.max()),
            "plan_orientation_error_max": float(orientation_error.max()) if costs[1] > 0 else None,
            "speed_limited_time": {name: float(held[:, j].sum() * dt) for j, name in enumerate(robot.joints)},
        }
        if "slowdown" in reference.info:  # a retimed plan's grid, which this one runs on (singularity_handling)
            info["slowdown"] = reference.info["slowdown"]
        warnings, violations = [], []
        if met["failed"]:
            first = met["failed"][0]
            warnings.append(f"mink's QP ({task.solver}) found no solution at {len(met['failed'])} step(s), the first "
                            f"at t = {t[first]:.3f} s; there the joint ranges were dropped (speed limits kept), or the "
                            "arm held still")
        tol = scenario.analysis
        if deviation[k_dev] > 0.1 * tol.path_tolerance:
            joints = [name for j, name in enumerate(robot.joints) if held[:, j].any()]
            why = f" ({', '.join(joints)} held at the speed limit)" if joints else ""
            warnings.append(f"the plan leaves the followed path by up to {deviation[k_dev] * 1e3:.3f} mm at t = "
                            f"{t[k_dev]:.3f} s{why}")
        if deviation[k_dev] > tol.path_tolerance:
            violations.append({"kind": "off_path", "message": f"the plan leaves the followed path by up to "
                               f"{deviation[k_dev] * 1e3:.2f} mm at t = {t[k_dev]:.3f} s (tolerance "
                               f"{tol.path_tolerance * 1e3:g} mm)"})
        if tool_error[-1] > tol.goal_tolerance:
            violations.append({"kind": "goal_missed", "message": f"the plan ends {tool_error[-1] * 1e3:.2f} mm from "
                               f"the followed plan's end (tolerance {tol.goal_tolerance * 1e3:g} mm)"})
        index = np.clip(np.searchsorted(reference.s, [w["s"] for w in reference.waypoints]), 0, len(t) - 1)
        waypoints = tuple({**w, "q": q[i].tolist()} for w, i in zip(reference.waypoints, index))
        return JointTrajectory(t=t, s=reference.s, q_ref=q, qd_ref=qd, tool_ref=tool_ref, waypoints=waypoints,
                               info=info, warnings=tuple(warnings), violations=tuple(violations),
                               series={"plan_tool_error": tool_error, "plan_orientation_error": orientation_error})

    def check(self, scenario, robot: Robot) -> tuple[str, str] | None:
        """mink installed (extras), and the followed planner's own check of its task, its field named inside
        `task.task` (in the direct form, inside `task`)."""
        refusal = extras.missing("mink", self.name)
        if refusal:
            return "planner", refusal
        inner = followed(scenario)
        problem = inner.planner_def.check(inner, robot)
        if problem is None:
            return None
        field, message = problem
        if scenario.task.direct or not field.startswith("task"):
            return field, message
        return f"task.task{field[len('task'):]}", message


PLANNER = MinkBaseline()
