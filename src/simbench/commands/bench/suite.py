"""Bench suites (docs/guide/bench.md): the robots, how many tasks each and at what seed, the version of the
benchmark's definition they are drawn by (bench.tasks.VERSIONS), and the methods. A shipped suite is named by a robot
(or `all`); a suite file's errors name the file and the field, as a scenario's do.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Annotated, Any

from pydantic import Field, ValidationError

from simbench.commands.bench import methods as methods_table
from simbench.commands.bench.robots import SHIPPED, BenchRobot, custom
from simbench.commands.bench.tasks import GENERATOR, VERSIONS
from simbench.core.errors import ScenarioError
from simbench.scenario.schema import Name, SimbenchModel, file_name
from simbench.scenario.validation import describe, read_spec

MAX_TASKS = 10000
DEFAULT_TASKS = 30
MAX_SEED = 2**63 - 1  # the tasks' seed, as a suite file gives it or --seed
MAX_SLOWDOWN = 10.0  # a run whose plan takes longer than this times the asked duration is `too_slow` (its default)
PLAN_SECONDS = 120.0  # s: a run still planning after this long is cut, `too_slow` (its default)


class SuiteSpec(SimbenchModel):
    """A suite file as written."""

    name: Name | None = None
    version: str = GENERATOR
    description: str = ""
    tasks: Annotated[int, Field(ge=1, le=MAX_TASKS)] = DEFAULT_TASKS
    seed: Annotated[int, Field(ge=0, le=MAX_SEED)] = 0
    methods: Annotated[list[str], Field(min_length=1)] | None = None
    robots: Annotated[list[str | dict[str, Any]], Field(min_length=1)]
    max_slowdown: Annotated[float, Field(gt=0.0, le=1e6)] = MAX_SLOWDOWN
    plan_seconds: Annotated[float, Field(gt=0.0, le=86400.0)] = PLAN_SECONDS


class _OwnArm(SimbenchModel):
    """The name a suite file gives an arm of its own, held to the rule of a scenario's `name:` (it names rows and
    folders)."""

    name: Name


@dataclass(frozen=True)
class Suite:
    """A suite ready to draw: its name, where it came from, its robots, tasks per robot, seed and methods, the costs
    past which a run is `too_slow` (its plan's slowdown: planned over asked duration; the seconds it plans), and the
    version of the benchmark's definition its tasks are drawn by."""

    name: str
    source: str
    robots: tuple[BenchRobot, ...]
    tasks: int
    seed: int
    methods: tuple[str, ...]
    description: str = ""
    max_slowdown: float = MAX_SLOWDOWN
    plan_seconds: float = PLAN_SECONDS
    version: str = GENERATOR

    def with_options(self, tasks: int | None = None, seed: int | None = None,
                     methods: list[str] | None = None) -> Suite:
        """The suite with the command line's overrides; ScenarioError naming the option at fault."""
        if tasks is not None and not 1 <= tasks <= MAX_TASKS:
            raise ScenarioError("--tasks", None, f"expected a number of tasks from 1 to {MAX_TASKS}, got {tasks}")
        if seed is not None and not 0 <= seed <= MAX_SEED:
            raise ScenarioError("--seed", None, f"expected a seed from 0 to {MAX_SEED} (2^63 - 1), got {seed}")
        chosen = self.methods if methods is None else tuple(check_methods(methods, "--methods", None))
        return replace(self, tasks=self.tasks if tasks is None else tasks, seed=self.seed if seed is None else seed,
                       methods=chosen)


def check_methods(names: list[str], source: str, field: str | None) -> list[str]:
    """`names` if each is a method simbench has and can run here; ScenarioError naming the first that is not."""
    for i, name in enumerate(names):
        where = f"{field}[{i}]" if field else None
        if name not in methods_table.METHODS:
            raise ScenarioError(source, where, f"unknown method {name!r} (expected one of: "
                                               f"{', '.join(methods_table.METHODS)})")
        refusal = methods_table.refusal(name)
        if refusal:  # its optional package is not installed
            raise ScenarioError(source, where, refusal)
    if len(set(names)) != len(names):
        raise ScenarioError(source, field, "a method is named twice")
    return list(names)


def load_suite(text: str | Path) -> Suite:
    """A suite of random tasks and methods to bench.

    Args:
        text: A shipped suite by robot name (`puma600`, `jaco`, ..., or `all`), or a suite file's path.

    Returns:
        The suite: its robots, tasks per robot, seed and methods.

    Raises:
        ScenarioError: naming the file and the field at fault.
    """
    text = str(text)
    if text == "all" or text in SHIPPED:
        names = list(SHIPPED) if text == "all" else [text]
        return Suite(text, f"{text} (shipped suite)", tuple(SHIPPED[n]() for n in names), DEFAULT_TASKS, 0,
                     tuple(methods_table.installed()))
    path = Path(text)
    if not path.suffix and not path.exists():
        raise ScenarioError(text, None, f"no shipped suite or suite file called {text!r} (shipped suites: all, "
                                        f"{', '.join(SHIPPED)})")
    return _load_file(path)


def _load_file(path: Path) -> Suite:
    source = str(path)
    spec = read_spec(path, SuiteSpec, "suite")
    if spec.version not in VERSIONS:
        raise ScenarioError(source, "version", f"unknown benchmark version {spec.version!r} (this simbench has: "
                                               f"{', '.join(VERSIONS)})")
    robots = [_robot(entry, i, path) for i, entry in enumerate(spec.robots)]
    names = [r.name for r in robots]
    for i, name in enumerate(names):
        if name in names[:i]:
            raise ScenarioError(source, f"robots[{i}]", f"robot {name!r} is listed twice")
    chosen = (check_methods(spec.methods, source, "methods") if spec.methods is not None
              else methods_table.installed())
    return Suite(spec.name or file_name(path.stem, source), source, tuple(robots), spec.tasks, spec.seed,
                 tuple(chosen), spec.description, spec.max_slowdown, spec.plan_seconds, spec.version)


def _robot(entry: str | dict, i: int, path: Path) -> BenchRobot:
    """The bench robot of `robots[i]`: a shipped one by name, or a mapping of the suite file's own."""
    source, where = str(path), f"robots[{i}]"
    if isinstance(entry, str):
        if entry not in SHIPPED:
            raise ScenarioError(source, where, f"unknown robot {entry!r} (shipped: {', '.join(SHIPPED)}; or a "
                                               "mapping with name and model)")
        try:
            return SHIPPED[entry]()
        except ScenarioError as err:
            raise ScenarioError(source, where, err.message) from None
    mapping = dict(entry)
    name, speed = mapping.pop("name", None), mapping.pop("speed", 0.1)
    if name is None:
        raise ScenarioError(source, f"{where}.name", "missing: an arm of your own needs a name")
    try:
        _OwnArm(name=name)
    except ValidationError as err:
        raise ScenarioError(source, f"{where}.name", describe(err, _OwnArm, {"name": name})[1]) from None
    if isinstance(speed, bool) or not isinstance(speed, (int, float)) or not 0 < speed <= 10:
        raise ScenarioError(source, f"{where}.speed", f"expected a tool speed in m/s, > 0 and <= 10, got {speed!r}")
    from simbench.scenario.robot_mapping import anchored, load_robot
    from simbench.scenario.schema import Units

    mapping = anchored({**mapping, "name": name}, path.parent)  # the arm's name in its runs' reports, as in the suite
    try:
        arm = load_robot(mapping, source, Units())
    except ScenarioError as err:
        field = (err.field or "").removeprefix("robot").lstrip(".")
        raise ScenarioError(source, f"{where}.{field}" if field else where, err.message) from None
    return custom(name, mapping, arm.dof, float(speed))
