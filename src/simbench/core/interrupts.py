"""Ctrl-C (SIGINT) or SIGTERM during a simbench command: exit 130 (143 for SIGTERM) with one line, whenever it
comes, after the same clean-up (staging folders removed, worker processes stopped).

A plain KeyboardInterrupt does not always reach the command: an extension module being imported turns it into an
ImportError or swallows it (hence `held_back` while simbench's own modules load), and one that leaves an exec()
of a string (scipy's import) makes the interpreter kill itself with SIGINT at exit (hence the subclass
`Interrupted`). `CtrlC.pressed` records a press however it was converted; `is_press` tells it apart from user code
raising KeyboardInterrupt or SystemExit itself.
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
    """Whether `err`, raised out of user code, is the user's Ctrl-C or SIGTERM rather than that code's own
    `raise KeyboardInterrupt` or `sys.exit()` (without raising_interrupted's handler: any KeyboardInterrupt)."""
    ours = [handler for handler in map(signal.getsignal, _SIGNALS) if isinstance(handler, CtrlC)]
    if ours:
        return isinstance(err, Interrupted) or any(handler.pressed for handler in ours)
    return isinstance(err, KeyboardInterrupt)


@contextmanager
def deferred() -> Iterator[None]:
    """Ctrl-C and SIGTERM recorded for the block, then handled as they would have been: for os.fork, whose at-fork
    hooks (logging's lock) a handler raising inside would leave locked for every later fork."""
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
    """Hold SIGINT (Ctrl-C) and SIGTERM back until the block is done; they are delivered then."""
    if not _handles_signals():
        yield
        return
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, set(_SIGNALS))
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
