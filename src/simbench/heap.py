"""Handing the RSMG planner's freed memory back to the system before the plan's references are made.

The schedule's search allocates and frees many arrays smaller than glibc's mmap threshold (its IK cache, the
contacts and the rotor's axes on the schedule grid); the heap keeps those pages, and every later stage's arrays
then stack on top of them in the peak resident size (the ten-minute soak's: BENCHMARKS.md). Elsewhere than glibc
there is no trim, and `give_back` does nothing.
"""

from __future__ import annotations

import ctypes

TRIM_SAMPLES = 100_000  # control samples from which a plan gives its freed heap back


def _malloc_trim():
    """glibc's malloc_trim, which hands the heap's freed pages back to the system; None elsewhere."""
    try:
        return ctypes.CDLL(None).malloc_trim
    except (AttributeError, OSError, TypeError):
        return None


_MALLOC_TRIM = _malloc_trim()


def give_back(samples: int) -> None:
    """Return the heap's free pages to the system, for a plan of at least TRIM_SAMPLES control samples (a short
    one frees a few MB, not worth the trim's milliseconds in a sweep's runs)."""
    if samples >= TRIM_SAMPLES and _MALLOC_TRIM is not None:
        _MALLOC_TRIM(0)
