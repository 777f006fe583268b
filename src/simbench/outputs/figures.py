"""A metric's figures (simbench.api.Metric.finish) as flat columns `<name>.<figure>`, and `<name>.<figure>.<key>`
for figures given by name (a joint's): the columns of a sweep's results.csv and of a comparison's table."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np


def columns(name: str, figures: Mapping[str, Any]) -> dict[str, Any]:
    """The figures of metric `name` as columns, in their order: numbers as Python numbers, lists as lists."""
    out: dict[str, Any] = {}
    for figure, value in figures.items():
        if isinstance(value, Mapping):
            out.update({f"{name}.{figure}.{key}": _python(v) for key, v in value.items()})
        else:
            out[f"{name}.{figure}"] = _python(value)
    return out


def _python(value: Any) -> Any:
    """A NumPy number or array (or a list of them) as Python's, which a CSV cell or JSON writes as it reads."""
    if isinstance(value, (np.ndarray, np.generic)):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [_python(v) for v in value]
    return value
