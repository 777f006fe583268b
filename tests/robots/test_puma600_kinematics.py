"""PUMA 600 kinematics against MuJoCo's compiled model, and the analytic IK in its 8 configurations."""

import itertools

import mujoco
import numpy as np
import pytest

from simbench.core.plant import Plant
from simbench.robots import Tolerance
from simbench.robots import puma600 as P

ROBOT = P.ROBOT


@pytest.fixture(scope="module")
def plant():
    return Plant.load(ROBOT)


def random_q(n: int, seed: int, margin: float = 0.0) -> np.ndarray:
    q = np.random.default_rng(seed).uniform(ROBOT.lower + margin, ROBOT.upper - margin, size=(n, 6))
    return q


def test_fk_wrist_and_orientation_equal_mujoco_sites(plant):
    model, data = plant.model, mujoco.MjData(plant.model)
    q = random_q(1000, seed=0)
    pos, rot = P.tool_pose(q)
    wrist = P.wrist_center(q)
    for i, qi in enumerate(q):
        data.qpos[plant.qpos_adr] = qi
        mujoco.mj_kinematics(model, data)
        assert np.abs(data.site("tool").xpos - pos[i]).max() < 1e-9
        assert np.abs(data.site("wrist_center").xpos - wrist[i]).max() < 1e-9
        assert np.abs(data.site("tool").xmat.reshape(3, 3) - rot[i]).max() < 1e-9


def test_jacobian_equals_mujoco_site_jacobian(plant):
    model, data = plant.model, mujoco.MjData(plant.model)
    jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    for qi in random_q(200, seed=1):
        data.qpos[plant.qpos_adr] = qi
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_jacSite(model, data, jacp, jacr, model.site("tool").id)
        mj = np.vstack([jacp, jacr])[:, plant.dof_adr]
        assert np.abs(P.jacobian(qi)[0] - mj).max() < 1e-9


def test_ik_of_fk_returns_q_in_its_own_configuration():
    q = random_q(3000, seed=2)
    q = q[np.abs(np.sin(q[:, 4])) > 1e-2]  # q4 and q6 are not separable at the wrist singularity
    pos, rot = P.tool_pose(q)
    back = P.ik(pos, rot, P.configuration(q))
    assert np.abs(np.angle(np.exp(1j * (back - q)))).max() < 1e-8


def test_eight_configurations_reach_the_same_pose_and_are_distinct():
    q = random_q(300, seed=3, margin=0.2)
    pos, rot = P.tool_pose(q)
    solutions = []
    for flags in itertools.product((-1.0, 1.0), repeat=3):
        sol = P.ik(pos, rot, np.array(flags))
        ok = ~np.isnan(sol).any(axis=1)
        assert ok.mean() > 0.99
        p2, r2 = P.tool_pose(sol[ok])
        assert np.abs(p2 - pos[ok]).max() < 1e-9 and np.abs(r2 - rot[ok]).max() < 1e-9
        assert np.all(P.configuration(sol[ok]) == np.array(flags))
        solutions.append(sol)
    stacked = np.stack(solutions, axis=1)
    for i, j in itertools.combinations(range(8), 2):
        diff = np.abs(np.angle(np.exp(1j * (stacked[:, i] - stacked[:, j])))).max(axis=1)
        assert np.all(diff[~np.isnan(diff)] > 1e-3)


def test_named_poses_have_the_documented_configurations():
    assert P.configuration(P.HOME).tolist() == [[-1.0, 1.0, 1.0]]  # Corke's qn: righty, elbow up
    corke_zero = np.deg2rad([180.0, 180.0, 0, 0, 30.0, 0])
    assert P.configuration(corke_zero)[0, 0] == P.ARM["righty"]  # "zero angle position is a righty" (Corke)


def test_elbow_up_means_the_elbow_lies_above_the_shoulder_wrist_line():
    q = random_q(5000, seed=4)
    origins, _ = P.link_frames(q)
    wrist, elbow = origins[:, 3], origins[:, 2]
    u = wrist / np.linalg.norm(wrist, axis=1, keepdims=True)
    above = np.sign((elbow - np.einsum("ij,ij->i", elbow, u)[:, None] * u)[:, 2])
    level = np.abs(u[:, 2]) < 0.5
    assert np.mean(above[level] == P.configuration(q[level])[:, 1]) > 0.98


def singular_q(kind: str) -> np.ndarray:
    q = np.deg2rad([170.0, -120.0, -160.0, 30.0, 40.0, 10.0])
    if kind == "wrist":
        q[4] = 0.0
    elif kind == "elbow":
        q[2] = P.STRETCH
    else:  # shoulder: r = c2 g - s2 h = 0
        g = P.A3 * np.cos(q[2]) - P.D4 * np.sin(q[2]) + P.A2
        h = P.A3 * np.sin(q[2]) + P.D4 * np.cos(q[2])
        q[1] = np.arctan2(g, h)
    return q


@pytest.mark.parametrize("kind", ["shoulder", "elbow", "wrist"])
def test_singular_sets_are_where_mujocos_jacobian_loses_rank(plant, kind):
    model, data = plant.model, mujoco.MjData(plant.model)
    q = singular_q(kind)
    data.qpos[plant.qpos_adr] = q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    mujoco.mj_jacSite(model, data, jacp, jacr, model.site("tool").id)
    sv = np.linalg.svd(np.vstack([jacp, jacr])[:, plant.dof_adr], compute_uv=False)
    assert sv[-1] / sv[0] < 1e-9
    sets = {s.name: s for s in P.singular_sets(q[None], Tolerance(np.deg2rad(1), 1e-3))}
    assert sets[kind].distance[0] < 1e-6
    assert all(s.distance[0] > 1 for name, s in sets.items() if name != kind)
    assert P.measures(q[None])["manipulability"][0] < 1e-9


def test_shoulder_gap_is_the_wrist_sites_distance_from_the_shoulder_singular_plane(plant):
    """|r| = |c1 Px + s1 Py| read off MuJoCo's wrist-centre site (base frame), for random q: the closed form
    without q1 that puma600.shoulder_gap uses is that distance."""
    model, data = plant.model, mujoco.MjData(plant.model)
    base = model.body("base").id
    for q in np.random.default_rng(21).uniform(-np.pi, np.pi, (40, 6)):
        data.qpos[plant.qpos_adr] = q
        mujoco.mj_kinematics(model, data)
        p = data.xmat[base].reshape(3, 3).T @ (data.site("wrist_center").xpos - data.xpos[base])
        assert P.shoulder_gap(q[None])[0] == pytest.approx(abs(np.cos(q[0]) * p[0] + np.sin(q[0]) * p[1]), abs=1e-9)
