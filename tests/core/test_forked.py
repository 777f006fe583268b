"""core.forked.dealt: jobs dealt out to this process and forked children, each answer in its job's place. Truths:
the jobs' own answers (their index and the process that ran them, os.getpid)."""

import os

import pytest

from simbench.core.forked import dealt


def _where(index: int) -> tuple[int, int]:
    return index, os.getpid()


def _raising(index: int) -> int:
    if index == 1:
        raise ValueError(f"job {index} in process {os.getpid()}")
    return index


def test_each_answer_is_in_its_jobs_place_and_process_w_runs_job_w_first():
    """7 jobs by 3 processes: the answers in the jobs' order; job 0 here, jobs 1 and 2 each in a child of its own."""
    answers = dealt([(_where, (i,)) for i in range(7)], 3, "testing")
    assert [index for index, _ in answers] == list(range(7))
    pids = [pid for _, pid in answers]
    assert pids[0] == os.getpid() and len({pids[0], pids[1], pids[2]}) == 3
    assert set(pids) == {pids[0], pids[1], pids[2]}


def test_one_process_runs_every_job_here():
    assert dealt([(_where, (i,)) for i in range(3)], 1, "testing") == [(i, os.getpid()) for i in range(3)]


def test_a_childs_error_reaches_the_caller():
    """Job 1, a child's first, raises: the caller gets its error, raised in the child."""
    with pytest.raises(ValueError, match="job 1 in process") as raised:
        dealt([(_raising, (i,)) for i in range(4)], 2, "testing")
    assert f"process {os.getpid()}" not in str(raised.value)
