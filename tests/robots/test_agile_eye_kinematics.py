"""Agile Eye kinematics: IK and FK against each other in every mode, the Jacobians against the motion, the
singular curves, the learnt FK against the exact one, and MuJoCo's closed chain against the FK."""

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from simbench.core.plant import Plant
from simbench.planners import learnt_fk
from simbench.robots import agile_eye as E


def random_rotations(n: int, seed: int, min_gap_deg: float = 1.0) -> np.ndarray:
    rot = Rotation.random(4 * n, random_state=seed).as_matrix()
    return rot[E.axis_gaps(rot).min(axis=1) > np.deg2rad(min_gap_deg)][:n]


@pytest.mark.parametrize("mode", range(8))
def test_fk_of_ik_contains_the_orientation_in_every_working_mode(mode):
    rot = random_rotations(500, seed=mode)
    theta = E.ik(rot, mode)
    solutions = E.fk_all(theta)
    assert np.abs(solutions - rot[:, None]).max(axis=(2, 3)).min(axis=1).max() < 1e-9
    # Every FK solution satisfies the loop closures w_i . v_i = 0, and the 8 are distinct.
    w = E.intermediate_axes(theta)
    assert np.abs(np.einsum("nic,nkci->nki", w, solutions)).max() < 1e-12
    gaps = np.array([[E.rotation_angle(solutions[:, i], solutions[:, j]) for j in range(8)] for i in range(8)])
    off_diagonal = ~np.eye(8, dtype=bool)
    assert gaps[off_diagonal].min() > 1e-6
    # The working mode's bits add pi to each leg's angle and nothing else.
    bits = (mode >> np.arange(3)) & 1
    assert np.allclose(np.angle(np.exp(1j * (theta - E.ik(rot, 0) - np.pi * bits))), 0, atol=1e-12)


def test_jacobians_relate_angular_velocity_and_joint_rates():
    """A omega = B theta_dot (eqs. 4-7) on a motion followed by finite differences of the exact FK."""
    rng = np.random.default_rng(3)
    rot = random_rotations(40, seed=9, min_gap_deg=10)
    for r in rot:
        theta0 = E.ik(r, 0)[0]
        rate = rng.normal(size=3)
        h = 1e-6
        theta = theta0 + np.array([-h, 0.0, h])[:, None] * rate
        path = E.fk_track(theta, r)
        omega_hat = (path[2] @ path[0].T - path[0] @ path[2].T) / (4 * h)
        omega = np.array([omega_hat[2, 1], omega_hat[0, 2], omega_hat[1, 0]])
        a, b = E.jacobians(theta0[None], path[1][None])
        assert np.allclose(a[0] @ omega, b[0] @ rate, atol=1e-6)


@pytest.mark.parametrize("leg", range(3))
@pytest.mark.parametrize("sign", (1.0, -1.0))
def test_det_a_and_det_b_vanish_exactly_on_the_singular_curves(leg, sign):
    rng = np.random.default_rng(leg)
    for spin, theta_free in rng.uniform(-np.pi, np.pi, size=(20, 2)):
        # Any orientation with v_leg = sign * u_leg: align, then spin about u_leg.
        align = Rotation.align_vectors([sign * E.U[leg]], [np.eye(3)[leg]])[0].as_matrix()
        rot = Rotation.from_rotvec(spin * E.U[leg]).as_matrix() @ align
        theta = E.ik(rot, 0)[0]
        theta[leg] = theta_free  # IK leaves this leg's angle free on the curve; any value closes the loop
        a, b = E.jacobians(theta[None], rot[None])
        assert abs(np.linalg.det(a[0])) < 1e-12 and abs(np.linalg.det(b[0])) < 1e-12
        assert E.kci(theta[None], rot[None])[0] == 0.0
    # Off the curves det A does not vanish, and it shrinks with the distance to them.
    rot = random_rotations(3000, seed=20 + leg)
    det = np.abs(np.linalg.det(E.jacobians(E.ik(rot, 0), rot)[0]))
    gap = E.axis_gaps(rot).min(axis=1)
    assert det.min() > 0
    assert np.corrcoef(det, gap)[0, 1] > 0.9


def test_kci_is_one_at_home_and_between_zero_and_one():
    assert E.kci(np.zeros((1, 3)), np.eye(3)[None])[0] == pytest.approx(1.0)
    rot = random_rotations(1000, seed=5)
    kci = E.kci(E.ik(rot, 0), rot)
    assert np.all((kci > 0) & (kci <= 1 + 1e-12))


def test_learnt_fk_held_out_error_in_every_mode():
    """The shipped networks against the exact FK on fresh poses (a seed training never used): nothing trains."""
    fk = learnt_fk.load()
    for mode in range(8):
        theta, rot = learnt_fk.training_set(mode, 3000, seed=12345)
        error = np.rad2deg(E.rotation_angle(fk(theta, mode), rot))
        assert np.median(error) < 0.6 and np.percentile(error, 95) < 2.5
        assert np.median(error) == pytest.approx(fk.heldout_deg["median"][mode], rel=0.25)


def test_learnt_fk_modes_are_mode_zero_with_flipped_inputs():
    fk = learnt_fk.load()
    theta0, rot = learnt_fk.training_set(0, 200, seed=7)
    for mode in range(1, 8):
        theta = E.ik(rot, mode)
        assert np.allclose(fk(theta, mode), fk(theta0, 0), atol=1e-12)


def test_workspace_coordinates_invert_the_sampler():
    rng = np.random.default_rng(0)
    rot = learnt_fk.sample_workspace(2000, rng)
    tilt, torsion = learnt_fk.workspace_coordinates(rot)
    assert tilt.max() <= learnt_fk.CONE + 1e-9 and np.abs(torsion).max() <= learnt_fk.TORSION + 1e-9
    assert learnt_fk.in_workspace(rot).all()
    assert not learnt_fk.in_workspace(Rotation.from_rotvec([0, 0, 2.5]).as_matrix()[None])[0]


def test_assembled_model_puts_the_platform_at_r_with_closed_loops():
    plant = Plant.load(E.ROBOT)
    model, data = plant.model, mujoco.MjData(plant.model)
    for rot in learnt_fk.sample_workspace(50, np.random.default_rng(1)):
        theta = E.ik(rot, 0)[0]
        data.qpos[:] = 0
        data.qpos[:] = plant.initial_qpos(theta)
        mujoco.mj_kinematics(model, data)
        assert np.abs(data.body("platform").xmat.reshape(3, 3) - rot).max() < 1e-12
        for leg in (2, 3):
            assert np.linalg.norm(data.site(f"tip{leg}").xpos - data.site(f"mount{leg}").xpos) < 1e-12


def test_simulated_platform_equals_the_fk_of_the_simulated_base_angles(evaluated):
    _, ev = evaluated("agile_eye", "avoidance")
    rec = ev.recording
    rot = E.quat_to_matrix(rec.sensors["platform_quat"])
    fk = E.fk_track(rec.q, rot[0])
    assert np.rad2deg(E.rotation_angle(fk, rot)).max() < 0.05
