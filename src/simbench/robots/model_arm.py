"""simbench.api.Robot of an arm derived from its MJCF model (robots.model_scene): kinematics from MuJoCo itself.

The tool point and its Jacobian J = [Jp; Jr] (6 x dof: m/s and rad/s per joint speed) are MuJoCo's (mj_kinematics,
mj_jacSite on a private MjData, the other joints at qpos0). Its singular measures, per sample:

    sigma_min           least singular value of J (of the min(6, dof) it has), SI as J is
    manipulability      Yoshikawa's, the product of J's singular values (sqrt det(J J^T) where dof >= 6)
    inverse_condition   sigma_min / sigma_max of the unit-consistent Jacobian Ju = [Jp / L; Jr]

with L the arm's reach (robots.chain.Chain.reach), so that a metre of tool motion at the end of the reach counts as
a radian. The singular set `rank_loss` is where Ju loses rank; its gap, Ju's least singular value, grows near it as
the joint angle away from it (rad), so it is near below the analysis' `near_angle` (robots.rank_loss).

Its plant is fitted to each plan (plant_fit): the added servos designed for it (simbench.robots.servo_design), a start
whose geoms touch refused, contacts along the plan and forces past the limits reported before any physics. Its run
adds the tool's orientation error, `tool_orientation_error` (rad): the angle from the orientation the plan asks
(its `tool_orientation_ref`, else the tool's at q_ref) to the tool's at the recorded joints, a promise where the plan
asks one; and a `contact` event (breaking) wherever the recorded joints put two of the arm's geoms, or one and the
floor, in contact (robots.contacts).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import mujoco
import numpy as np

from simbench.api import (Array, JointTrajectory, PlantFit, Recording, Robot, SingularSet, Summariser, Summary,
                          Tolerance, Violation)
from simbench.api.events import Event
from simbench.api.trajectory import ORIENTATION_REF
from simbench.core.indices import as_slice
from simbench.core.plant import register_scene
from simbench.maths.rotations import quat_to_matrix, rotation_angle
from simbench.robots.contacts import Contacts, Touch, checked_rows
from simbench.robots.model_scene import TOOL_SENSOR, DerivedArm
from simbench.robots.rank_loss import closest_sample, rank_loss_detail, unit_jacobian
from simbench.robots.servo_design import design, force_violations, plan_dynamics

ORIENTATION_ERROR = "tool_orientation_error"
CONTACT_STEP = {"revolute": np.deg2rad(0.5), "prismatic": 1e-3}  # joint motion between contact checks (rad, m)


class ModelArm(Robot):
    """An arm read from its model file (DerivedArm), with speed limits `qd_max` (SI, one per joint). Its scene is
    registered under the model's path followed by '#simbench' (plant.register_scene)."""

    def __init__(self, arm: DerivedArm, qd_max: Array):
        self.arm = arm
        chain = arm.chain
        super().__init__(name=arm.name, description=f"arm derived from its model {Path(arm.path).name}",
                         scene=self._register(), joints=chain.joints, kinds=chain.kinds, lower=chain.lower,
                         upper=chain.upper, qd_max=qd_max, tool_site=arm.tool_site,
                         tool_sensor=TOOL_SENSOR, orientation_error=ORIENTATION_ERROR, breaking=("contact",))
        self._kinematics: tuple[mujoco.MjModel, mujoco.MjData, np.ndarray, np.ndarray, int] | None = None
        self._contacts: Contacts | None = None

    def _register(self) -> str:
        key = f"{self.arm.path}#simbench-{hashlib.sha1(repr(self.arm.options).encode()).hexdigest()[:12]}"
        register_scene(key, self.arm.spec)
        return key

    def __getstate__(self) -> dict:
        return {**self.__dict__, "_kinematics": None, "_contacts": None}  # MuJoCo's are made anew where unpickled

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        register_scene(str(self.scene), self.arm.spec)

    def _compiled(self) -> tuple[mujoco.MjModel, mujoco.MjData, np.ndarray | slice, np.ndarray | slice, int]:
        """The arm's kinematics model and data, its joints' qpos and dof addresses (a slice where they run in order,
        as in most files: a slice indexes at a fraction of an index array's cost) and the tool site's id, made once
        (planning asks for them at every control sample)."""
        if self._kinematics is None:
            model = self.arm.spec().compile()
            joints = [model.joint(name) for name in self.joints]
            data = mujoco.MjData(model)  # its qpos starts at qpos0
            self._kinematics = (model, data, as_slice([j.qposadr[0] for j in joints]),
                                as_slice([j.dofadr[0] for j in joints]), model.site(self.tool_site).id)
        return self._kinematics

    def fk(self, q: Array) -> Array:
        """The tool point (N, 3) in metres at joint values q (N, dof), as MuJoCo places the tool's site."""
        return self.pose(q)[0]

    def pose(self, q: Array) -> tuple[Array, Array]:
        """The tool point (N, 3) and its rotation (N, 3, 3) at joint values q (N, dof), from one kinematics pass a
        row."""
        return self._passes(q, jacobian=False)[:2]

    @property
    def reach(self) -> float:
        """The characteristic length L (m) of the unit-consistent Jacobian: the chain's reach."""
        return self.arm.chain.reach

    @property
    def anchor(self) -> Array:
        """The anchor (world, m) at qpos0 of the joint nearest the world (robots.chain's `base`), where the reach is
        measured from; none of the joints moves it."""
        model, data, adr, _, _ = self._compiled()
        data.qpos[adr] = model.qpos0[adr]
        mujoco.mj_kinematics(model, data)
        return data.xanchor[model.joint(self.base_joint).id].copy()

    @property
    def base_joint(self) -> str:
        """The joint nearest the world (robots.chain's `base`), whose anchor the reach is measured from."""
        return self.arm.chain.base

    def tool_rotation(self, q: Array) -> Array:
        """The tool site's orientation (N, 3, 3) in the world at joint values q (N, dof): MuJoCo's site_xmat."""
        return self.pose(q)[1]

    def jacobian(self, q: Array) -> Array:
        """J = [Jp; Jr] (N, 6, dof) at joint values q (N, dof): mj_jacSite's, at the tool site."""
        return self.pose_jacobian(q)[2]

    def pose_jacobian(self, q: Array) -> tuple[Array, Array, Array]:
        """The tool point (N, 3), its rotation (N, 3, 3) and J (N, 6, dof) at joint values q (N, dof), from one
        kinematics pass a row: fk, tool_rotation and jacobian at once (a planner's every control sample needs all
        three)."""
        return self._passes(q, jacobian=True)

    def pose_jacobian_at(self, q: Array) -> tuple[Array, Array, Array]:
        """pose_jacobian's at one joint vector q (dof,): the tool point (3,), its rotation (3, 3) and J (6, dof),
        without the batch's arrays (a resolved-rate planner asks for them at every control sample)."""
        return self._row(q, jacobian=True)

    def _row(self, q: Array, jacobian: bool) -> tuple[Array, Array, Array | None]:
        """One row's kinematics pass: the tool point (3,), its rotation (3, 3) and, where asked, J (6, dof)."""
        model, data, adr, dofs, site = self._compiled()
        data.qpos[adr] = q
        mujoco.mj_kinematics(model, data)
        point, rotation = data.site_xpos[site].copy(), data.site_xmat[site].reshape(3, 3).copy()
        if not jacobian:
            return point, rotation, None
        mujoco.mj_comPos(model, data)
        jac = np.zeros((6, model.nv))
        mujoco.mj_jacSite(model, data, jac[:3], jac[3:], site)
        return point, rotation, jac[:, dofs]

    def _passes(self, q: Array, jacobian: bool) -> tuple[Array, Array, Array | None]:
        """pose's and pose_jacobian's rows: each row of q posed (the joints off the chain stay at qpos0, set once),
        kinematics computed, and the Jacobian where asked; None for it where not. A plain loop, the data's arrays
        taken once (each attribute access makes a new view); a single row (a search's every evaluation, a Newton
        step's) by _row, without the batch's arrays."""
        q = np.atleast_2d(q)
        if len(q) == 1:
            point, rotation, jac = self._row(q[0], jacobian)
            # (J contiguous, as the batch's rows are: a product of a strided view may take another BLAS path)
            return point[None], rotation[None], None if jac is None else np.ascontiguousarray(jac)[None]
        model, data, adr, dofs, site = self._compiled()
        points, rotations = np.empty((len(q), 3)), np.empty((len(q), 9))
        out = np.empty((len(q), 6, self.dof)) if jacobian else None
        jac = np.zeros((6, model.nv))
        jacp, jacr = jac[:3], jac[3:]
        qpos, site_xpos, site_xmat = data.qpos, data.site_xpos, data.site_xmat
        for k, row in enumerate(q):
            qpos[adr] = row
            mujoco.mj_kinematics(model, data)
            if out is not None:
                mujoco.mj_comPos(model, data)
                mujoco.mj_jacSite(model, data, jacp, jacr, site)
                out[k] = jac[:, dofs]
            points[k], rotations[k] = site_xpos[site], site_xmat[site]
        return points, rotations.reshape(-1, 3, 3), out

    def measures(self, rec: Recording) -> dict[str, Array]:
        """sigma_min (SI), manipulability and inverse_condition along the run (the module's docstring)."""
        jac = self.jacobian(rec.q)
        raw = np.linalg.svd(jac, compute_uv=False)
        unit = np.linalg.svd(unit_jacobian(jac, self.reach), compute_uv=False)
        return {"sigma_min": raw[:, -1], "manipulability": raw.prod(axis=1),
                "inverse_condition": unit[:, -1] / unit[:, 0], "sigma_min_unit": unit[:, -1]}

    def singular_sets(self, rec: Recording, tol: Tolerance) -> list[SingularSet]:
        return self.singular_sets_from(rec, tol, self.measures(rec))

    def singular_sets_from(self, rec: Recording, tol: Tolerance, measures: dict[str, Array]) -> list[SingularSet]:
        """rank_loss: Ju's least singular value, near below tol.angle; its event's closest sample and detail as
        robots.rank_loss finds them."""
        gap = measures["sigma_min_unit"]
        return [SingularSet("rank_loss", "Jacobian rank loss",
                            f"least singular value of [Jp / L; Jr] = 0 (L = {self.reach:.4g} m, the reach)",
                            gap / tol.angle, {"sigma_min_unit": gap},
                            detail=lambda i: rank_loss_detail(self.jacobian(rec.q[i])[0], self.reach),
                            closest=lambda a, b: a + closest_sample(unit_jacobian(self.jacobian(rec.q[a:b + 1]),
                                                                                  self.reach)))]

    def contacts(self) -> Contacts:
        """Contact queries on the arm's scene (robots.contacts)."""
        if self._contacts is None:
            self._contacts = self.arm.contacts(self.arm.spec().compile())
        return self._contacts

    def contact_step(self) -> np.ndarray:
        """How far each joint moves between contact checks along a plan or a run (rad or m)."""
        return np.array([CONTACT_STEP[kind] for kind in self.kinds])

    def plant_fit(self, plant, trajectory: JointTrajectory, analysis) -> PlantFit:
        """The added servos designed for the plan (simbench.robots.servo_design), the contacts at its start and along it
        (robots.contacts), and the forces it needs past the limits."""
        dynamics = plan_dynamics(plant, trajectory)
        options = self.arm.options
        servos = design(plant, trajectory, dynamics, self.arm.designed, analysis, options.bandwidth,
                        options.damping_ratio)
        contacts = self.contacts()
        along = _first_touches(contacts.along(trajectory.q_ref, self.contact_step()))
        violations = [Violation("contact", f"the plan puts {touch.describe()} at t = {trajectory.t[k]:.3f} s", 
                                float(trajectory.t[k]), 0, {"bodies": list(touch.bodies), "depth": touch.depth,
                                                            "source": "planner"})
                      for k, touch in along if k > 0]
        return PlantFit(kp={s.joint: s.kp for s in servos}, kv={s.joint: s.kv for s in servos},
                        design=tuple(s.report() for s in servos),
                        start_contacts=tuple(touch.describe() for touch in contacts.at(trajectory.q_ref[0])),
                        violations=tuple(violations + force_violations(plant, trajectory, dynamics)))

    def judges_orientation(self, trajectory: JointTrajectory) -> bool:
        """The tool's orientation is a promise where the plan asks one (its tool_orientation_ref)."""
        return ORIENTATION_REF in trajectory.series

    def summary(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> Summary:
        return self.summariser(traj).whole(traj, rec, series)

    def summariser(self, traj: JointTrajectory) -> Summariser:
        return _Derived(self)


def _first_touches(found: list[tuple[int, Touch]]) -> list[tuple[int, Touch]]:
    """Each pair of bodies' first contact, the deepest of its row."""
    first: dict[tuple[str, str], tuple[int, Touch]] = {}
    for k, touch in found:
        kept = first.get(touch.bodies)
        if kept is None or (kept[0] == k and touch.depth > kept[1].depth):
            first[touch.bodies] = (k, touch)
    return sorted(first.values(), key=lambda item: item[0])


class _Derived(Summariser):
    """The tool's orientation error a window at a time, the contacts of the recorded joints (`contact` events: a
    span a pair of bodies, its deepest overlap), and the report's entry `derived_arm`: the model, what was done to
    its actuators, joints and contacts, and what was dropped."""

    def __init__(self, arm: ModelArm):
        self.robot, self.arm = arm, arm.arm
        self.spans: dict[tuple[str, str], list] = {}  # each pair's spans: [t_start, t_end, deepest, touch]
        self.open: set[tuple[str, str]] = set()  # the pairs in touch at the row checked last

    def add(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> dict[str, Array]:
        robot = self.robot
        asked = (quat_to_matrix(traj.series[ORIENTATION_REF]) if ORIENTATION_REF in traj.series
                 else robot.tool_rotation(traj.q_ref))
        self._contacts(rec)
        return {ORIENTATION_ERROR: rotation_angle(asked, robot.tool_rotation(rec.q))}

    def _contacts(self, rec: Recording) -> None:
        """The window's contacts at its checked rows (robots.contacts.checked_rows): a pair in touch at two checked
        rows in a row is one span."""
        contacts = self.robot.contacts()
        for k in checked_rows(rec.q, self.robot.contact_step()):
            t = float(rec.t[k])
            touching = {touch.bodies: touch for touch in contacts.at(rec.q[k])}
            for pair, touch in touching.items():
                spans = self.spans.setdefault(pair, [])
                if pair in self.open:
                    spans[-1][1] = t
                    if touch.depth > spans[-1][2]:
                        spans[-1][2:] = [touch.depth, touch]
                else:
                    spans.append([t, t, touch.depth, touch])
            self.open = set(touching)

    def finish(self):
        arm = self.arm
        events = [Event(t0, t1, "contact", {"bodies": list(touch.bodies), "geoms": [touch.geom1, touch.geom2],
                                            "depth": depth, "describe": touch.describe()})
                  for spans in self.spans.values() for t0, t1, depth, touch in spans]
        return {"derived_arm": {"model": Path(arm.path).name, "tool": arm.chain.tool.describe(),
                                "reach": arm.chain.reach, "actuator_notes": arm.notes(),
                                "locked_joints": list(arm.locked),
                                "excluded_pairs": [list(pair) for pair in arm.excluded],
                                "integrator": arm.integrator,
                                "added": list(arm.added), "dropped": list(arm.dropped)}}, events
