"""PUMA 600 manipulability and condition number against NumPy's SVD of `puma600.jacobian`."""

import numpy as np

from simbench.robots import puma600 as P

RNG_SEED = 14


def random_q(n: int, rng: np.random.Generator) -> np.ndarray:
    """n joint vectors uniform over [-pi, pi]^6 (the measures do not look at the joint limits)."""
    return rng.uniform(-np.pi, np.pi, (n, 6))


def near_singular(kind: str, q: np.ndarray, offset: float) -> np.ndarray:
    """q moved to `offset` (rad) from the shoulder (r = 0), elbow (arm stretched) or wrist (q5 = 0) singularity."""
    q = q.copy()
    if kind == "wrist":
        q[:, 4] = offset
    elif kind == "elbow":
        q[:, 2] = P.STRETCH + offset
    else:  # shoulder: r = c2 g - s2 h = 0 at q2 = atan2(g, h)
        g = P.A3 * np.cos(q[:, 2]) - P.D4 * np.sin(q[:, 2]) + P.A2
        h = P.A3 * np.sin(q[:, 2]) + P.D4 * np.cos(q[:, 2])
        q[:, 1] = np.arctan2(g, h) + offset
    return q


def svd_truth(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Manipulability and condition number the straightforward way: the SVD of the chain-built Jacobian."""
    jac = P.jacobian(q)
    jac[:, :3] /= P.A2 + P.D4
    sv = np.linalg.svd(jac, compute_uv=False)
    return np.prod(sv, axis=-1), sv[:, 0] / sv[:, -1]


def samples() -> np.ndarray:
    """4000 random joint vectors, and 100 at each of 1e-2 .. 1e-8 rad from each singular set."""
    rng = np.random.default_rng(RNG_SEED)
    near = [near_singular(kind, random_q(100, rng), offset) for kind in ("shoulder", "elbow", "wrist")
            for offset in (1e-2, 1e-4, 1e-6, 1e-8)]
    return np.concatenate([random_q(4000, rng), *near])


def test_measures_equal_the_svd_of_the_jacobian_also_near_each_singular_set():
    q = samples()
    manipulability, condition = svd_truth(q)
    m = P.measures(q)
    # The SVD's least singular value is good to about 1e-16 of the largest: relative errors of eps * condition.
    slack = 1e-9 + 1e-13 * condition
    assert np.all(np.abs(m["condition"] / condition - 1) <= slack)
    assert np.all(np.abs(m["manipulability"] - manipulability) <= slack * manipulability + 1e-15)
    assert condition.max() > 1e6  # the near-singular samples reached the SVD branch
    assert np.median(np.abs(m["condition"] / condition - 1)[condition < 100]) < 1e-14


def test_manipulability_is_the_determinant():
    q = random_q(500, np.random.default_rng(RNG_SEED + 1))
    jac = P.jacobian(q)
    jac[:, :3] /= P.A2 + P.D4
    np.testing.assert_allclose(P.manipulability(q), np.abs(np.linalg.det(jac)), rtol=1e-12, atol=1e-15)


def test_frame3_jacobian_has_the_chain_jacobians_gram_matrix():
    q = random_q(500, np.random.default_rng(RNG_SEED + 2))
    jac = P.jacobian(q)
    jac[:, :3] /= P.A2 + P.D4
    j3 = P.frame3_jacobian(q)
    np.testing.assert_allclose(j3.transpose(0, 2, 1) @ j3, jac.transpose(0, 2, 1) @ jac, atol=1e-14)
