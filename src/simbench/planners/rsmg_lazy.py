"""Arrays along the RSMG schedule's grid computed block by block as the search reads them (`Lazy`, `LazyExit`),
their bounded cache, and first_false, the exits of a whole array."""

from __future__ import annotations

import mmap
from collections import OrderedDict

import numpy as np

CACHE_FLOATS = 1e7  # floats that a cache of arrays along the grid may hold (80 MB); the least recently read go first
OWN_PAGES = 65536  # bytes from which a cached array is kept on pages of its own (BoundedCache.keep)
_LAZY_BLOCK = 1024  # schedule steps in a block of a Lazy array
_PRIVATE = getattr(mmap, "MAP_PRIVATE", 0) | getattr(mmap, "MAP_ANONYMOUS", 0)  # none on Windows: mmap's own


def on_own_pages(array: np.ndarray) -> np.ndarray:
    """A copy of `array` on an anonymous mapping of its own, whose pages go back to the system as soon as the copy
    is freed. The heap keeps the pages of the arrays freed on it (glibc's, whose mmap threshold rises to the largest
    array freed so far, to 32 MiB), under whatever the process allocates next."""
    buffer = mmap.mmap(-1, array.nbytes, flags=_PRIVATE) if _PRIVATE else mmap.mmap(-1, array.nbytes)
    own = np.frombuffer(buffer, array.dtype, count=array.size).reshape(array.shape)
    own[...] = array
    return own


def first_false(ok: np.ndarray) -> np.ndarray:
    """For each step along the last axis (and one past the end), the first at or after it where `ok` is false."""
    n = ok.shape[-1]
    first = np.minimum.accumulate(np.where(ok, n, np.arange(n))[..., ::-1], axis=-1)[..., ::-1]
    return np.concatenate([first, np.full(ok.shape[:-1] + (1,), n)], axis=-1)


def first_out(ok: np.ndarray) -> np.ndarray:
    """first_false(ok)[..., 0] alone, without the pass over every later step."""
    n = ok.shape[-1]
    return np.where(ok.all(axis=-1), n, ok.argmin(axis=-1)) if n else np.zeros(ok.shape[:-1], np.int64)


class BoundedCache(OrderedDict):
    """A cache dropping its least recently read entries once they hold more than `floats` numbers. Its arrays of
    OWN_PAGES bytes or more are kept on pages of their own (on_own_pages): the cache of a long schedule's search
    holds up to 80 MB in thousands of blocks, which on the heap would stay resident under the plan and its run
    once the search ends (the ten-minute soak's peak memory: BENCHMARKS.md)."""

    def __init__(self, floats: float):
        super().__init__()
        self.floats, self.held = floats, 0

    def keep(self, key, value):
        """Keep value under key (an array counts its size, anything else 1); return it (an array on pages of its
        own from OWN_PAGES bytes)."""
        if isinstance(value, np.ndarray) and value.nbytes >= OWN_PAGES:
            value = on_own_pages(value)
        self[key] = value
        self.held += _floats(value)
        while self.held > self.floats and len(self) > 1:
            _, old = self.popitem(last=False)
            self.held -= _floats(old)
        return value

    def clear(self) -> None:
        """Drop every entry."""
        super().clear()
        self.held = 0

    def fetch(self, key, make):
        """The value under key, or make()'s kept there; either way now the newest entry, the last to go."""
        if key in self:
            self.move_to_end(key)
            return self[key]
        return self.keep(key, make())


def _floats(value) -> int:
    """What a cached value counts against its cache's bound: an array's size, anything else 1."""
    return value.size if isinstance(value, np.ndarray) else 1


