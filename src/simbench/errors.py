"""The two ways a simbench command fails: bad input (exit 2) and a run that cannot go on (exit 1)."""

from __future__ import annotations


class ScenarioError(Exception):
    """A scenario file that cannot be used: names the file, the field and what is expected."""

    def __init__(self, source: str, field: str | None, message: str):
        self.source = source
        self.field = field
        self.message = message
        where = f"{source}: {field}" if field else source
        super().__init__(f"{where}: {message}")


class RunError(Exception):
    """A valid scenario whose run failed: an unreachable path, diverged physics."""
