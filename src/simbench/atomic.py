"""Writes that never leave a half-written file or folder: a run or a sweep stopped at any instant leaves the
previous complete output, or none.

Everything is first written beside its destination under a hidden name, then moved into place with a rename,
which POSIX makes atomic within one filesystem.
"""

from __future__ import annotations

import os
import shutil
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def write_text(path: Path, text: str) -> None:
    """Replace `path` with `text` in one step."""
    tmp = path.parent / f".{path.name}.partial-{os.getpid()}"
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def staged_file(path: Path) -> Iterator[Path]:
    """A hidden path beside `path` to write to; moved onto `path` if the block succeeds, removed if it fails."""
    tmp = path.parent / f".{path.name}.partial-{os.getpid()}"
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def staged_folder(out: Path) -> Iterator[Path]:
    """A fresh hidden folder beside `out`, moved onto `out` if the block succeeds, removed if it fails."""
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.partial-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = out.parent / f".{out.name}.old-{os.getpid()}"
    with _no_interrupt():  # Ctrl-C between the two renames would leave neither folder in place
        if out.exists():
            out.rename(old)
        tmp.rename(out)
    shutil.rmtree(old, ignore_errors=True)


@contextmanager
def _no_interrupt() -> Iterator[None]:
    """Hold SIGINT (Ctrl-C) back until the block is done; it is delivered then. Elsewhere than the main thread
    of a POSIX process, where Python handles no signals, a no-op."""
    held = hasattr(signal, "pthread_sigmask") and threading.current_thread() is threading.main_thread()
    if held:
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        if held:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
