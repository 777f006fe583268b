"""Rotations as NumPy arrays: matrices (N, 3, 3) and unit quaternions (N, 4) in MuJoCo's order, w x y z."""

from __future__ import annotations

import numpy as np


def axis_rotation(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues' rotation matrices (N, 3, 3) about unit axes (N, 3) by angles (N,)."""
    k = np.zeros((len(axis), 3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
    k -= k.transpose(0, 2, 1)
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * k + (1 - c) * k @ k


def quat_to_matrix(quat: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of unit quaternions (N, 4), w x y z."""
    w, x, y, z = np.reshape(quat, (-1, 4)).T
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)


def canonical(quat: np.ndarray) -> np.ndarray:
    """The same rotations (N, 4), w x y z, each with w >= 0 (q and -q are one rotation)."""
    return quat * np.where(quat[:, :1] < 0, -1.0, 1.0)


def matrix_to_quat(rot: np.ndarray) -> np.ndarray:
    """Unit quaternions (N, 4), w x y z with w >= 0, of rotation matrices (N, 3, 3), each from the largest of w,
    x, y and z (Shepperd's method, as scipy's); in NumPy, so that a run need not load scipy.spatial."""
    m = np.reshape(rot, (-1, 3, 3))
    diag = np.einsum("nii->ni", m)
    trace = diag.sum(axis=1)
    choice = np.argmax(np.concatenate([diag, trace[:, None]], axis=1), axis=1)  # x, y, z or w largest
    xyzw = np.empty((len(m), 4))
    w = choice == 3
    xyzw[w] = np.stack([m[w, 2, 1] - m[w, 1, 2], m[w, 0, 2] - m[w, 2, 0], m[w, 1, 0] - m[w, 0, 1], 1 + trace[w]], -1)
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        c = choice == i
        xyzw[c, i] = 1 - trace[c] + 2 * m[c, i, i]
        xyzw[c, j] = m[c, j, i] + m[c, i, j]
        xyzw[c, k] = m[c, k, i] + m[c, i, k]
        xyzw[c, 3] = m[c, k, j] - m[c, j, k]
    xyzw /= np.sqrt(np.einsum("ij,ij->i", xyzw, xyzw))[:, None]
    return canonical(np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1))


def rotation_angle(r1: np.ndarray, r2: np.ndarray) -> np.ndarray:
    """Geodesic angle (N,) between rotations r1 and r2 (N, 3, 3)."""
    cos = (np.einsum("nij,nij->n", r1, r2) - 1) / 2
    return np.arccos(np.clip(cos, -1.0, 1.0))
