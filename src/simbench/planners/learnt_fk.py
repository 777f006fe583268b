"""Learnt forward kinematics of the Agile Eye (paper 003, section 4): one network per working mode.

The paper maps base angles to ZYX Euler angles with one hidden layer of 7 tanh units a mode. simbench departs:
  - inputs sin(theta_i), cos(theta_i), which do not wrap at +-pi;
  - outputs R's first two columns, made a rotation by Gram-Schmidt (Euler angles wrap and lose a degree of freedom);
  - two hidden layers of 64 tanh units (L-BFGS) on 20000 poses: line of sight within 75 deg of home, torsion
    within +-45 deg, away from the singular curves, where the FK is ill-conditioned (so the planner checks every
    window with the exact FK);
  - mode 0's network is trained and the other seven derived exactly: pi added to leg i's angle negates its sin
    and cos, so mode m's network is mode 0's with its flipped legs' first-layer rows negated.

The weights ship in `data/agile_eye_fk.npz` with their held-out error; `python -m simbench train-fk` retrains them
(needs scikit-learn). Gradients are by reverse mode (LearntFK.forward, rates_vjp).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

from simbench.core import extras
from simbench.maths.rotations import axis_rotation, rotation_angle
from simbench.robots import agile_eye

WEIGHTS = Path(__file__).resolve().parent.parent / "data" / "agile_eye_fk.npz"
CONE = np.deg2rad(75.0)
TORSION = np.deg2rad(45.0)
_E1 = np.cross(agile_eye.LINE_OF_SIGHT, [0.0, 0.0, 1.0])  # across the line of sight: tilt azimuths start here
_E1 /= np.linalg.norm(_E1)


def sample_workspace(n: int, rng: np.random.Generator) -> np.ndarray:
    """n platform orientations (n, 3, 3): line of sight uniform in the cone, torsion uniform."""
    los = agile_eye.LINE_OF_SIGHT
    cos_tilt = rng.uniform(np.cos(CONE), 1.0, n)
    tilt, azimuth = np.arccos(cos_tilt), rng.uniform(0.0, 2 * np.pi, n)
    e2 = np.cross(los, _E1)
    axis = np.cos(azimuth)[:, None] * _E1 + np.sin(azimuth)[:, None] * e2  # tilt axes, perpendicular to los
    tilt_rot = axis_rotation(axis, tilt)
    twist = axis_rotation(np.broadcast_to(los, (n, 3)), rng.uniform(-TORSION, TORSION, n))
    return tilt_rot @ twist


def workspace_coordinates(rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tilt of the line of sight from home and torsion about it (rad), the coordinates sample_workspace draws."""
    los = agile_eye.LINE_OF_SIGHT
    sight = np.reshape(rot, (-1, 3, 3)) @ los
    axis = np.cross(los, sight)
    sine = np.linalg.norm(axis, axis=1)
    tilt = np.arctan2(sine, sight @ los)
    axis = np.where(sine[:, None] > 1e-12, axis / np.maximum(sine, 1e-12)[:, None], [1.0, 0.0, 0.0])
    untilted = np.einsum("nji,njk->nik", axis_rotation(axis, tilt), np.reshape(rot, (-1, 3, 3)))
    turned = untilted @ _E1
    return tilt, np.arctan2(np.cross(_E1, turned) @ los, turned @ _E1)


def in_workspace(rot: np.ndarray, slack: float = np.deg2rad(2.0)) -> np.ndarray:
    """Whether orientations lie in the training workspace (within `slack` of its edge)."""
    tilt, torsion = workspace_coordinates(rot)
    return (tilt <= CONE + slack) & (np.abs(torsion) <= TORSION + slack)


def features(theta: np.ndarray) -> np.ndarray:
    """Network inputs (N, 6): sin and cos of the base angles."""
    return np.concatenate([np.sin(theta), np.cos(theta)], axis=1)


