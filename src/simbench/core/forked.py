"""A function run in a forked child process while this one goes on: a run's plots are drawn so while its video
renders (on a thread, matplotlib stalled the render loop), and a bench's tasks and a sweep's figures are dealt out
to forked children (`dealt`). Only the result or error is pickled back. A plain os.fork, so that a sweep's daemonic
worker may fork one too; without fork, it runs here when its result is asked."""

from __future__ import annotations

import gc
import multiprocessing
import os
import pickle
import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack, contextmanager, suppress
from typing import Any, NoReturn

from simbench.core.errors import RunError, described
from simbench.core.interrupts import deferred, held_back


@contextmanager
def parents_heap_frozen() -> Iterator[None]:
    """Around a fork: the objects this process holds kept out of the child's garbage collection (gc.freeze), so
    that the child never runs a destructor of the parent's garbage. Ray's GCS client, garbage after a Ray sweep,
    locks in its destructor a mutex that a thread of the parent held at the fork: a child collecting it hung."""
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


@contextmanager
def forked(fn: Callable[..., Any], *args: Any, doing: str) -> Iterator[Callable[[], Any]]:
    """Start fn(*args) in a forked child; yields `result`, which waits for it and returns what it returned or
    raises what it raised (`doing` says what the child does, in its errors: "drawing the plots"). Leaving the
    block stops a child whose result was not asked for, and waits for it; the child ends with this process."""
    if not hasattr(os, "fork"):
        yield lambda: fn(*args)
        return
    parent = os.getpid()
    readable, writable = os.pipe()
    pid = 0
    reaped = False

    def result() -> Any:
        nonlocal reaped
        with os.fdopen(readable, "rb", closefd=False) as pipe:
            sent = pipe.read()
        status = os.waitpid(pid, 0)[1]
        reaped = True
        if not sent:
            raise RunError(f"the process {doing} ended (exit code {os.waitstatus_to_exitcode(status)}) before it "
                           "finished")
        done, value = pickle.loads(sent)
        if done:
            return value
        raise value

    try:
        # Ctrl-C and SIGTERM held back until the child has its own handlers (the parent's would run the parent's
        # code in it), and in the parent not handled inside the fork's at-fork hooks (interrupts.deferred); one
        # that came meanwhile is handled as the block ends, with the child to stop below.
        with deferred(), held_back(), parents_heap_frozen():
            pid = os.fork()
            if pid == 0:
                _child(readable, writable, parent, doing, fn, args)
            os.close(writable)
        yield result
    finally:
        if pid and not reaped:  # (a Ctrl-C may have come between its end and waitpid's return: then it is gone)
            with suppress(ProcessLookupError):
                os.kill(pid, signal.SIGTERM)
            with suppress(ChildProcessError):
                os.waitpid(pid, 0)
        if not pid:
            os.close(writable)
        os.close(readable)


def _child(readable: int, writable: int, parent: int, doing: str, fn: Callable[..., Any], args: tuple) -> NoReturn:
    """fn(*args) in the child, its result or error pickled into the pipe; then os._exit, so that none of the
    parent's clean-up runs twice. Signals stay held back until the child's own handlers are set."""
    try:
        os.close(readable)
        die_with(parent)
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})
        try:
            sent = pickle.dumps((True, fn(*args)))
        except BaseException as err:  # the parent raises it (an outside robot's plots hook may raise anything)
            sent = pickle.dumps((False, _sendable(err, doing)))
        with os.fdopen(writable, "wb") as pipe:
            pipe.write(sent)
    finally:
        os._exit(0)


def _sendable(err: BaseException, doing: str) -> BaseException:
    """The error itself where it survives pickling, else a RunError that says what it was."""
    try:
        pickle.loads(pickle.dumps(err))
    except Exception:
        return RunError(f"{doing} raised {described(err)}")
    return err


def dealt(jobs: Sequence[tuple[Callable[..., Any], tuple]], workers: int, doing: str) -> list[Any]:
    """Each (fn, args) job's fn(*args), in order, by `workers` processes at once: this one and forked children
    (`forked`: their jobs are their copy of this process's, nothing pickled to them). Process w runs job w first,
    then each takes the next job none has taken (a counter they share), so that a long job holds up no other. The
    first error, in the processes' order, is raised."""
    processes = max(1, min(workers, len(jobs)))
    if processes == 1 or not hasattr(os, "fork"):
        return [fn(*args) for fn, args in jobs]
    taken = multiprocessing.get_context("fork").Value("q", processes)  # the next job none has taken

    def share(first: int) -> dict[int, Any]:
        fn, args = jobs[first]
        done = {first: fn(*args)}
        while True:
            with taken.get_lock():
                index = taken.value
                taken.value += 1
            if index >= len(jobs):
                return done
            fn, args = jobs[index]
            done[index] = fn(*args)

    with ExitStack() as children:
        theirs = [children.enter_context(forked(share, w, doing=doing)) for w in range(1, processes)]
        shares = [share(0)] + [result() for result in theirs]
    out: list[Any] = [None] * len(jobs)
    for done in shares:
        for index, value in done.items():
            out[index] = value
    return out


_WATCH = 0.2  # s: how often a worker looks whether its parent is still there


def die_with(parent: int) -> None:
    """End this process as soon as its parent is gone (SIGKILL included), so that no worker outlives its sweep
    holding the folder's lock, nor its environment's task pool. A thread watches getppid(): the pipe cannot tell
    (later workers hold copies of its parent end), and PR_SET_PDEATHSIG crashed forked workers of a threaded
    parent."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(_WATCH)
        os._exit(1)

    threading.Thread(target=watch, name="simbench-parent-watch", daemon=True).start()


def as_worker() -> None:
    """Signals in a worker: Ctrl-C ignored (the parent answers it), SIGTERM the end at once (the inherited handler
    would raise a traceback in a waiting worker)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
