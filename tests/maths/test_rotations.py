"""simbench.maths.rotations and the RSMG's commanded rotor motion, in NumPy, against scipy's Rotation (the
independent truth: a library of its own, which a run of the RSMG no longer loads)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from simbench.maths.rotations import canonical, matrix_to_quat, quat_to_matrix
from simbench.planners.round_robin import Motion


def scipy_quat(rot: np.ndarray) -> np.ndarray:
    """scipy's quaternions of rotation matrices, w x y z with w >= 0."""
    xyzw = Rotation.from_matrix(rot).as_quat()
    return canonical(np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1))


def test_quaternions_of_random_and_half_turn_rotations_are_scipys():
    """Random rotations (each of x, y, z and w the largest somewhere) and the half turns, where w = 0 and the
    quaternion comes from the largest of x, y and z: scipy's quaternions to 1e-15, unit, w >= 0, and back to the
    same matrices."""
    axes = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, -2, 3]], float)
    half = Rotation.from_rotvec(np.pi * axes / np.linalg.norm(axes, axis=1)[:, None]).as_matrix()
    rot = np.concatenate([Rotation.random(2000, random_state=4).as_matrix(), half, np.eye(3)[None]])
    quat = matrix_to_quat(rot)
    largest = np.argmax(np.abs(quat), axis=1)
    assert set(largest.tolist()) == {0, 1, 2, 3}
    assert np.abs(quat - scipy_quat(rot)).max() < 1e-15
    assert np.abs(np.linalg.norm(quat, axis=1) - 1).max() < 1e-15 and (quat[:, 0] >= 0).all()
    assert np.abs(quat_to_matrix(quat) - rot).max() < 1e-15


@pytest.mark.parametrize("seed", range(6))
def test_the_rotors_commanded_orientations_are_scipys_compositions(seed):
    """Random turns and tumbles (any axes, up to 100 turns either way): R(s) is scipy's rotation vector 2 pi turns
    s about the axis, and a tumble the precession's after the spin's (their composition), to a few rounding
    steps of the largest angle (hundreds of radians: the angle itself is rounded by 1e-16 of that)."""
    rng = np.random.default_rng(seed)
    unit = [list(v / np.linalg.norm(v)) for v in rng.normal(size=(3, 3))]
    turns = rng.uniform(-100, 100, 3)
    s = np.sort(rng.uniform(0, 1, 500))
    tol = 1e-15 + 4 * np.finfo(float).eps * 2 * np.pi * np.abs(turns).max()
    about = lambda axis, n: Rotation.from_rotvec(2 * np.pi * n * s[:, None] * np.array(axis))
    motion = Motion(kind="turns", axis=unit[0], turns=turns[0])
    assert np.abs(motion.orientation(s) - about(unit[0], turns[0]).as_matrix()).max() < tol
    motion = Motion(kind="tumble", spin_axis=unit[1], spin_turns=turns[1], precession_axis=unit[2],
                    precession_turns=turns[2])
    truth = (about(unit[2], turns[2]) * about(unit[1], turns[1])).as_matrix()
    assert np.abs(motion.orientation(s) - truth).max() < tol
