"""The spherical arm's analytic kinematics against MuJoCo's compiled model of it."""

import mujoco
import numpy as np
import pytest

from simbench.core.plant import Plant
from simbench.robots import Tolerance, spherical_arm

ROBOT = spherical_arm.ROBOT


@pytest.fixture(scope="module")
def plant():
    return Plant.load(ROBOT)


def random_configurations(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lo = np.where(np.isfinite(ROBOT.lower), ROBOT.lower, -np.pi)
    hi = np.where(np.isfinite(ROBOT.upper), ROBOT.upper, 3 * np.pi)
    return rng.uniform(lo, hi, size=(n, ROBOT.dof))


def mujoco_tool(plant, q: np.ndarray) -> np.ndarray:
    data = mujoco.MjData(plant.model)
    out = np.empty((len(q), 3))
    for i, qi in enumerate(q):
        data.qpos[plant.qpos_adr] = qi
        mujoco.mj_kinematics(plant.model, data)
        out[i] = data.site(ROBOT.tool_site).xpos
    return out


def test_fk_equals_mujoco_tool_site(plant):
    q = random_configurations(1000, seed=1)
    assert np.abs(spherical_arm.fk(q) - mujoco_tool(plant, q)).max() < 1e-9


def test_jacobian_equals_mujoco_site_jacobian(plant):
    model, data = plant.model, mujoco.MjData(plant.model)
    q = random_configurations(200, seed=2)
    jac = spherical_arm.jacobian(q)
    jacp = np.zeros((3, model.nv))
    for qi, ji in zip(q, jac):
        data.qpos[plant.qpos_adr] = qi
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_jacSite(model, data, jacp, None, model.site(ROBOT.tool_site).id)
        assert np.abs(jacp[:, plant.dof_adr] - ji).max() < 1e-9


def test_jacobian_loses_rank_exactly_where_cos_q3_is_zero():
    q = random_configurations(500, seed=3)
    on_axis = q.copy()
    on_axis[:, 2] = np.pi / 2
    assert np.all(np.linalg.matrix_rank(spherical_arm.jacobian(on_axis), tol=1e-12) == 2)
    assert np.allclose(spherical_arm.manipulability(on_axis), 0.0, atol=1e-9)
    off_axis = q[np.abs(np.cos(q[:, 2])) > 1e-3]
    assert np.all(np.linalg.matrix_rank(spherical_arm.jacobian(off_axis), tol=1e-12) == 3)
    assert np.all(spherical_arm.manipulability(off_axis) > 0)


def test_axis_distance_is_the_tool_distance_from_the_lift_axis():
    q = random_configurations(300, seed=4)
    x = spherical_arm.fk(q)
    assert np.allclose(spherical_arm.axis_distance(q), np.hypot(x[:, 0], x[:, 1]), atol=1e-12)


@pytest.mark.parametrize("name, q_deg_mm", [
    ("p1", [10, 200, 90, 0]), ("p2", [10, 200, 90, 400]),
    ("p3", [0, 0, -75, 100]), ("p4", [0, 0, 180, 100]), ("p5", [0, 0, 30, 0]), ("p6", [0, 0, 30, 400]),
    ("p7", [0, 400, -75, 100]), ("p8", [0, 400, 180, 100]), ("p9", [0, 400, 30, 0]), ("p10", [0, 400, 30, 400]),
    ("p11", [0, 200, -75, 0]), ("p12", [0, 200, -75, 400]), ("p13", [0, 200, 180, 0]),
    ("p14", [0, 200, 180, 400]),
])
def test_singular_set_classifier_names_paper_sets(name, q_deg_mm):
    q = np.array([[np.deg2rad(q_deg_mm[0]), q_deg_mm[1] / 1e3, np.deg2rad(q_deg_mm[2]), q_deg_mm[3] / 1e3]])
    tol = Tolerance(angle=np.deg2rad(1), length=1e-3)
    on = {s.name for s in spherical_arm.singular_sets(q, tol) if s.distance[0] <= 1.0}
    assert name in on
    # Moving the pair's joints 2 tolerances away leaves the set.
    nudged = q + np.array([[0, 2e-3, np.deg2rad(2), 2e-3]]) * np.sign(0.2 - q / np.maximum(ROBOT.upper, 1))
    off = {s.name for s in spherical_arm.singular_sets(nudged, tol) if s.distance[0] <= 1.0}
    assert name not in off


def test_singular_set_distance_scales_with_tolerance():
    q = np.array([[0.0, 0.2, np.pi / 2 + np.deg2rad(1.5), 0.0]])
    sets = {s.name: s for s in spherical_arm.singular_sets(q, Tolerance(np.deg2rad(2), 1e-3))}
    assert sets["p1"].distance[0] == pytest.approx(0.75)
    assert sets["p1"].gaps["q3"][0] == pytest.approx(np.deg2rad(1.5))
    assert sets["cos_q3_zero"].distance[0] == pytest.approx(0.75)
    assert sets["p2"].distance[0] == pytest.approx(400.0)


def test_singular_sets_are_their_joints_largest_scaled_gap_on_random_configurations():
    """Each of the 15 sets (which share their gaps: robots.joint_set) is, sample by sample, the largest of its
    joints' gaps |q_j - v_j| in multiples of the tolerance of the joint's kind, computed here from the paper's
    values one set at a time; a joint the set does not hold has no gap."""
    rng = np.random.default_rng(7)
    q = rng.uniform(np.where(np.isfinite(ROBOT.lower), ROBOT.lower, -np.pi),
                    np.where(np.isfinite(ROBOT.upper), ROBOT.upper, np.pi), (200, 4))
    q[::3, 2] = np.pi / 2  # on the S(2) sets' q3
    tol = Tolerance(angle=np.deg2rad(2), length=3e-3)
    held = {"cos_q3_zero": {2: np.pi / 2}, "p1": {2: np.pi / 2, 3: 0.0}, "p2": {2: np.pi / 2, 3: 0.4}}
    held |= {f"p{i}": {ja: va, jb: vb} for i, ((ja, va), (jb, vb), _) in enumerate(spherical_arm._S3, start=3)}
    sets = spherical_arm.singular_sets(q, tol)
    assert [s.name for s in sets] == list(held)
    for s in sets:
        gaps = {j: np.abs(q[:, j] - v) for j, v in held[s.name].items()}
        scale = {j: tol.angle if ROBOT.kinds[j] == "revolute" else tol.length for j in gaps}
        assert set(s.gaps) == {ROBOT.joints[j] for j in gaps}
        for j, gap in gaps.items():
            np.testing.assert_array_equal(s.gaps[ROBOT.joints[j]], gap)
        np.testing.assert_allclose(s.distance, np.max([gap / scale[j] for j, gap in gaps.items()], axis=0),
                                   rtol=1e-15)
