"""Ctrl-C (SIGINT) during a simbench command: exit 130 with one line, whenever it comes.

With CPython 3.11 and this project's dependencies, a plain KeyboardInterrupt does not always reach the command:
- an extension module being imported turns it into an ImportError (numpy: "PyCapsule_Import could not import
  module datetime"; MuJoCo's pybind11 modules: "initialization failed") or swallows it. The command therefore
  imports its dependencies with Ctrl-C held back (`held_back`); it is delivered the moment they are in.
- one that leaves an exec() of a string (scipy runs one while it is imported) is marked as unhandled, and the
  interpreter kills itself with SIGINT at exit even after the command caught it and returned 130. The mark is
  set for KeyboardInterrupt itself only, so Ctrl-C raises the subclass `Interrupted`.
`CtrlC.pressed` records a press however it was converted afterwards.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass


class Interrupted(KeyboardInterrupt):
    """Ctrl-C during a simbench command."""


@dataclass
class CtrlC:
    """Whether Ctrl-C was pressed while the command ran."""

    pressed: bool = False

    def __call__(self, signum, frame) -> None:
        self.pressed = True
        raise Interrupted


def _handles_signals() -> bool:
    """Python runs signal handlers in the main thread of a POSIX process only."""
    return hasattr(signal, "pthread_sigmask") and threading.current_thread() is threading.main_thread()


@contextmanager
def raising_interrupted() -> Iterator[CtrlC]:
    """Have Ctrl-C raise Interrupted for the duration. Left alone where SIGINT is ignored (a background job) or
    handled by someone else, and where no handler can be set; `pressed` then stays False."""
    ctrl_c = CtrlC()
    if not _handles_signals() or signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield ctrl_c
        return
    signal.signal(signal.SIGINT, ctrl_c)
    try:
        yield ctrl_c
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)


@contextmanager
def held_back() -> Iterator[None]:
    """Hold SIGINT (Ctrl-C) back until the block is done; it is delivered then. A no-op where Python handles no
    signals."""
    if not _handles_signals():
        yield
        return
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
