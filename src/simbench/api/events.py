"""What a run met and what it broke, as records: the events of its analysis and the violations of its verdict.
Public through simbench.api (api.Event, api.Violation); a leaf of simbench's imports, as api is."""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

KINDS = ("joint_limit", "velocity_limit", "reference_jump", "actuator_saturation", "off_path", "orientation_error",
         "goal_missed", "singular_crossing", "clearance_margin", "acceleration_limit", "force_limit", "contact")
"""The kinds of violation a verdict finds (simbench.analysis.verdict); a robot adds its own (Robot.breaking)."""


class _Entries(Mapping):
    """A record that reads as the dict of its report.json entries (`event["kind"]`, `.get`, `dict(event)`)."""

    @abstractmethod
    def entries(self) -> dict[str, Any]:
        """The record's report.json entries."""

    def __getitem__(self, key: str) -> Any:
        return self.entries()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.entries())

    def __len__(self) -> int:
        return len(self.entries())


@dataclass(frozen=True)
class Event(_Entries):
    """Something a run met: a singular set neared, a joint limit reached.

    Read as the dict report.json holds (`event["kind"]`).

    Attributes:
        t_start: When it began (s).
        t_end: When it ended (s); `t_start` for an instant.
        kind: What it is (`joint_limit`, a singular set's name, ...).
        detail: What else it says, SI units.
    """

    t_start: float
    t_end: float
    kind: str
    detail: dict[str, Any] = field(default_factory=dict)

    def entries(self) -> dict[str, Any]:
        """The event as report.json writes it.

        Returns:
            `t_start`, `t_end`, `kind` and `detail`.
        """
        return {"t_start": self.t_start, "t_end": self.t_end, "kind": self.kind, "detail": self.detail}

    @classmethod
    def of(cls, found: Event | Mapping[str, Any]) -> Event:
        """An Event, given one or its dict.

        Args:
            found: An Event, or a dict {t_start, t_end, kind[, detail]}.

        Returns:
            The Event.
        """
        return found if isinstance(found, Event) else cls(**found)


@dataclass(frozen=True)
class Violation(_Entries):
    """A promise a run broke (`simbench.analysis.verdict`): why its status is not `ok`.

    Read as the dict report.json holds (`violation["kind"]`), its detail's entries beside the others.

    Attributes:
        kind: Which promise (`velocity_limit`, `off_path`, ...).
        message: What happened, in one line.
        t: From when (s), or None.
        events: How many events show it.
        detail: How badly, SI units.
    """

    kind: str
    message: str
    t: float | None = None
    events: int = 0
    detail: dict[str, Any] = field(default_factory=dict)

    def entries(self) -> dict[str, Any]:
        """The violation as report.json writes it.

        Returns:
            `kind`, `message`, `t` and `events`, and the detail's entries beside them.
        """
        return {"kind": self.kind, "message": self.message, "t": self.t, "events": self.events, **self.detail}

    @classmethod
    def of(cls, found: Violation | Mapping[str, Any]) -> Violation:
        """A Violation, given one or its dict.

        Args:
            found: A Violation, or a dict {kind, message[, t, events], ...}, the other entries its detail.

        Returns:
            The Violation.
        """
        if isinstance(found, Violation):
            return found
        rest = dict(found)
        kind, message, t, events = rest.pop("kind"), rest.pop("message"), rest.pop("t", None), rest.pop("events", 0)
        return cls(kind, message, t, events, rest)
