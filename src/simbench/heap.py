"""Handing the RSMG planner's freed memory back to the system before the plan's references are made.

The schedule's search allocates and frees many arrays smaller than glibc's mmap threshold (its IK cache, the
contacts and the rotor's axes on the schedule grid); the heap keeps those pages, and every later stage's arrays
then stack on top of them in the peak resident size (the ten-minute soak's: BENCHMARKS.md). Cyclic garbage is
collected first, so that what it held is trimmed too. Elsewhere than glibc there is no trim, and `give_back` only
collects.
"""

from __future__ import annotations

import ctypes
import gc

TRIM_SAMPLES = 100_000  # control samples from which a plan gives its freed heap back


def _malloc_trim():
    """glibc's malloc_trim, which hands the heap's freed pages back to the system; None elsewhere."""
    try:
        return ctypes.CDLL(None).malloc_trim
    except (AttributeError, OSError, TypeError):
        return None


_MALLOC_TRIM = _malloc_trim()


def give_back(samples: int) -> None:
    """Collect the cyclic garbage and return the heap's free pages to the system, for a plan of at least
    TRIM_SAMPLES control samples (a short one frees a few MB, not worth the milliseconds in a sweep's runs)."""
    if samples >= TRIM_SAMPLES:
        gc.collect()
        if _MALLOC_TRIM is not None:
            _MALLOC_TRIM(0)
