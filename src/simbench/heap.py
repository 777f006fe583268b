"""Handing a long run's freed memory back to the system between its stages.

Planning and analysing a long run allocate and free many arrays smaller than glibc's mmap threshold (which it
raises as large ones are freed); the heap keeps those pages, and the next stage's arrays, mapped afresh, then stack
on top of them in the peak resident size (the ten-minute soak: 260 MB of the 440 MB held after planning two
minutes of it). Cyclic garbage is collected first: planners leave some (40 MB of small arrays on the ten-minute
soak) that the interpreter's own collection would free only later.
"""

from __future__ import annotations

import ctypes
import gc

TRIM_SAMPLES = 100_000  # control samples from which a run gives its freed heap back


def _malloc_trim():
    """glibc's malloc_trim, which hands the heap's freed pages back to the system; None elsewhere."""
    try:
        return ctypes.CDLL(None).malloc_trim
    except (AttributeError, OSError, TypeError):
        return None


_MALLOC_TRIM = _malloc_trim()


def trim() -> None:
    """Return the heap's free pages to the system (without collecting garbage first: a few milliseconds on a
    large heap)."""
    if _MALLOC_TRIM is not None:
        _MALLOC_TRIM(0)


def give_back(samples: int) -> None:
    """Collect the cyclic garbage and return the heap's free pages to the system, in a run of `samples` control
    samples at least TRIM_SAMPLES long. A short run frees a few MB, and the collection and trim would cost it a
    few milliseconds (a sweep's runs)."""
    if samples >= TRIM_SAMPLES:
        gc.collect()
        trim()
