"""The RSMG's design (paper 001; simbench.robots.rsmg explains it): constants, arm axes, candidate contact points,
and which arms grip; a leaf both rsmg and rsmg_outputs read."""

from __future__ import annotations

import numpy as np

from simbench.api import REVOLUTE

ALPHA = np.deg2rad(70.0)
BETA = np.deg2rad(70.0)
RADIUS = 0.05  # m: the rotor
ARMS = 4
CANDIDATES = 3
GAMMA_BAND = np.deg2rad([10.0, 170.0])  # eq. 45
DET_A_MIN = 0.01  # eq. 46


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _tetrahedron() -> np.ndarray:
    """Arm axes u_i: one straight down, three at 109.47 deg from it, 120 deg apart in azimuth."""
    up = 1.0 / 3.0
    side = np.sqrt(1.0 - up**2)
    azimuth = np.deg2rad([0.0, 120.0, 240.0])
    return np.vstack([[0.0, 0.0, -1.0], np.stack([side * np.cos(azimuth), side * np.sin(azimuth),
                                                  np.full(3, up)], axis=-1)])


U = _tetrahedron()
X_REF = _unit(np.vstack([[1.0, 0.0, 0.0]] + [[0.0, 0.0, 1.0] - u[2] * u for u in U[1:]]))
Y_REF = np.cross(U, X_REF)
# Candidate contact points (rotor frame): arm i's three, 120 deg apart on the great circle normal to u_i.
_PHASE = 2 * np.pi / 3 * np.arange(CANDIDATES)
POINTS = np.stack([np.cos(_PHASE)[:, None] * X_REF[i] + np.sin(_PHASE)[:, None] * Y_REF[i] for i in range(ARMS)])
JOINTS = tuple(f"theta{i + 1}" for i in range(ARMS)) + tuple(f"gamma{i + 1}" for i in range(ARMS))
KINDS = (REVOLUTE,) * (2 * ARMS)
LOWER = np.full(2 * ARMS, -np.inf)
UPPER = np.full(2 * ARMS, np.inf)
QD_MAX = np.full(2 * ARMS, 4 * np.pi)  # 2 turns/s: a small direct-drive motor's speed, the base joints' and gammas'
CHUNK = 1 << 16  # samples the measures and rsmg_outputs' errors work on at once: memory bounded on a long run


def gripping(rec) -> np.ndarray:
    """Which arms grip (their welds on) at each recorded sample (N, 4), bool."""
    return np.stack([rec.eq_active[f"grip{i + 1}"] for i in range(ARMS)], axis=1).astype(bool)
