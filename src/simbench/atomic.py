"""Writes that never leave a half-written file or folder: a run or a sweep stopped at any instant leaves the
previous complete output, or none.

Everything is first written beside its destination under a hidden name, then moved into place with a rename,
which POSIX makes atomic within one filesystem. What a killed writer left under such a name is removed by the
next writer of the same path (destination.sweep_leftovers).
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from simbench.destination import mark, sweep_leftovers
from simbench.interrupts import held_back


def _beside(path: Path, tag: str) -> Path:
    """The hidden name under which this process writes or sets aside `path`."""
    return path.parent / f".{path.name}.{tag}-{os.getpid()}"


def write_text(path: Path, text: str) -> None:
    """Replace `path` with `text` in one step."""
    with staged_file(path) as tmp:
        tmp.write_text(text)


@contextmanager
def staged_file(path: Path) -> Iterator[Path]:
    """A hidden path beside `path` to write to; moved onto `path` if the block succeeds, removed if it fails."""
    sweep_leftovers(path)
    tmp = _beside(path, "partial")
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def staged_folder(out: Path) -> Iterator[Path]:
    """A fresh hidden folder beside `out`, moved onto `out` (with its marker, destination.mark) if the block
    succeeds, removed if it fails. The caller has checked that `out` may be replaced (destination.check)."""
    out.parent.mkdir(parents=True, exist_ok=True)
    sweep_leftovers(out)
    tmp = _beside(out, "partial")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    mark(tmp)
    old = _beside(out, "old")
    with held_back():  # Ctrl-C between the two renames would leave neither folder in place
        if out.exists():
            out.rename(old)
        tmp.rename(out)
    shutil.rmtree(old, ignore_errors=True)

