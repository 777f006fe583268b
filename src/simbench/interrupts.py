"""Ctrl-C (SIGINT) or SIGTERM during a simbench command: exit 130 (143 for SIGTERM) with one line, whenever it
comes, after the same clean-up (staging folders removed, worker processes stopped).

With CPython 3.11 and this project's dependencies, a plain KeyboardInterrupt does not always reach the command:
- an extension module being imported turns it into an ImportError (numpy: "PyCapsule_Import could not import
  module datetime"; MuJoCo's pybind11 modules: "initialization failed") or swallows it. The command therefore
  imports its own dependencies with Ctrl-C held back (`held_back`); it is delivered the moment they are in.
  Outside packages' entry points load afterwards with signals deliverable (one that hangs can be stopped, and
  processes it starts do not inherit a blocked Ctrl-C); one that an import converts is still a press (`is_press`).
- one that leaves an exec() of a string (scipy runs one while it is imported) is marked as unhandled, and the
  interpreter kills itself with SIGINT at exit even after the command caught it and returned 130. The mark is
  set for KeyboardInterrupt itself only, so Ctrl-C raises the subclass `Interrupted`.
`CtrlC.pressed` records a press however it was converted afterwards. User code (a policy, a plugin) may raise
KeyboardInterrupt or SystemExit itself: `is_press` tells that apart from the process's own Ctrl-C.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass


class Interrupted(KeyboardInterrupt):
    """Ctrl-C during a simbench command."""


_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@dataclass
class CtrlC:
    """Whether Ctrl-C was pressed (or SIGTERM came) while the command ran, and which."""

    pressed: bool = False
    signum: int = signal.SIGINT

    def __call__(self, signum, frame) -> None:
        self.pressed = True
        self.signum = signum
        raise Interrupted

    @property
    def exit_code(self) -> int:
        """128 + the signal's number, as a shell reports a command the signal ended."""
        return 128 + int(self.signum)


def _handles_signals() -> bool:
    """Python runs signal handlers in the main thread of a POSIX process only."""
    return hasattr(signal, "pthread_sigmask") and threading.current_thread() is threading.main_thread()


@contextmanager
def raising_interrupted() -> Iterator[CtrlC]:
    """Have Ctrl-C and SIGTERM raise Interrupted for the duration. Each is left alone where it is ignored (SIGINT
    in a background job) or handled by someone else, and both where no handler can be set."""
    ctrl_c = CtrlC()
    if not _handles_signals():
        yield ctrl_c
        return
    defaults = {signal.SIGINT: signal.default_int_handler, signal.SIGTERM: signal.SIG_DFL}
    ours = [s for s in _SIGNALS if signal.getsignal(s) is defaults[s]]
    for signum in ours:
        signal.signal(signum, ctrl_c)
    try:
        yield ctrl_c
    finally:
        for signum in ours:
            signal.signal(signum, defaults[signum])


def is_press(err: BaseException) -> bool:
    """Whether `err`, raised out of user code, is the user's Ctrl-C or SIGTERM rather than that code's own failure
    (a `raise KeyboardInterrupt`, a `sys.exit()`). Where `raising_interrupted` handles the signals: Interrupted,
    or anything once a press came (an import may have converted it). Elsewhere (a Python session's own handler):
    a KeyboardInterrupt, as Python takes it."""
    ours = [handler for handler in map(signal.getsignal, _SIGNALS) if isinstance(handler, CtrlC)]
    if ours:
        return isinstance(err, Interrupted) or any(handler.pressed for handler in ours)
    return isinstance(err, KeyboardInterrupt)


@contextmanager
def deferred() -> Iterator[None]:
    """Ctrl-C and SIGTERM recorded, not handled, for the block; then each is handled as it would have been. For a
    block that must not be cut by an exception: os.fork runs Python's at-fork hooks (logging's takes and gives back
    its lock), and a handler pending from just before, run inside one, would leave the lock taken for good and
    every later fork of the process (ffmpeg's) waiting on it. A no-op where Python handles no signals."""
    if not _handles_signals():
        yield
        return
    came: list[int] = []
    previous = {signum: signal.signal(signum, lambda signum, frame: came.append(signum)) for signum in _SIGNALS}
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        for signum in came:
            if callable(previous[signum]):
                previous[signum](signum, None)
            elif previous[signum] == signal.SIG_DFL:
                signal.raise_signal(signum)


@contextmanager
def held_back() -> Iterator[None]:
    """Hold SIGINT (Ctrl-C) and SIGTERM back until the block is done; they are delivered then. A no-op where
    Python handles no signals."""
    if not _handles_signals():
        yield
        return
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, set(_SIGNALS))
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
