"""A function run in a forked child process while this one goes on: a run's plots are drawn so while its video
renders, on a CPU of their own and with an interpreter lock of their own (on a thread, matplotlib's Python
stalled the render loop). The child inherits the arguments (nothing is pickled but the result or the error); it
ignores Ctrl-C and SIGTERM as the sweep's workers do: the parent answers them and stops it. Where processes
cannot be forked, the function runs in this process when its result is asked for."""

from __future__ import annotations

import multiprocessing
import pickle
import signal
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from simbench.errors import RunError, described


@contextmanager
def forked(fn: Callable[..., Any], *args: Any) -> Iterator[Callable[[], Any]]:
    """Start fn(*args) in a forked child; yields `result`, which waits for it and returns what it returned or
    raises what it raised. Leaving the block stops a child whose result was not asked for, and waits for it."""
    if "fork" not in multiprocessing.get_all_start_methods():
        yield lambda: fn(*args)
        return
    ctx = multiprocessing.get_context("fork")
    receiver, sender = ctx.Pipe(duplex=False)
    child = ctx.Process(target=_child, args=(sender, fn, args), name="simbench-forked", daemon=True)
    child.start()
    sender.close()

    def result() -> Any:
        try:
            done, value = receiver.recv()
        except EOFError:
            child.join()
            raise RunError(f"the process drawing the plots ended (exit code {child.exitcode}) before it finished")
        if done:
            return value
        raise value

    try:
        yield result
    finally:
        if child.is_alive() and not receiver.poll():
            child.terminate()
        child.join()
        receiver.close()


def _child(sender, fn: Callable[..., Any], args: tuple) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        sender.send((True, fn(*args)))
    except BaseException as err:  # the parent raises it (an outside robot's plots hook may raise anything)
        sender.send((False, _sendable(err)))


def _sendable(err: BaseException) -> BaseException:
    """The error itself where it survives pickling, else a RunError that says what it was."""
    try:
        pickle.loads(pickle.dumps(err))
    except Exception:
        return RunError(f"drawing the plots raised {described(err)}")
    return err
