"""How big a sweep is, counted before anything is expanded: its runs and the memory their documents would take
(NODE_BYTES a YAML value of a run: BENCHMARKS.md, the sweep's notes). A sweep too big for the memory budget is
the sweep file's error, naming the field to blame, rather than a process the kernel ends.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from simbench.core import budget
from simbench.core.errors import ScenarioError

MAX_RUNS = 100_000
NODE_BYTES = 100  # a YAML value of one run, at the peak of expanding a sweep and writing its manifest


@dataclass(frozen=True)
class Size:
    """A sweep's runs, the YAML values a run's document holds at most, and the field that sets most of them."""

    runs: int
    values: int
    largest: tuple[str, int] | None  # (swept field, values of its largest value), None with nothing swept

    @property
    def memory(self) -> int:
        """Bytes its expansion takes (see the module's docstring)."""
        return self.runs * self.values * NODE_BYTES


def values(value: Any) -> int:
    """The YAML values in `value`: 1 for a scalar, a list's items and a mapping's keys and values counted too."""
    if isinstance(value, dict):
        return 1 + sum(1 + values(v) for v in value.values())
    if isinstance(value, list):
        return 1 + sum(values(v) for v in value)
    return 1


def measure(spec, document: dict) -> Size:
    """The size of the sweep `spec` (a SweepSpec) over the base `document`, from the lengths of its lists only."""
    runs = math.prod(len(v) for v in spec.grid.values()) * (spec.random.samples if spec.random else 1)
    swept = {f"grid.{name}": max(map(values, options)) for name, options in spec.grid.items()}
    if spec.random:
        swept.update({f"random.params.{name}": _drawn_values(dist) for name, dist in spec.random.params.items()})
    largest = max(swept.items(), key=lambda item: item[1], default=None)
    return Size(runs, values(document) + sum(swept.values()), largest)


def _count_field(spec) -> str:
    """The field that multiplies the runs most: random.samples, or the grid."""
    points = math.prod(len(v) for v in spec.grid.values())
    return "random.samples" if spec.random and spec.random.samples >= points else "grid"


def _drawn_values(dist) -> int:
    """The YAML values of one draw of a Distribution: a number, a vector as long as its bounds, or a choice."""
    if dist.kind == "choice":
        return max(map(values, dist.choice))
    if dist.kind == "integers":
        return 1
    return values(getattr(dist, dist.kind)[0])


def check(spec, document: dict, source: str) -> Size:
    """The sweep's size; ScenarioError naming the field to blame for over MAX_RUNS runs or the memory budget."""
    size = measure(spec, document)
    count_field = _count_field(spec)
    if size.runs > MAX_RUNS:
        raise ScenarioError(source, count_field, f"{size.runs} runs (expected at most {MAX_RUNS})")
    limits = budget.machine_limits()
    if size.memory <= limits.memory:
        return size
    fit = limits.memory // (size.values * NODE_BYTES)
    cost = (f"about {budget.size(size.memory)} of memory to expand, more than the {budget.size(limits.memory)} "
            f"this machine allows ({limits.memory_basis})")
    field, swept = size.largest or (count_field, 0)
    if 2 * swept > size.values:  # one field's values make most of each run
        raise ScenarioError(source, field, f"its values hold up to {swept:,} YAML values, copied into each of the "
                                           f"{size.runs:,} runs: {cost}; expected at most {fit:,} runs of values "
                                           "this large, or smaller values")
    raise ScenarioError(source, count_field, f"{size.runs:,} runs of {size.values:,} YAML values each: {cost}; "
                                             f"expected at most {fit:,} runs")
