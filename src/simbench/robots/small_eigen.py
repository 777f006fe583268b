"""The least and the largest eigenvalue of many small symmetric matrices at once, in NumPy operations over the
samples rather than one LAPACK call a matrix (which costs some microseconds of call overhead for a 6 x 6).

Householder reduction to a tridiagonal T (Golub and Van Loan, Matrix Computations, section 8.3.1), then
Laguerre's method on det(T - x I) (Wilkinson, The Algebraic Eigenvalue Problem, section 7.6), evaluated by the
LDL^T recurrence of T - x I with its first two derivatives. The roots are all real, so Laguerre's iterates from
below the least root (0, for a positive semidefinite matrix) or above the largest (Gershgorin's bound) move
monotonically onto it, cubically near a simple root, linearly near a multiple one. An iterate never passes the
root, so one where T - x I is singular (a pivot exactly 0: a step that is not finite) is that root itself. Both
come to about 1e-16 of the largest eigenvalue, as LAPACK's do; a sample not settled in STEPS is flagged.
"""

from __future__ import annotations

import numpy as np

STEPS = 12
SETTLED = 1e-12  # an error left this small relative to the eigenvalue: converged (`_settle`)
FLOOR = 1e-15  # or this small relative to the largest eigenvalue: at the rounding floor of any method

Entries = list[list[np.ndarray]]  # a[i][j]: entry (i, j) of every sample, as an array over the samples


def _total(terms: list):
    """The sum of arrays, without numpy's extra addition of the start value 0."""
    return sum(terms[1:], terms[0]) if terms else 0.0


def gram(columns: list[tuple]) -> Entries:
    """J^T J of the matrices whose columns are given, each a tuple of entries: arrays over the samples, or
    constants (floats), whose zeros are skipped and whose ones multiply nothing (x * 1.0 is x)."""
    def product(x, y):
        return y if isinstance(x, float) and x == 1.0 else x if isinstance(y, float) and y == 1.0 else x * y

    def dot(u: tuple, v: tuple):
        return _total([product(x, y) for x, y in zip(u, v) if not (isinstance(x, float) and x == 0.0)
                       and not (isinstance(y, float) and y == 0.0)])
    n = len(columns)
    upper = {(i, j): dot(columns[i], columns[j]) for i in range(n) for j in range(i, n)}
    return [[upper[min(i, j), max(i, j)] for j in range(n)] for i in range(n)]


def tridiagonal(a: Entries) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Diagonal and squared off-diagonal of a tridiagonal matrix similar to the symmetric a (changed in place):
    Householder reflections H = I - beta v v^T clear column k below its subdiagonal, for k = 0 .. n - 3. Sums
    accumulate in place, in the order of their terms (the arrays are what take the time, not the calls)."""
    n = len(a)
    e2 = []
    for k in range(n - 2):
        x = [a[i][k] for i in range(k + 1, n)]
        norm2 = _total([xi * xi for xi in x])
        alpha = -np.copysign(np.sqrt(norm2), x[0])
        v = [x[0] - alpha] + x[1:]
        vv = norm2 - 2 * alpha * x[0] + alpha * alpha  # v . v
        beta = np.divide(2.0, vv, out=np.zeros_like(vv), where=vv > 0)
        rows = range(k + 1, n)
        p = [_dot([a[i][j] for j in rows], v) for i in rows]
        for pi in p:
            pi *= beta
        half_k = 0.5 * beta * _dot(p, v)
        w = [pi - half_k * vi for pi, vi in zip(p, v)]
        for i, vi, wi in zip(rows, v, w):
            for j, vj, wj in zip(rows, v, w):
                if j >= i:
                    update = a[i][j] - vi * wj
                    update -= wi * vj
                    a[i][j] = a[j][i] = update
        e2.append(norm2)
    e2.append(a[n - 1][n - 2] ** 2)
    return [a[i][i] for i in range(n)], e2


def _dot(u: list[np.ndarray], v: list[np.ndarray]) -> np.ndarray:
    """u . v, a new array: the products added in order, as `_total` adds them."""
    total = u[0] * v[0]
    for x, y in zip(u[1:], v[1:]):
        total += x * y
    return total


def laguerre_step(d: list[np.ndarray], e2: list[np.ndarray], x: np.ndarray) -> np.ndarray:
    """One Laguerre step for det(T - x I) at every x (any shape broadcasting with the samples): with the LDL^T
    pivots u_i of T - x I, G = sum u_i' / u_i = sum 1 / (x - lambda) and H = sum 1 / (x - lambda)^2."""
    n = len(d)
    w = 1.0 / (d[0] - x)  # 1 / u_0
    t, s = -w, 0.0  # u_i' / u_i and u_i'' / u_i
    g, h = t, t * t
    for i in range(1, n):  # u_i = d_i - x - e_{i-1}^2 / u_{i-1}, and its derivatives in x
        r = e2[i - 1] * w
        du, ddu = r * t - 1.0, r * (s - 2.0 * t * t)
        w = 1.0 / (d[i] - x - r)
        t, s = du * w, ddu * w
        g, h = g + t, h + t * t - s
    root = np.sqrt(np.maximum((n - 1) * (n * h - g * g), 0.0))
    return x - n / (g + np.copysign(root, g))


def _settle(d: list, e2: list, x: np.ndarray, done: np.ndarray, last, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Laguerre steps from x (2, N) until each has settled or `steps` are taken: the error left after a step,
    estimated as the step times the square of its ratio to the step before (cubic convergence leaves less; near a
    multiple root, where Laguerre's linear rate stays under 0.42, about 5 times as much), under SETTLED of the
    eigenvalue or FLOOR of the largest. Once half have settled, the rest go on alone (fewer operations)."""
    for taken in range(1, steps + 1):
        new = laguerre_step(d, e2, x)
        new = np.where(np.isfinite(new), new, x)  # x is the extreme root: T - x I singular (see above)
        step = np.abs(new - x)
        x = np.where(done, x, new)
        ratio = 1.0 if last is None else np.minimum(step / last, 1.0)  # 0 / 0 only where done already
        done = done | (step * ratio * ratio <= SETTLED * np.abs(x) + FLOOR * x[1])
        last = step
        rest = np.flatnonzero(~done.all(axis=0))
        if 2 * rest.size <= done.shape[1]:
            if rest.size and taken < steps:
                x[:, rest], done[:, rest] = _settle([v[rest] for v in d], [v[rest] for v in e2], x[:, rest],
                                                    done[:, rest], last[:, rest], steps - taken)
            break
    return x, done


def extreme_eigenvalues(a: Entries) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least and largest eigenvalue (N,) of the positive semidefinite a (entries over N samples; changed), and
    whether both settled (`_settle`)."""
    d, e2 = tridiagonal(a)
    e = [np.sqrt(x) for x in e2]
    bound = np.max([di + (e[i - 1] if i else 0.0) + (e[i] if i < len(e) else 0.0) for i, di in enumerate(d)], 0)
    x = np.stack([np.zeros_like(bound), bound * (1.0 + 1e-12) + 1e-300])
    with np.errstate(all="ignore"):
        x, done = _settle(d, e2, x, np.zeros(x.shape, bool), None, STEPS)
    return x[0], x[1], done.all(axis=0) & np.isfinite(x).all(axis=0)
