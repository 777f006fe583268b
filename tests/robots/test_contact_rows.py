"""robots.contacts.checked_rows: the rows a contact check reads, against the rule read one row at a time."""

from __future__ import annotations

import numpy as np

from simbench.robots.contacts import WINDOW, checked_rows


def _one_row_at_a_time(q: np.ndarray, step: np.ndarray) -> list[int]:
    """The rule as its docstring states it: the first row, each row where some joint has moved by its step since the
    row read before, and the last."""
    rows, last = [0], q[0]
    for k in range(1, len(q)):
        if np.any(np.abs(q[k] - last) >= step):
            rows.append(k)
            last = q[k]
    return rows if rows[-1] == len(q) - 1 else [*rows, len(q) - 1]


def test_the_rows_read_are_those_the_rule_reads_one_row_at_a_time():
    """Random walks (seeded) slow and fast against the steps, shorter and longer than a WINDOW, one to seven
    joints: the same rows."""
    rng = np.random.default_rng(11)
    for _ in range(200):
        n, dof = int(rng.integers(1, 5 * WINDOW)), int(rng.integers(1, 8))
        q = np.cumsum(rng.normal(0.0, rng.uniform(1e-4, 0.05), (n, dof)), axis=0)
        step = rng.uniform(1e-3, 0.05, dof)
        assert checked_rows(q, step) == _one_row_at_a_time(q, step)