def to_rotation(out: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) from network outputs (N, 6) = two columns, by Gram-Schmidt."""
    a, b = out[:, :3], out[:, 3:]
    c1 = a / np.linalg.norm(a, axis=1, keepdims=True)
    b = b - np.einsum("ij,ij->i", c1, b)[:, None] * c1
    c2 = b / np.linalg.norm(b, axis=1, keepdims=True)
    return np.stack([c1, c2, np.cross(c1, c2)], axis=-1)


def _rotation_vjp(out: np.ndarray, torque: np.ndarray, rot: np.ndarray | None = None) -> np.ndarray:
    """The cotangent g (N, 6) of network outputs with g . d_out = torque . omega, omega (base frame) the angular
    velocity of to_rotation(out): Gram-Schmidt differentiated. With p = c1 . b, b' = b - p c1 and t = R^T torque:
    g_b = t_1 c3 / |b'|, g_a = (t_3 c2 - (t_2 + t_1 p / |b'|) c3) / |a|. `rot`: to_rotation(out) if at hand."""
    rot = to_rotation(out) if rot is None else rot
    a, b = out[:, :3], out[:, 3:]
    norm_a = np.linalg.norm(a, axis=1, keepdims=True)
    c1, c2, c3 = rot[:, :, 0], rot[:, :, 1], rot[:, :, 2]
    p = np.einsum("ij,ij->i", c1, b)[:, None]
    norm_b = np.linalg.norm(b - p * c1, axis=1, keepdims=True)
    t = np.einsum("nck,nc->nk", rot, torque)  # body components of the torque
    g_a = (t[:, 2:3] * c2 - (t[:, 1:2] + t[:, 0:1] * p / norm_b) * c3) / norm_a
    return np.concatenate([g_a, t[:, 0:1] * c3 / norm_b], axis=1)


def targets(rot: np.ndarray) -> np.ndarray:
    """Network outputs (N, 6) for orientations: their first two columns."""
    return np.concatenate([rot[:, :, 0], rot[:, :, 1]], axis=1)


@dataclass(frozen=True)
class Network:
    """A tanh multilayer perceptron with a linear output layer."""

    weights: tuple[np.ndarray, ...]
    biases: tuple[np.ndarray, ...]

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.layers(x)[-1]

    def layers(self, x: np.ndarray) -> list[np.ndarray]:
        """The input, every hidden layer's output and the output, for vjp."""
        out = [x]
        for w, b in zip(self.weights[:-1], self.biases[:-1]):
            x = np.tanh(x @ w + b)
            out.append(x)
        out.append(x @ self.weights[-1] + self.biases[-1])
        return out

    def vjp(self, layers: list[np.ndarray], g_out: np.ndarray) -> np.ndarray:
        """The gradient in the inputs (N, in) of g_out . output (N, out), by reverse mode through `layers`."""
        g = g_out @ self.weights[-1].T
        for w, h in zip(reversed(self.weights[:-1]), reversed(layers[1:-1])):
            g = (g * (1.0 - h * h)) @ w.T
        return g


@dataclass(frozen=True)
class LearntFK:
    """The 8 per-mode networks and what their training measured."""

    networks: tuple[Network, ...]
    heldout_deg: dict

    def __call__(self, theta: np.ndarray, mode: int) -> np.ndarray:
        """Estimated platform orientations (N, 3, 3) for base angles (N, 3) of working mode `mode`."""
        return to_rotation(self.networks[mode](features(np.atleast_2d(theta))))

    def forward(self, theta: np.ndarray, mode: int) -> tuple[np.ndarray, list[np.ndarray]]:
        """The estimate (N, 3, 3), as calling this gives it, and the network's layers for rates_vjp."""
        layers = self.networks[mode].layers(features(np.atleast_2d(theta)))
        return to_rotation(layers[-1]), layers

    def rates_vjp(self, theta: np.ndarray, mode: int, torque: np.ndarray, layers: list[np.ndarray],
                  rot: np.ndarray | None = None) -> np.ndarray:
        """The gradient (N, 3) in the base angles of anything whose derivative in the platform's rotation (base
        frame) is `torque` (N, 3), by reverse mode (`layers` and `rot`, if at hand, from forward)."""
        theta = np.atleast_2d(theta)
        g_x = self.networks[mode].vjp(layers, _rotation_vjp(layers[-1], torque, rot))
        return g_x[:, :3] * np.cos(theta) - g_x[:, 3:] * np.sin(theta)  # d sin = cos, d cos = -sin


