"""A long run's every-step rows held a window at a time (simbench.physics.sim's run analysed as it is simulated): the
run
then holds a window and a chunk of every step's rows, however long it is.
"""

from __future__ import annotations

import numpy as np


class WindowBuffer:
    """The rows of an array of `length` rows (each of shape `row`) that are held: `capacity` consecutive ones from
    `start`. Indexed by the whole array's row numbers (an int, a slice of step 1, or row numbers; negative ones
    from `length`); IndexError for a row not held."""

    def __init__(self, length: int, capacity: int, row: tuple[int, ...] = (), dtype=float):
        self.length, self.start = length, 0
        self.held = np.empty((min(capacity, length), *row), dtype)

    @property
    def shape(self) -> tuple[int, ...]:
        """The whole array's shape."""
        return (self.length, *self.held.shape[1:])

    def __len__(self) -> int:
        return self.length

    def __getitem__(self, index):
        return self.held[self._local(index)]

    def __setitem__(self, index, value) -> None:
        self.held[self._local(index)] = value

    def drop(self, upto: int) -> None:
        """Let the rows before `upto` go: rows up to `upto` + capacity can then be written."""
        shift = upto - self.start
        if shift <= 0:
            return
        if shift < len(self.held):
            self.held[:len(self.held) - shift] = self.held[shift:]
        self.start = upto

    def _local(self, index):
        """`index` into the held rows."""
        if isinstance(index, slice):
            lo, hi, step = index.indices(self.length)
            if step != 1:
                raise IndexError(f"a WindowBuffer takes slices of step 1, got {index}")
            if hi <= lo:
                return slice(0, 0)
            self._check(lo, hi)
            return slice(lo - self.start, hi - self.start)
        if isinstance(index, (int, np.integer)):  # a closed loop's step: no arrays
            row = int(index) + (self.length if index < 0 else 0)
            self._check(row, row + 1)
            return row - self.start
        rows = np.asarray(index)
        if rows.dtype.kind not in "iu":
            raise IndexError(f"a WindowBuffer is indexed by rows (an int, a slice or row numbers), got {index!r}")
        rows = np.where(rows < 0, rows + self.length, rows)
        if rows.size:
            self._check(int(rows.min()), int(rows.max()) + 1)
        return rows - self.start

    def _check(self, lo: int, hi: int) -> None:
        """IndexError unless rows lo..hi-1 are held."""
        if lo < self.start or hi > self.start + len(self.held):
            raise IndexError(f"rows {lo}..{hi - 1} asked of a WindowBuffer holding rows {self.start}.."
                             f"{self.start + len(self.held) - 1} of {self.length}")
