"""Where the shipped models, scenarios and sweeps live: inside the wheel, or at the root of a source checkout."""

from __future__ import annotations

from pathlib import Path

_PACKAGE = Path(__file__).resolve().parents[1]  # simbench/ (this module lies in simbench/core/)


def _find(name: str) -> Path:
    for candidate in (_PACKAGE / name, _PACKAGE.parents[1] / name):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(f"simbench's {name}/ folder is missing from {_PACKAGE} and the source tree")


def models_dir() -> Path:
    """models/: one folder per robot with its MJCF."""
    return _find("models")


def scenarios_dir() -> Path:
    """scenarios/: the shipped YAML scenarios, one folder per robot."""
    return _find("scenarios")


def sweeps_dir() -> Path:
    """sweeps/: the shipped sweep files."""
    return _find("sweeps")
