"""simbench.api.Robot of an arm derived from its MJCF model (robots.model_scene): kinematics from MuJoCo itself.

The tool point and its Jacobian J = [Jp; Jr] (6 x dof: m/s and rad/s per joint speed) are MuJoCo's (mj_kinematics,
mj_jacSite on a private MjData, the other joints at qpos0). Its singular measures, per sample:

    sigma_min           least singular value of J (of the min(6, dof) it has), SI as J is
    manipulability      Yoshikawa's, the product of J's singular values (sqrt det(J J^T) where dof >= 6)
    inverse_condition   sigma_min / sigma_max of the unit-consistent Jacobian Ju = [Jp / L; Jr]

with L the arm's reach (robots.chain.Chain.reach), so that a metre of tool motion at the end of the reach counts as
a radian. The singular set `rank_loss` is where Ju loses rank; its gap, Ju's least singular value, grows near it as
the joint angle away from it (rad), so it is near below the analysis' `near_angle` (robots.rank_loss).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import mujoco
import numpy as np

from simbench.api import Array, JointTrajectory, Recording, Robot, SingularSet, Summariser, Summary, Tolerance
from simbench.plant import register_scene
from simbench.robots.model_scene import TOOL_SENSOR, TOOL_SITE, DerivedArm
from simbench.robots.rank_loss import closest_sample, rank_loss_detail, unit_jacobian


class ModelArm(Robot):
    """An arm read from its model file (DerivedArm), with speed limits `qd_max` (SI, one per joint). Its scene is
    registered under the model's path followed by '#simbench' (plant.register_scene)."""

    def __init__(self, arm: DerivedArm, qd_max: Array):
        self.arm = arm
        chain = arm.chain
        super().__init__(name=arm.name, description=f"arm derived from its model {Path(arm.path).name}",
                         scene=self._register(), joints=chain.joints, kinds=chain.kinds, lower=chain.lower,
                         upper=chain.upper, qd_max=qd_max, tool_site=chain.tool.site or TOOL_SITE,
                         tool_sensor=TOOL_SENSOR)
        self._kinematics: tuple[mujoco.MjModel, mujoco.MjData] | None = None

    def _register(self) -> str:
        key = f"{self.arm.path}#simbench-{hashlib.sha1(repr(self.arm.options).encode()).hexdigest()[:12]}"
        register_scene(key, self.arm.spec)
        return key

    def __getstate__(self) -> dict:
        return {**self.__dict__, "_kinematics": None}  # MuJoCo's structures are made anew where it is unpickled

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        register_scene(str(self.scene), self.arm.spec)

    def _posed(self, q: Array):
        """(model, data) at each row of q (N, dof) in turn, kinematics and com positions computed."""
        if self._kinematics is None:
            model = self.arm.spec().compile()
            self._kinematics = model, mujoco.MjData(model)
        model, data = self._kinematics
        adr = [model.joint(name).qposadr[0] for name in self.joints]
        for row in np.atleast_2d(q):
            data.qpos[:] = model.qpos0
            data.qpos[adr] = row
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            yield model, data

    def fk(self, q: Array) -> Array:
        """The tool point (N, 3) in metres at joint values q (N, dof), as MuJoCo places the tool's site."""
        return np.array([data.site(self.tool_site).xpos.copy() for _, data in self._posed(q)])

    @property
    def reach(self) -> float:
        """The characteristic length L (m) of the unit-consistent Jacobian: the chain's reach."""
        return self.arm.chain.reach

    def tool_rotation(self, q: Array) -> Array:
        """The tool site's orientation (N, 3, 3) in the world at joint values q (N, dof): MuJoCo's site_xmat."""
        return np.array([data.site(self.tool_site).xmat.reshape(3, 3).copy() for _, data in self._posed(q)])

    def jacobian(self, q: Array) -> Array:
        """J = [Jp; Jr] (N, 6, dof) at joint values q (N, dof): mj_jacSite's, at the tool site."""
        out = []
        for model, data in self._posed(q):
            jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
            mujoco.mj_jacSite(model, data, jacp, jacr, model.site(self.tool_site).id)
            dofs = [model.joint(name).dofadr[0] for name in self.joints]
            out.append(np.vstack([jacp[:, dofs], jacr[:, dofs]]))
        return np.array(out)

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

    def summary(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> Summary:
        return self.summariser(traj).whole(traj, rec, series)

    def summariser(self, traj: JointTrajectory) -> Summariser:
        return _Derived(self.arm)


class _Derived(Summariser):
    """The report's entry `derived_arm`: the model, what was done to its actuators and what was dropped."""

    def __init__(self, arm: DerivedArm):
        self.arm = arm

    def add(self, traj: JointTrajectory, rec: Recording, series: dict[str, Array]) -> dict[str, Array]:
        return {}

    def finish(self):
        arm = self.arm
        return {"derived_arm": {"model": Path(arm.path).name, "tool": arm.chain.tool.describe(),
                                "reach": arm.chain.reach, "actuator_notes": arm.notes(),
                                "added": list(arm.added), "dropped": list(arm.dropped)}}, []
