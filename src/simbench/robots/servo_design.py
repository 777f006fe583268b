"""Joint servos designed for a plan, as a controls engineer designs a joint controller from the arm's inertia
(robosuite and Drake derive their joint controllers from it too), and the forces a plan needs checked against the
force limits before it is simulated.

Over the plan's samples (SAMPLES of them evenly, and each joint's rows of largest planned acceleration; the torques
at every row), for each designed joint i, with M the joint-space inertia (armature included):

    I_i      the largest M_ii: the inertia the servo must move at its stiffest need
    I0_i     the least 1 / (M^-1)_ii: the inertia the joint shows when the other joints give way, which sets the
             coupled arm's fastest mode
    d_i      the largest torque the plan's motion needs beyond what the servo's feed-forward gives (controllers.Servo
             feeds the joint's viscous friction b qd forward): M qdd + c - passive - b qd, the inertial and Coriolis
             torques (gravity cancelled by gravity compensation where the scene has it), plus the joint's friction
             loss f, which MuJoCo's soft friction opposes to any motion up to f
    e_i      the joint's error budget: ERROR_SHARE of analysis.path_tolerance over its lever on the tool point (the
             largest norm of its column of Jp), and of analysis.orientation_tolerance where it turns the tool

A position servo's bandwidth is w_i = max(w0, sqrt(d_i / (e_i I_i))): the least bandwidth w0 (`servo.bandwidth`,
else DEFAULT_BANDWIDTH) on the plan's largest inertia ("inertia"), raised where the plan's torques would push the
joint off by more than its budget ("accuracy": Kp e_i >= d_i), then capped:

    timestep     the joint stable at the timestep dt on its least inertia I0_i, with STABLE of the margin: MuJoCo's
                 semi-implicit step of a spring Kp with damping Kd on an inertia I is stable while
                 dt^2 Kp / I < 4 + 2 dt Kd / I where the damping is integrated implicitly (a position servo under
                 `implicitfast`), and while dt^2 Kp / I < 4 - 2 dt Kd / I where it is explicit (computed torque's
                 PD, from the measured state); the cap is the largest w within STABLE times that bound
    force limit  Kp e_i / ERROR_SHARE <= F_i: an error of the whole tolerance takes at most the force limit;
                 stiffer, the servo would saturate before the tool leaves its tolerance

and Kp = I w^2, Kd = 2 zeta I w (critically damped at zeta = 1). Computed torque feeds the inverse dynamics forward,
its PD correcting only what the model leaves: no accuracy floor and no force-limit cap, the timestep's alone.

The forces: where |M qdd + c - passive| + f of a joint (f its friction loss) passes its force limit at a sample
where it moves, the plan needs more than the drive gives: a `force_limit` violation naming the joint, the force
and when.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from simbench.api import Array, Violation
from simbench.api.trajectory import JointTrajectory

SAMPLES = 200  # plan rows whose inertias and levers are read, evenly (the first and the last among them)
CHUNK = 4096  # plan rows whose torques are found at once (memory: a few arrays of CHUNK x nv floats)
ERROR_SHARE = 0.05  # of the path and orientation tolerances: a designed joint's steady error budget
STABLE = 0.5  # share of the timestep's stability bound a designed joint may use (the module's docstring)
DEFAULT_BANDWIDTH = 50.0  # rad/s: w0 where the robot mapping gives none


@dataclass(frozen=True)
class JointServo:
    """One joint's designed gains (SI) and why: `reason` is what set the bandwidth (the module's docstring)."""

    joint: str
    kp: float
    kv: float
    bandwidth: float
    reason: str
    inertia: float
    torque: float
    budget: float

    def report(self) -> dict:
        """report.json's entry: the gains, the bandwidth, the reason, and the figures behind them (SI)."""
        return {"joint": self.joint, "kp": self.kp, "kv": self.kv, "bandwidth": self.bandwidth,
                "reason": self.reason, "inertia": self.inertia, "plan_torque": self.torque,
                "error_budget": self.budget}

    def describe(self) -> str:
        return (f"kp {self.kp:.4g}, kv {self.kv:.4g}, bandwidth {self.bandwidth:.4g} rad/s ({self.reason}; inertia "
                f"{self.inertia:.3g})")


