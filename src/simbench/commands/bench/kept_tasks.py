"""A bench's drawn tasks, kept in its folder (KEPT) so that the same bench resumed there takes them rather than
drawing them again (0.1 to 1.1 s a task on one core: bench.tasks; some 200 s on two for the suite `all` at 100 tasks).

They are taken only on a resume (never with `force`, which starts over and draws anew), and only where what may
change between two runs of one installation is as it was when they were drawn (`_key`): the suite's version of the
benchmark, its seed and task count, each robot (its name, what shapes the generator's searches and the model's
hash) and the versions of simbench, NumPy, SciPy and MuJoCo, whose floating point the searches follow. A file that is
not such a record, or whose tasks do not match its digest, is drawn over. The code of a simbench whose version did
not change (an editable install being worked on) and the machine (its CPU, its BLAS) are not in the key: there the
resume takes the tasks its folder's finished runs ran, as the folder's manifest, which holds every run's document,
asks (a draw that differed would be refused there).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import scipy

from simbench.commands.bench.suite import Suite
from simbench.commands.bench.tasks import Task, draw_all
from simbench.core.atomic import holds, write_text
from simbench.core.version import __version__

KEPT = "tasks.json"
_TUPLES = tuple(f.name for f in dataclasses.fields(Task) if str(f.type).startswith("tuple"))  # lists in JSON


def tasks_for(out: Path, suite: Suite, models: dict[str, str], workers: int, force: bool) -> list[list[Task]]:
    """The suite's tasks, one list a robot: those kept in `out` where a resume may take them, else drawn by
    `workers` processes (bench.tasks.draw_all); `models`: each robot's model hash (BenchSpec.models)."""
    kept = None if force else _taken(out / KEPT, suite, models)
    return kept if kept is not None else draw_all(suite.robots, suite.tasks, suite.seed, suite.version, workers)


def keep(store, out: Path, suite: Suite, models: dict[str, str], tasks: list[list[Task]]) -> None:
    """Write the tasks into `out` (claimed in the folder's marker first) unless it holds them already."""
    text = _text(suite, models, tasks)
    if holds(out / KEPT, text):
        return
    store.claim((KEPT,))
    with store.writing():
        write_text(out / KEPT, text)


def _key(suite: Suite, models: dict[str, str]) -> dict:
    """What decides the suite's draw."""
    robots = [{"name": r.name, "mapping": r.mapping, "model": models[r.name], "hold": r.hold, "boundary": r.boundary,
               "shapes": list(r.shapes), "speed": r.speed, "floor": r.floor, "plane": r.plane} for r in suite.robots]
    return {"version": suite.version, "seed": suite.seed, "tasks": suite.tasks, "robots": robots,
            "simbench": __version__, "numpy": np.__version__, "scipy": scipy.__version__, "mujoco": mujoco.__version__}


def _text(suite: Suite, models: dict[str, str], tasks: list[list[Task]]) -> str:
    """The record (a machine's: the runs' scenario files are the tasks to read): the key, the tasks (one list a
    robot, each task its fields) and their digest."""
    drawn = [[dataclasses.asdict(task) for task in robot] for robot in tasks]
    return json.dumps({"key": _key(suite, models), "digest": _digest(drawn), "tasks": drawn}) + "\n"


def _digest(drawn: list) -> str:
    return hashlib.sha256(json.dumps(drawn, sort_keys=True).encode()).hexdigest()


def _taken(path: Path, suite: Suite, models: dict[str, str]) -> list[list[Task]] | None:
    """The tasks the record at `path` holds where it is the suite's (key and digest as they should be), else None."""
    try:
        if path.is_symlink() or not path.is_file():
            return None
        record = json.loads(path.read_text(encoding="utf-8"))
        drawn = record["tasks"]
        if record["key"] != json.loads(json.dumps(_key(suite, models))) or record["digest"] != _digest(drawn):
            return None
        tasks = [[_task(fields) for fields in robot] for robot in drawn]
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError, AttributeError):
        return None
    expected = [[(r.name, i) for i in range(suite.tasks)] for r in suite.robots]
    return tasks if [[(task.robot, task.index) for task in robot] for robot in tasks] == expected else None


def _task(fields: dict[str, Any]) -> Task:
    """A task from its fields as the record holds them (its tuples as lists)."""
    values: dict[str, Any] = {name: tuple(value) if name in _TUPLES else value for name, value in fields.items()}
    return Task(**values)
