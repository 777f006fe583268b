"""What a run met and what it broke, as records: the events of its analysis and the violations of its verdict.
Public through simbench.api (api.Event, api.Violation); a leaf of simbench's imports, as api is."""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any


class _Entries(Mapping):
    """A record that reads as the dict it replaced (`event["kind"]`, `.get`, `dict(event)`): its report.json
    entries, in the order report.json writes them, so that scripts written against the dicts keep working."""

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
    """Something a run met over a span of time (a singular set neared, a joint at its limit, an assembly-mode
    change): from `t_start` to `t_end` (s, the plan's times; equal for an instant), its kind and what the analysis or
    the robot found there (SI units). report.json writes it as {t_start, t_end, kind, detail}."""

    t_start: float
    t_end: float
    kind: str
    detail: dict[str, Any] = field(default_factory=dict)

    def entries(self) -> dict[str, Any]:
        return {"t_start": self.t_start, "t_end": self.t_end, "kind": self.kind, "detail": self.detail}

    @classmethod
    def of(cls, found: Event | Mapping[str, Any]) -> Event:
        """An Event, given one or the dict {t_start, t_end, kind[, detail]} that a robot written before it returns."""
        return found if isinstance(found, Event) else cls(**found)


@dataclass(frozen=True)
class Violation(_Entries):
    """A promise a run broke (simbench.verdict lists the kinds): what, in one line, from when (`t`, s; None where
    it has no time), how many events show it, and the figures that say how badly (`detail`: the joint, the worst
    excess, ...). report.json writes it as {kind, message, t, events, **detail}."""

    kind: str
    message: str
    t: float | None = None
    events: int = 0
    detail: dict[str, Any] = field(default_factory=dict)

    def entries(self) -> dict[str, Any]:
        return {"kind": self.kind, "message": self.message, "t": self.t, "events": self.events, **self.detail}

    @classmethod
    def of(cls, found: Violation | Mapping[str, Any]) -> Violation:
        """A Violation, given one or the dict {kind, message[, t, events], ...} that a planner written before it
        reports (JointTrajectory.violations): its other entries are the detail."""
        if isinstance(found, Violation):
            return found
        rest = dict(found)
        kind, message, t, events = rest.pop("kind"), rest.pop("message"), rest.pop("t", None), rest.pop("events", 0)
        return cls(kind, message, t, events, rest)
