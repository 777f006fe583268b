"""What a run met and what it broke, as records: the events of its analysis and the violations of its verdict.
Public through simbench.api (api.Event, api.Violation); a leaf of simbench's imports, as api is."""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any


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
    """Something a run met from `t_start` to `t_end` (s; equal for an instant): its kind and detail (SI units)."""

    t_start: float
    t_end: float
    kind: str
    detail: dict[str, Any] = field(default_factory=dict)

    def entries(self) -> dict[str, Any]:
        return {"t_start": self.t_start, "t_end": self.t_end, "kind": self.kind, "detail": self.detail}

    @classmethod
    def of(cls, found: Event | Mapping[str, Any]) -> Event:
        """An Event, given one or its dict {t_start, t_end, kind[, detail]}."""
        return found if isinstance(found, Event) else cls(**found)


@dataclass(frozen=True)
class Violation(_Entries):
    """A promise a run broke (simbench.verdict): its one-line message, from when (`t`, s, or None), how many
    events show it, and how badly (`detail`)."""

    kind: str
    message: str
    t: float | None = None
    events: int = 0
    detail: dict[str, Any] = field(default_factory=dict)

    def entries(self) -> dict[str, Any]:
        return {"kind": self.kind, "message": self.message, "t": self.t, "events": self.events, **self.detail}

    @classmethod
    def of(cls, found: Violation | Mapping[str, Any]) -> Violation:
        """A Violation, given one or its dict {kind, message[, t, events], ...}, the other entries its detail."""
        if isinstance(found, Violation):
            return found
        rest = dict(found)
        kind, message, t, events = rest.pop("kind"), rest.pop("message"), rest.pop("t", None), rest.pop("events", 0)
        return cls(kind, message, t, events, rest)
