"""simbench.pages: arrays whose rows are handed back to the system once read (a run analysed as it is simulated).
The truth: what the rows held before, and zeros where a page wholly inside the rows was handed back."""

import mmap

import numpy as np
import pytest

from simbench import pages


@pytest.mark.parametrize("shape, dtype", [((5000, 27), float), ((40501, 4), bool), ((40501, 0), bool), ((0, 8), float),
                                          ((3, 2), float), ((20000,), float)])
def test_released_rows_read_zeros_and_the_others_keep_their_values(shape, dtype):
    """Rows lo..hi-1 handed back read zero where their pages lay wholly inside them (on a system with madvise);
    every row outside them keeps its values: wide and narrow rows, rows of no bytes, arrays of no rows, and a
    range past the array's end."""
    a = pages.releasable(shape, dtype)
    a[...] = (np.arange(a.size).reshape(shape) % 7 + 1).astype(dtype)
    before = a.copy()
    lo, hi = len(a) // 3, 2 * len(a) // 3 + 1
    pages.release(a, lo, hi)
    row, page = a.itemsize * int(np.prod(shape[1:])), mmap.PAGESIZE
    start, end = -(-lo * row // page) * page, min(hi, len(a)) * row // page * page
    for r in range(len(a)):
        first, stop = r * row, (r + 1) * row
        if r < lo or r >= hi:
            assert np.array_equal(a[r], before[r]), r
        elif row and start <= first and stop <= end and hasattr(mmap, "MADV_DONTNEED"):
            assert not a[r].any(), r
    pages.release(a, hi, len(a) + 10)  # as far as the end
    assert np.array_equal(a[:lo], before[:lo])


def test_a_view_is_released_at_its_own_rows_or_not_at_all():
    """A planner's array may be a view of a mapping `releasable` made: rows 1,000.. of it (C order, starting
    mid-mapping) hand back the pages wholly inside their own rows lo..hi-1, the mapping's rows before the view
    kept; a reversed or a transposed view, whose rows are not in order on the mapping, is left whole (releasing
    its bytes 0.. would zero its last rows)."""
    base = pages.releasable((5000, 8))
    base[...] = np.arange(base.size).reshape(base.shape) % 11 + 1
    before = base.copy()
    view = base[1000:]
    pages.release(view, 0, 2000)
    zero = ~view.any(axis=1)
    assert zero[:2000].sum() >= 2000 - 2 * mmap.PAGESIZE // 64 and not zero[2000:].any()
    assert np.array_equal(base[:1000], before[:1000])
    if hasattr(mmap, "MADV_DONTNEED"):
        assert zero[:2000].any()
    for other in (pages.releasable((5000, 8))[::-1], pages.releasable((8, 5000)).T):
        other[...] = before
        pages.release(other, 0, 4000)
        assert np.array_equal(other, before)
