"""What a method's row says, decided in one place for `compare` (comparison.csv) and `simbench bench` (runs.csv):
status, error, deviation_max (report.json's tracking.tool_max, m), orientation_max (its tracking.orientation_max,
rad: the tool's orientation error, where the robot has one) and simbench.analysis.singularity_handling's figures; None
for
each where a run got none.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from simbench.analysis.singularity_handling import SingularityHandling

FIGURES = ("deviation_max", "speed_share_max", "slowdown", "closest_approach")
_METRIC = SingularityHandling.name


def score(status: str, error: str | None, tracking: Mapping[str, Any] | None,
          metrics: Mapping[str, Mapping[str, Any]] | None) -> dict[str, Any]:
    """The shared columns of a run's row (the module's docstring): `tracking` as report.json's, `metrics` its
    metrics by name."""
    ours = (metrics or {}).get(_METRIC) or {}
    return {"status": status, "error": error, "deviation_max": _number((tracking or {}).get("tool_max")),
            "orientation_max": _number((tracking or {}).get("orientation_max")),
            **{name: _number(ours.get(name)) for name in FIGURES[1:]}}


def score_flat(status: str, error: str | None, flat: Mapping[str, Any]) -> dict[str, Any]:
    """`score` of a sweep's flat figures (simbench.commands.sweep.execute.metrics: tool_max, <metric>.<figure>)."""
    tracking = {name: flat[name] for name in ("tool_max", "orientation_max") if flat.get(name) is not None}
    metrics = {_METRIC: {name: flat.get(f"{_METRIC}.{name}") for name in FIGURES[1:]}}
    return score(status, error, tracking, metrics)


def _number(value: Any) -> float | None:
    return None if value is None else float(value)