@dataclass(frozen=True)
class PlanDynamics:
    """What the design reads of a plan (the module's docstring), per joint (dof,): the largest M_ii, the least
    1 / (M^-1)_ii, the largest torque beyond the feed-forward, the largest lever (m per rad or m) and turn (rad per
    rad) on the tool; and every row's whole torque need (N, dof)."""

    inertia: Array
    fastest: Array
    torque: Array
    lever: Array
    turn: Array
    need: Array


def plan_dynamics(plant, traj: JointTrajectory) -> PlanDynamics:
    """The plan's inertias and levers at its sampled rows, and its torques at every row (the module's docstring)."""
    model, dofs = plant.model, plant.dof_adr
    n = len(traj.t)
    qdd = np.gradient(traj.qd_ref, traj.dt, axis=0) if n > 1 else np.zeros_like(traj.qd_ref)
    sampled = np.unique(np.concatenate([np.linspace(0, n - 1, min(n, SAMPLES)).round().astype(int),
                                        np.argmax(np.abs(qdd), axis=0)]))
    data = mujoco.MjData(model)
    site = model.site(plant.robot.tool_site).id
    full, jac = np.zeros((model.nv, model.nv)), np.zeros((6, model.nv))
    jacp, jacr, block = jac[:3], jac[3:], np.ix_(dofs, dofs)
    inertias, jacs = np.empty((len(sampled), len(dofs), len(dofs))), np.empty((len(sampled), 6, len(dofs)))
    for i, qpos in enumerate(plant.initial_qpos(traj.q_ref[sampled])):  # positions alone: what M and J read
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_crb(model, data)
        mujoco.mj_fullM(model, data, full)
        inertias[i] = full[block]
        mujoco.mj_jacSite(model, data, jacp, jacr, site)
        jacs[i] = jac[:, dofs]
    diag, fastest = np.diagonal(inertias, axis1=1, axis2=2), 1 / np.diagonal(np.linalg.inv(inertias), axis1=1, axis2=2)
    lever = np.linalg.norm(jacs[:, :3], axis=1).max(axis=0, initial=0.0)
    turn = np.linalg.norm(jacs[:, 3:], axis=1).max(axis=0, initial=0.0)
    whole = np.empty((n, len(dofs)))  # M qdd + c - passive at every row
    for start in range(0, n, CHUNK):
        whole[start:start + CHUNK] = _torques(plant, data, traj, qdd, slice(start, min(n, start + CHUNK)))
    friction = model.dof_frictionloss[dofs]
    beyond = np.abs(whole - model.dof_damping[dofs] * traj.qd_ref).max(axis=0) + friction
    return PlanDynamics(diag.max(axis=0), fastest.min(axis=0), beyond, lever, turn,
                        whole + friction * np.sign(traj.qd_ref))


def _torques(plant, data: mujoco.MjData, traj: JointTrajectory, qdd: np.ndarray, rows: slice) -> np.ndarray:
    """M qdd + c - passive of the designed joints at the plan's `rows` (rows, dof): each row's full qpos (passive
    joints assembled), qvel and qacc (zero but for the designed joints') made for all the rows at once and MuJoCo's
    results written into row views (the Python between MuJoCo's calls was most of a row's time)."""
    model, dofs = plant.model, plant.dof_adr
    q = traj.q_ref[rows]
    qpos = plant.initial_qpos(q)
    qvel, qacc = np.zeros((len(q), model.nv)), np.zeros((len(q), model.nv))
    qvel[:, dofs], qacc[:, dofs] = traj.qd_ref[rows], qdd[rows]
    inverse, passive = np.empty((len(q), model.nv)), np.empty((len(q), model.nv))
    at, speed, acceleration, passive_now = data.qpos, data.qvel, data.qacc, data.qfrc_passive  # views, taken once
    for i in range(len(q)):
        at[:], speed[:], acceleration[:] = qpos[i], qvel[i], qacc[i]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_comVel(model, data)
        mujoco.mj_passive(model, data)
        mujoco.mj_rne(model, data, 1, inverse[i])
        passive[i] = passive_now
    return (inverse - passive)[:, dofs]