@cache
def load(path: Path = WEIGHTS) -> LearntFK:
    """The shipped (or given) networks."""
    data = np.load(path)
    networks = []
    for m in range(8):
        layers = int(data[f"layers_{m}"])
        networks.append(Network(tuple(data[f"w_{m}_{k}"] for k in range(layers)),
                                tuple(data[f"b_{m}_{k}"] for k in range(layers))))
    heldout = {key: data[key].tolist() for key in ("median", "p95", "max")}
    heldout.update(samples=int(data["samples"]), hidden=data["hidden"].tolist(), seed=int(data["seed"]))
    return LearntFK(tuple(networks), heldout)


def training_set(mode: int, samples: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(theta, orientation) pairs of one working mode from the exact IK of workspace samples."""
    rot = sample_workspace(samples, np.random.default_rng([seed, mode]))
    return agile_eye.ik(rot, mode), rot


def for_mode(base: Network, mode: int) -> Network:
    """Mode `mode`'s network from mode 0's: the input rows of the legs the mode turns by pi, negated."""
    flip = np.ones(6)
    for leg in range(3):
        if mode >> leg & 1:
            flip[[leg, leg + 3]] = -1.0
    return Network((base.weights[0] * flip[:, None], *base.weights[1:]), base.biases)


def train(samples: int = 20000, hidden: tuple[int, ...] = (64, 64), seed: int = 0, out: Path = WEIGHTS,
          log=print) -> dict:
    """Fit mode 0's network on 75 % of the samples, derive the others, check each on held-out poses of its mode,
    write them to `out`; the held-out errors (deg). Needs scikit-learn (the `train` extra)."""
    extras.require("sklearn", "training the learnt FK", "train-fk")
    split = int(0.75 * samples)
    mode_0 = training_set(0, samples, seed)
    base = _fit(*mode_0, split, hidden, seed)
    arrays: dict[str, np.ndarray] = {}
    stats: dict[str, list[float]] = {"median": [], "p95": [], "max": []}
    for m in range(8):
        net = for_mode(base, m)
        theta, rot = mode_0 if m == 0 else training_set(m, samples, seed)
        error = np.rad2deg(rotation_angle(to_rotation(net(features(theta[split:]))), rot[split:]))
        for key, value in (("median", np.median(error)), ("p95", np.percentile(error, 95)), ("max", error.max())):
            stats[key].append(float(value))
        log(f"mode {m}: held-out error median {stats['median'][-1]:.3f} deg, 95th percentile "
            f"{stats['p95'][-1]:.3f} deg, max {stats['max'][-1]:.3f} deg")
        arrays.update(_arrays(net, m))
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out, **arrays, **{k: np.array(v) for k, v in stats.items()}, samples=np.array(samples),
                        hidden=np.array(hidden), seed=np.array(seed))
    load.cache_clear()
    return stats


def _fit(theta: np.ndarray, rot: np.ndarray, split: int, hidden: tuple[int, ...], seed: int) -> Network:
    """Mode 0's network fitted by scikit-learn on the first `split` samples (tanh layers, L-BFGS)."""
    from sklearn.neural_network import MLPRegressor
    model = MLPRegressor(hidden_layer_sizes=hidden, activation="tanh", solver="lbfgs", max_iter=4000, tol=1e-10,
                         random_state=seed)
    model.fit(features(theta[:split]), targets(rot[:split]))
    return Network(tuple(model.coefs_), tuple(model.intercepts_))


def _arrays(net: Network, mode: int) -> dict[str, np.ndarray]:
    """A mode's network as the weights file stores it."""
    arrays = {f"layers_{mode}": np.array(len(net.weights))}
    for k, (w, b) in enumerate(zip(net.weights, net.biases)):
        arrays[f"w_{mode}_{k}"], arrays[f"b_{mode}_{k}"] = w, b
    return arrays
