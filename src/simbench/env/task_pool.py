"""A pool of random tasks planned ahead (task_kwargs={'random': seed, 'pool': N}): a reset takes one of N tasks that
a background process plans while the episodes run, instead of planning its own (a random task's plan costs about a
hundred times a reset; BENCHMARKS.md, bench_env_step).

Deterministic whatever the timing: task i is planned from its own seed (numpy's SeedSequence of one draw from the
environment's `random`, spawned N ways), so what it is does not depend on when, or in which process, it was planned;
each reset then picks one of the N uniformly with the same `random`, and waits for it if it is not planned yet (the
process plans them in index order, so only the first resets may wait). A reseed (shimmy's `reset(seed=...)`) drops
the pool; the next reset makes a new one from the new seed.

The process is a fresh interpreter, not a fork (a training process holds threads: a fork may copy a held lock),
and ends with this one (it watches its parent, as a sweep's workers do) and when the pool is dropped. A pool
pickles (and deep-copies) as the tasks planned so far; its copy plans the rest in a process of its own when a reset
asks for one of them.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import weakref
from contextlib import suppress
from multiprocessing import connection
from typing import Any

import numpy as np

from simbench.api import Array, JointTrajectory
from simbench.core.errors import RunError
from simbench.core.forked import as_worker, die_with
from simbench.scenario import Scenario

Task = tuple[Scenario, JointTrajectory]


class TaskPool:
    """N random tasks of a scenario's robot, planned ahead in a background process.

    Args:
        scenario: The scenario whose planner draws the tasks (as simbench.env.random_task.plan_random).
        bounds: The position targets' bounds the references keep within.
        dt: The plans' sample step (s).
        size: N, the number of tasks.
        entropy: The seed of the tasks' seeds.
    """

    def __init__(self, scenario: Scenario, bounds: tuple[Array, Array], dt: float, size: int, entropy: int):
        self.size = size
        self._job = (scenario, bounds, dt, entropy)
        self._tasks: list[Task | None] = [None] * size
        self._process: Any = None

    def take(self, random: np.random.RandomState) -> Task:
        """One of the tasks, picked uniformly by `random`; waits until it is planned.

        Raises:
            RunError: The process could not plan that task, or ended before it did.
        """
        index = int(random.randint(self.size))
        while self._tasks[index] is None:
            self._receive()
        task = self._tasks[index]
        assert task is not None
        return task

    def fill(self) -> None:
        """Wait until every task is planned (a reset then never waits).

        Raises:
            RunError: As `take`.
        """
        while None in self._tasks:
            self._receive()

    def _receive(self) -> None:
        """Wait for the next task the process sends, starting the process if none is planning."""
        if self._process is None:
            self._start()
        conn = self._process[1]
        try:
            index, task, why = conn.recv()
        except EOFError:
            self.close()
            raise RunError("the process planning the random tasks ended before it planned them all") from None
        if why is not None:
            self.close()
            raise RunError(f"random task {index} of the pool could not be planned: {why}")
        self._tasks[index] = task

    def _start(self) -> None:
        """Start the process that plans the tasks not planned yet, in index order: a fresh interpreter running this
        module (multiprocessing's spawn would run the user's script again in it, unless guarded by __main__)."""
        readable, writable = os.pipe()
        missing = [i for i, task in enumerate(self._tasks) if task is None]
        process = subprocess.Popen([sys.executable, "-c", _SERVE, str(writable), str(os.getpid())], env=child_environ(),
                                   stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, pass_fds=(writable,))
        os.close(writable)
        conn = connection.Connection(readable, writable=False)
        self._process = (process, conn)
        self._finalizer = weakref.finalize(self, _stop, process, conn)
        assert process.stdin is not None
        with suppress(BrokenPipeError):  # a process that ended at once: the first recv says so
            process.stdin.write(pickle.dumps((self._job, missing)))
            process.stdin.close()

    def close(self) -> None:
        """Stop the planning process (the tasks planned so far are kept)."""
        if self._process is not None:
            self._finalizer()
            self._process = None

    def __getstate__(self) -> dict:
        return {"size": self.size, "_job": self._job, "_tasks": self._tasks, "_process": None}


def child_environ() -> dict[str, str]:
    """The planning process's environment: this one's, with the folders this process imports from beyond the
    interpreter's own (the script's, any added at run time) on PYTHONPATH, so that the planner, the robot and their
    plugins import there as here."""
    own = tuple({sys.prefix, sys.base_prefix})
    added = [p for p in sys.path if p and not os.path.abspath(p).startswith(own)]
    return {**os.environ, "PYTHONPATH": os.pathsep.join([*added, os.environ.get("PYTHONPATH", "")]).strip(os.pathsep)}


def _stop(process: subprocess.Popen, conn: connection.Connection) -> None:
    """End a planning process and close its pipe."""
    conn.close()
    if process.poll() is None:
        process.kill()
    process.wait()


_SERVE = "import sys; from simbench.env.task_pool import serve; serve(int(sys.argv[1]), int(sys.argv[2]))"
"""What the planning process runs."""


def serve(writable: int, parent: int) -> None:
    """The planning process: the job from stdin, then each task of it planned from its own seed and sent, or why
    not."""
    from simbench.env.random_task import plan_random

    die_with(parent)
    as_worker()
    (scenario, bounds, dt, entropy), indices = pickle.load(sys.stdin.buffer)
    conn = connection.Connection(writable, readable=False)
    seeds = np.random.SeedSequence(entropy).spawn(max(indices) + 1 if indices else 0)
    for index in indices:
        random = np.random.RandomState(np.random.MT19937(seeds[index]))
        try:
            conn.send((index, plan_random(scenario, bounds, dt, random), None))
        except RunError as err:
            conn.send((index, None, str(err)))
            return
