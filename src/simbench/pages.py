"""Arrays whose rows can be handed back to the system once they have been read: a long plan's.

A long run recorded with a stride (sim.record_every) is analysed a window of samples at a time while it is
simulated; the plan is made whole by its planner, and once the run and the analysis have passed a row of it,
that row is not read again. On an array of `releasable`, those rows' pages go back to the system (madvise
MADV_DONTNEED on a private anonymous mapping: on Linux pages handed back read as zeros, elsewhere they may keep
their values), so the run holds the plan still to come, not all of it (the ten-minute soak's memory:
BENCHMARKS.md). Where the system has no such mapping (Windows), `releasable` is np.empty and `release` does
nothing.
"""

from __future__ import annotations

import mmap

import numpy as np

_PRIVATE = getattr(mmap, "MAP_PRIVATE", None)
_ANONYMOUS = getattr(mmap, "MAP_ANONYMOUS", None)
_DONTNEED = getattr(mmap, "MADV_DONTNEED", None)


def releasable(shape: tuple[int, ...], dtype=float) -> np.ndarray:
    """An uninitialised array on pages of its own whose rows `release` can hand back."""
    count = int(np.prod(shape))
    if _PRIVATE is None or _ANONYMOUS is None or _DONTNEED is None:
        return np.empty(shape, dtype)
    buffer = mmap.mmap(-1, max(count * np.dtype(dtype).itemsize, 1), flags=_PRIVATE | _ANONYMOUS)
    return np.frombuffer(buffer, dtype, count=count).reshape(shape)


def release(array: np.ndarray, lo: int, hi: int) -> None:
    """Hand rows lo..hi-1 of an array on a mapping `releasable` made back to the system (on Linux they read as
    zeros afterwards): the pages wholly inside them; those shared with other rows stay. A view whose rows are not
    in C order on the mapping (reversed, transposed, strided) is left as it is."""
    buffer = array.base
    while buffer is not None and not isinstance(buffer, mmap.mmap):
        buffer = getattr(buffer, "obj", None) if isinstance(buffer, memoryview) else getattr(buffer, "base", None)
    if buffer is None or not array.flags.c_contiguous:
        return
    offset = array.ctypes.data - np.frombuffer(buffer, np.uint8).ctypes.data  # where row 0 sits in the mapping
    row, hi = array.itemsize * int(np.prod(array.shape[1:])), min(hi, len(array))  # bytes a row (C order)
    start = -(-(offset + lo * row) // mmap.PAGESIZE) * mmap.PAGESIZE
    end = (offset + hi * row) // mmap.PAGESIZE * mmap.PAGESIZE
    if end > start:
        buffer.madvise(_DONTNEED, start, end - start)
