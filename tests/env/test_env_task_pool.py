"""task_kwargs={'random': seed, 'pool': N}: resets take random tasks planned ahead in a background process. The
truth each test holds it to: the same tasks planned here, in this process, from the seeds the pool documents;
the environment's pickled copy; the operating system's view of the planning process."""

from __future__ import annotations

import os
import pickle
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from simbench import env
from simbench.env.episode import track_of
from simbench.env.random_task import plan_random
from simbench.env.task_pool import TaskPool

POOL = 3


def loaded(seed: int = 7):
    """The spherical arm's case 1 with a pool (its random tasks are joint moves: milliseconds to plan)."""
    return env.load_task("spherical_arm", "case1", task_kwargs={"random": seed, "pool": POOL})


def episodes(e, n: int) -> list[np.ndarray]:
    """The plans' joint references of n resets."""
    out = []
    for _ in range(n):
        e.reset()
        out.append(track_of(e).plan.q_ref.copy())
    return out


def test_pooled_tasks_are_those_planned_here_from_the_documented_seeds():
    e = loaded()
    track = track_of(e)
    chooser = np.random.RandomState(7)  # the environment's random, as loaded
    entropy = int(chooser.randint(2**31))
    seeds = np.random.SeedSequence(entropy).spawn(POOL)
    plans = [plan_random(track.base_scenario, track.target_bounds, track.dt,
                         np.random.RandomState(np.random.MT19937(seed)))[1] for seed in seeds]
    assert len({p.q_ref.tobytes() for p in plans}) == POOL  # three different tasks
    got = episodes(e, 6)
    for q_ref in got:
        index = int(chooser.randint(POOL))  # the pick each reset makes
        np.testing.assert_array_equal(q_ref, plans[index].q_ref)


def test_the_same_seed_gives_the_same_episodes_and_a_pickled_copy_goes_on_alike():
    first, second = loaded(), loaded()
    a, b = episodes(first, 4), episodes(second, 4)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    copy = pickle.loads(pickle.dumps(first))
    for x, y in zip(episodes(first, 3), episodes(copy, 3)):
        np.testing.assert_array_equal(x, y)
    other = episodes(loaded(seed=8), 4)
    assert not all(np.array_equal(x, y) for x, y in zip(a, other))


def test_a_pool_needs_random_and_a_count():
    for kwargs in ({"pool": 4}, {"random": 0, "pool": 0}, {"random": 0, "pool": True}, {"random": 0, "pool": 2.5}):
        with pytest.raises(ValueError, match="pool: a number of random tasks >= 1, with random set"):
            env.load_task("spherical_arm", "case1", task_kwargs=kwargs)


PARENT = """
import sys
from simbench import env
from simbench.env.task_pool import TaskPool
track = env.load_task("spherical_arm", "case1", task_kwargs={"random": 0}).task
pool = TaskPool(track.base_scenario, track.target_bounds, track.dt, 100_000, 0)
pool._start()
print(pool._process[0].pid, flush=True)
sys.stdin.read()
"""


def alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().split()[2] != "Z"
    except FileNotFoundError:
        return False


@pytest.mark.skipif(sys.platform != "linux", reason="reads /proc")
def test_the_planning_process_ends_with_its_parent_killed_and_with_the_pool_closed():
    parent = subprocess.Popen([sys.executable, "-c", PARENT], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                              text=True)
    try:
        child = int(parent.stdout.readline())
        assert alive(child)  # 100,000 tasks to plan: still planning
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + 10
        while alive(child) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not alive(child)
    finally:
        parent.kill()
    track = track_of(env.load_task("spherical_arm", "case1", task_kwargs={"random": 0}))
    pool = TaskPool(track.base_scenario, track.target_bounds, track.dt, 100_000, 0)
    pool._start()
    process = pool._process[0]
    assert process.poll() is None
    pool.close()
    assert process.poll() is not None


def test_the_planning_process_imports_from_the_folders_this_one_added(tmp_path, monkeypatch):
    """A module beside the user's script (a folder on sys.path at run time, not on the interpreter's own path) is
    importable in the planning process's environment, as it is not in a bare one."""
    from simbench.env.task_pool import child_environ

    (tmp_path / "beside_the_script.py").write_text("ANSWER = 42\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    command = [sys.executable, "-c", "import beside_the_script; print(beside_the_script.ANSWER)"]
    bare = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    assert subprocess.run(command, env=bare, cwd="/", capture_output=True, text=True).returncode != 0
    done = subprocess.run(command, env=child_environ(), cwd="/", capture_output=True, text=True)
    assert done.returncode == 0 and done.stdout.strip() == "42"
