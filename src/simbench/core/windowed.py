"""What the analysis reduces a run's per-sample arrays to, found a window of samples at a time, so that analysing
a long run holds one window's arrays, not every sample's (simbench.analysis); and how many samples a window has
(`window_size`: a run of up to WINDOW samples is one window, a longer one is cut into groups of the path search near
each reference, so that its deviations are those of the search over the whole run).
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

NEAR_REFERENCE = 2.0  # s: the path search's blocks: the tool is measured against its own block and the two beside
GROUP = 1 << 15  # samples of a run of at most WINDOW whose path the search takes at once, on their stretch alone
WINDOW = 1 << 15  # a run of at most this many samples is analysed at once (every shipped scenario)
LONG = 1 << 13  # a longer one about this many at a time, and its path searched in groups of as many


def near_reference(dt: float) -> int:
    """The path search's block at control period dt: NEAR_REFERENCE's samples (deviation_near_reference)."""
    return max(1, int(round(NEAR_REFERENCE / dt)))


def group(block: int, samples: int) -> int:
    """The samples of a group of the path search in a run of `samples`: whole blocks, up to GROUP (LONG in a run
    longer than WINDOW), at least one."""
    return block * max(1, (GROUP if samples <= WINDOW else LONG) // block)


def window_size(dt: float, samples: int) -> int:
    """Samples the analysis of a run of `samples` at control period dt takes at a time: all of them, up to WINDOW;
    beyond, a group of the path search (about LONG)."""
    return max(samples, 1) if samples <= WINDOW else group(near_reference(dt), samples)


def spans(mask: np.ndarray) -> list[tuple[int, int]]:
    """Index ranges [start, end] (inclusive) of the runs of True in mask (at once where there are none: most)."""
    mask = np.asarray(mask, bool)
    if not mask.any():
        return []
    padded = np.concatenate([[False], mask, [False]])
    edges = np.flatnonzero(padded[1:] != padded[:-1])
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2])]


class Spans:
    """The runs of True in a mask (a joint at its limit, the tool near a singular set) seen a window at a time, as
    (first, last, state): `state` is what `add`'s reduce made of the run, `merge` joins two windows' pieces."""

    def __init__(self, merge: Callable[[Any, Any], Any]):
        self.merge = merge
        self.done: list[tuple[int, int, Any]] = []
        self.open: tuple[int, int, Any] | None = None  # a run that reached the last window's last sample

    def add(self, mask: np.ndarray, lo: int, reduce: Callable[[int, int], Any]) -> None:
        """The window of samples lo.. whose mask this is; reduce(a, b) gives the state of its run from window
        index a to b (inclusive)."""
        found = spans(mask)
        if self.open is not None and not (found and found[0][0] == 0):
            self.done.append(self.open)
            self.open = None
        for a, b in found:
            state, first = reduce(a, b), lo + a
            if self.open is not None:  # this window's first run goes on from the last window's
                first, state = self.open[0], self.merge(self.open[2], state)
                self.open = None
            if b == len(mask) - 1:
                self.open = (first, lo + b, state)
            else:
                self.done.append((first, lo + b, state))

    def finish(self) -> list[tuple[int, int, Any]]:
        """Every run, in order."""
        if self.open is not None:
            self.done.append(self.open)
            self.open = None
        return self.done


class Rises:
    """The samples where a series rose above every sample before it, and its values there, in order: the first
    sample beyond any level is among them."""

    def __init__(self):
        self.at: list[np.ndarray] = []
        self.values: list[np.ndarray] = []
        self.top = -np.inf

    def add(self, x: np.ndarray, lo: int) -> None:
        """The window of samples lo.. of the series."""
        if not len(x):
            return
        before = np.maximum(np.concatenate([[self.top], np.maximum.accumulate(x)[:-1]]), self.top)
        rose = np.flatnonzero(x > before)
        self.at.append(lo + rose)
        self.values.append(x[rose])
        self.top = max(self.top, float(np.max(x)))

    def first_beyond(self, level: float) -> int | None:
        """The first sample whose value is beyond `level`, or None."""
        for at, values in zip(self.at, self.values):
            beyond = np.flatnonzero(values > level)
            if beyond.size:
                return int(at[beyond[0]])
        return None


class Departure:
    """The tool's departure from the path after a jump in the plan (from sample `start`): its largest deviation,
    where, and the first sample from there on within `back` of the path."""

    def __init__(self, start: int, back: float):
        self.start, self.back = start, back
        self.peak, self.peak_at, self.back_at = -np.inf, start, None

    def add(self, deviation: np.ndarray, lo: int) -> None:
        """The window of samples lo.. of the path deviation."""
        skip = max(self.start - lo, 0)
        seg = deviation[skip:]
        if not len(seg):
            return
        i = int(np.argmax(seg))
        if seg[i] > self.peak:
            self.peak, self.peak_at = float(seg[i]), lo + skip + i
            within = np.flatnonzero(seg[i:] < self.back)
            self.back_at = lo + skip + i + int(within[0]) if within.size else None
        elif self.back_at is None:
            within = np.flatnonzero(seg < self.back)
            self.back_at = lo + skip + int(within[0]) if within.size else None


class Sums:
    """For named series (N,) or (N, k) seen a window at a time: sums of squares, largest |value|, largest value of
    a column (`highest`), last row and row count."""

    def __init__(self):
        self.squares: dict[str, Any] = {}
        self.largest: dict[str, Any] = {}
        self.highest: dict[str, float] = {}
        self.last: dict[str, Any] = {}
        self.count: dict[str, int] = {}

    def add(self, **series: np.ndarray) -> None:
        """A window of each series."""
        for name, x in series.items():
            squares = np.sum(np.square(x), axis=0)
            # a column at a time, as in `analysis._norms`: NumPy reduces across short rows slowly
            largest = np.abs(x).max() if x.ndim == 1 else np.array([np.abs(c).max() for c in x.T])
            if name in self.squares:
                self.squares[name] = self.squares[name] + squares
                self.largest[name] = np.maximum(self.largest[name], largest)
            else:
                self.squares[name], self.largest[name] = squares, largest
            if x.ndim == 1:
                self.highest[name] = float(np.maximum(self.highest.get(name, -np.inf), x.max()))  # NaN stays
            self.last[name] = x[-1]
            self.count[name] = self.count.get(name, 0) + len(x)

    def rms(self, name: str) -> Any:
        return np.sqrt(self.squares[name] / self.count[name])


class BlockSum:
    """The sum of a series seen a window at a time, the same float however the windows are cut: summed in fixed
    blocks of BLOCK from the run's first sample, the blocks' sums added in order."""

    BLOCK = 4096

    def __init__(self):
        self.total = 0.0  # of the whole blocks so far
        self.carry = np.zeros(0)  # the samples after them

    def add(self, x: np.ndarray) -> None:
        """A window of the series."""
        x = np.concatenate([self.carry, x]) if self.carry.size else np.asarray(x, float)
        whole = len(x) - len(x) % self.BLOCK
        for a in range(0, whole, self.BLOCK):
            self.total += float(np.sum(x[a:a + self.BLOCK]))
        self.carry = x[whole:].copy()

    def value(self) -> float:
        """The sum of every sample added."""
        return self.total + float(np.sum(self.carry))


def norms(v: np.ndarray) -> np.ndarray:
    """np.linalg.norm(v, axis=1) of v (N, 3), the same numbers, a column at a time: NumPy reduces short rows
    slowly."""
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    return np.sqrt(x * x + y * y + z * z)
