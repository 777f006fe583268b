"""The two ways a simbench command fails: bad input (exit 2) and a run that cannot go on (exit 1)."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from simbench.sim import Recording
    from simbench.trajectory import JointTrajectory


class ScenarioError(Exception):
    """A scenario file that cannot be used: names the file, the field and what is expected."""

    def __init__(self, source: str, field: str | None, message: str):
        self.source = source
        self.field = None if field is None else printable(field)
        self.message = printable(message)
        super().__init__(f"{source}: {self.detail}")

    @property
    def detail(self) -> str:
        """The field and what is expected, without the file: what a sweep's row says of a variant."""
        return f"{self.field}: {self.message}" if self.field else self.message


def printable(text: str) -> str:
    """Text with control characters and line breaks escaped (a key read from a file may hold any), so that an
    error stays one line."""
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in text)


class RunError(Exception):
    """A valid scenario whose run failed: an unreachable path, diverged physics."""


class PhysicsError(RunError):
    """The simulation failed mid-run (diverged, overflowed): when, why, the trajectory it was tracking and the
    recording up to then (None if it failed while settling, before the first tracked sample)."""

    def __init__(self, t: float, cause: str, trajectory: JointTrajectory, recording: Recording | None):
        self.t = t
        self.cause = cause
        self.trajectory = trajectory
        self.recording = recording
        when = f"at t = {t:.4f} s" if t >= 0 else f"while settling at the start pose ({-t:.4f} s before the start)"
        super().__init__(f"physics failed {when}: {cause}")