class Lazy:
    """An array along the grid (n steps, any trailing shape), its blocks computed by make(first, stop) when first
    read and kept in a shared BoundedCache. Reads as an array: lazy[step], lazy[steps], lazy[first:stop]."""

    _tags = iter(range(1 << 62))

    def __init__(self, n: int, make, cache: BoundedCache, size: int = _LAZY_BLOCK):
        self.n, self.make, self.cache, self.size, self.tag = n, make, cache, size, next(Lazy._tags)

    def block(self, b: int) -> np.ndarray:
        """Block b: steps b * size to (b + 1) * size (fewer at the end)."""
        return self.cache.fetch((self.tag, b), lambda: self.make(b * self.size, min((b + 1) * self.size, self.n)))

    def __getitem__(self, index):
        if isinstance(index, slice):
            first, stop, _ = index.indices(self.n)
            if stop <= first:
                return self.block(0)[:0]
            parts = [self.block(b) for b in range(first // self.size, (stop - 1) // self.size + 1)]
            whole = parts[0] if len(parts) == 1 else np.concatenate(parts)
            offset = (first // self.size) * self.size
            return whole[first - offset:stop - offset]
        steps = np.asarray(index)
        if steps.ndim == 0:
            return self.block(int(steps) // self.size)[int(steps) % self.size]
        blocks = steps // self.size
        first = self.block(int(blocks.flat[0])) if steps.size else self.block(0)
        out = np.empty(steps.shape + first.shape[1:], first.dtype)
        for b in _distinct(blocks):
            here = blocks == b
            out[here] = self.block(int(b))[steps[here] - b * self.size]
        return out


def _distinct(blocks: np.ndarray) -> np.ndarray:
    """The distinct blocks a read touches, in order (no sort where they are one: most reads)."""
    if blocks.size and blocks.min() == blocks.max():
        return blocks.reshape(-1)[:1]
    return np.unique(blocks)


class LazyExit:
    """first_false of a Lazy of booleans, block by block; read as first_false's array is."""

    def __init__(self, ok: Lazy):
        self.ok, self.n, self.size = ok, ok.n, ok.size
        self._from_start: dict[int, int] = {}  # block -> the first false at or after its first step

    def _local(self, b: int) -> np.ndarray:
        """first_false within block b (its length where none)."""
        return self.ok.cache.fetch((self.ok.tag, b, "exit"), lambda: first_false(self.ok.block(b)))

    def _from(self, b: int, limit: int) -> int:
        """The first false at or after block b's first step, or `limit` if none before it (computing no further)."""
        pending = []
        while b * self.size < min(limit, self.n) and b not in self._from_start:
            local = self._local(b)
            if local[0] < len(local) - 1:
                self._from_start[b] = b * self.size + int(local[0])
                break
            pending.append(b)
            b += 1
        if b not in self._from_start and b * self.size < self.n:
            return limit  # not looked beyond: nothing to remember
        found = self._from_start.get(b, self.n)
        for p in pending:
            self._from_start[p] = found
        return min(found, limit)

    def __getitem__(self, index):
        return self.upto(index, self.n)

    def upto(self, index, limit: int):
        """min(self[index], limit), computing no block past `limit` beyond those holding the steps (the search
        looks a few swings ahead, not to where a point leaves the band)."""
        steps = np.asarray(index)
        if steps.ndim == 0:
            return self._one(int(steps), limit)
        flat = steps.ravel()
        out = np.full(flat.shape, self.n, dtype=np.int64)
        inside = flat < self.n
        blocks = flat // self.size
        for b in _distinct(blocks[inside]):
            here = inside & (blocks == b)
            local = self._local(int(b))
            found = local[flat[here] - b * self.size]
            ahead = found >= len(local) - 1  # none left in this block: the first from the next one on
            out[here] = np.where(ahead, self._from(int(b) + 1, limit), b * self.size + found)
        return np.minimum(out, limit).reshape(steps.shape)

    def _one(self, step: int, limit: int) -> int:
        """upto of a single step, without the arrays."""
        if step >= self.n:
            return min(self.n, limit)
        b, at = divmod(step, self.size)
        local = self._local(b)
        found = int(local[at])
        return min(self._from(b + 1, limit) if found >= len(local) - 1 else b * self.size + found, limit)


def exit_upto(exit: np.ndarray | LazyExit, steps: np.ndarray, limit: int) -> np.ndarray:
    """min(exit[steps], limit) of a first_false array or a LazyExit (LazyExit.upto)."""
    return exit.upto(steps, limit) if isinstance(exit, LazyExit) else np.minimum(exit[steps], limit)