def design(plant, traj: JointTrajectory, dynamics: PlanDynamics, designed: np.ndarray, tolerances,
           bandwidth: float | None = None, damping_ratio: float = 1.0, feedforward: bool = False) -> list[JointServo]:
    """The designed joints' servos (the module's docstring): position servos, or with `feedforward` (inverse
    dynamics fed forward, the PD explicit: computed torque) a PD without accuracy floor, its damping capped too.
    `tolerances`: the scenario's `analysis` (path_tolerance, orientation_tolerance; unread with `feedforward`)."""
    robot, dt = plant.robot, float(plant.model.opt.timestep)
    w0 = DEFAULT_BANDWIDTH if bandwidth is None else bandwidth
    d = dynamics
    inertia = np.maximum(d.inertia, 1e-12)
    caps = {"timestep": stable_bandwidth(inertia / np.maximum(d.fastest, 1e-12), damping_ratio, dt,
                                         implicit=not feedforward)}
    budget, stiff = np.full(len(inertia), np.nan), np.zeros_like(inertia)
    if not feedforward:
        budget = ERROR_SHARE * np.minimum(tolerances.path_tolerance / np.maximum(d.lever, 1e-12),
                                          tolerances.orientation_tolerance / np.maximum(d.turn, 1e-12))
        caps["force limit"] = np.sqrt(plant.force_limit() * ERROR_SHARE / (budget * inertia))
        stiff = np.sqrt(d.torque / (budget * inertia))
    out = []
    for i in np.flatnonzero(designed):
        w, reason = (w0, "inertia") if w0 >= stiff[i] else (float(stiff[i]), "accuracy")
        for cap, bound in caps.items():
            if bound[i] < w:
                w, reason = float(bound[i]), cap
        out.append(JointServo(robot.joints[i], float(inertia[i] * w**2), float(2 * damping_ratio * inertia[i] * w),
                              float(w), reason, float(inertia[i]), float(d.torque[i]), float(budget[i])))
    return out


def pd_gains(inertia: Array, bandwidth: float, damping_ratio: float) -> tuple[Array, Array]:
    """The PD gains (Kp, Kd) that give joints of these inertias a second-order error response of natural frequency
    `bandwidth` (rad/s) and damping ratio `damping_ratio`: Kp = I w^2, Kd = 2 zeta I w."""
    inertia = np.asarray(inertia, float)
    return inertia * bandwidth ** 2, 2 * damping_ratio * inertia * bandwidth


def stable_bandwidth(ratio: Array, damping_ratio: float, dt: float, implicit: bool) -> Array:
    """The largest w (rad/s) with dt^2 Kp / I0 <= STABLE (4 +- 2 dt Kd / I0) (the module's docstring) for Kp = I w^2,
    Kd = 2 zeta I w and `ratio` = I / I0: with x = w dt, r x^2 -+ 4 STABLE zeta r x - 4 STABLE <= 0."""
    sign = 1.0 if implicit else -1.0
    b = sign * 2 * STABLE * damping_ratio
    return (b + np.sqrt(b**2 + 4 * STABLE / ratio)) / dt


def force_violations(plant, traj: JointTrajectory, dynamics: PlanDynamics) -> list[Violation]:
    """A `force_limit` violation for each joint whose torque need passes its force limit at a row: the worst, and
    from when."""
    limit = plant.force_limit()
    robot, t, need = plant.robot, traj.t, np.abs(dynamics.need)
    out = []
    for j in np.flatnonzero((need > limit).any(axis=0)):
        first, worst = int(np.argmax(need[:, j] > limit[j])), int(np.argmax(need[:, j]))
        unit = "N m" if robot.kinds[j] == "revolute" else "N"
        out.append(Violation("force_limit", f"the plan needs {robot.joints[j]} to exert {need[worst, j]:.3g} {unit} at "
                             f"t = {t[worst]:.3f} s, beyond its force limit {limit[j]:g} {unit} (from t = "
                             f"{t[first]:.3f} s)", float(t[first]), 0,
                             {"joint": robot.joints[j], "need": float(need[worst, j]), "limit": float(limit[j]),
                              "source": "planner"}))
    return out
