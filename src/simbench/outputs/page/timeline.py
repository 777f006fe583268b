"""A run's events on one time axis: an inline SVG with a lane per kind of event, and the same events as a table."""

from __future__ import annotations

import math

from simbench.outputs.page.html import esc, number

_WIDTH = 1000  # the SVG's user units; it scales to the page's width
_LEFT, _RIGHT, _TOP = 130, 24, 10
_LANE = 36  # a lane: a row of labels over a row of marks
_LABEL_BASE, _MARK_TOP = 11, 15  # below the lane's top: the labels' baseline (10.5 px text), the marks' top
_CHAR = 6.3  # a label's width a character, at most (10.5 px system-ui or DejaVu Sans)
_AXIS = 34
_MAX_LABELS = 10  # a lane with more marks than this names them in its tooltips and the table only
_MAX_ROWS = 300

# (lane, the report's key for its events, colour)
_LANES = (
    ("failure", "failure", "#b3261e"),
    ("violation", "violations", "#d0461c"),
    ("singularity", "singularity_events", "#6a3d9a"),
    ("limit", "limit_events", "#d97a00"),
    ("switch", "switch_events", "#1b7f79"),
    ("warning", "warnings", "#a68a00"),
)


def events(report: dict) -> list[dict]:
    """Every event of the report as {lane, kind, t_start, t_end (None: an instant), detail}."""
    out: list[dict] = []
    for lane, key, _ in _LANES:
        entries = report.get(key) or []
        if isinstance(entries, dict):
            entries = [entries]
        for e in entries:
            if not isinstance(e, dict):
                out.append({"lane": lane, "kind": str(e), "t_start": None, "t_end": None, "detail": ""})
                continue
            if "t_start" in e:
                t0, t1 = e.get("t_start"), e.get("t_end")
                detail = e.get("detail", "")
            else:
                t0, t1 = e.get("t"), None
                detail = {k: v for k, v in e.items() if k not in ("t", "kind")}
            kind = e.get("kind", lane)
            out.append({"lane": lane, "kind": str(kind), "t_start": _time(t0), "t_end": _time(t1),
                        "detail": detail})
    return out


def _time(value) -> float | None:
    return float(value) if isinstance(value, (int, float)) and math.isfinite(value) else None


def _describe(detail) -> str:
    """An event's detail as one line: `key: value; ...`, nested mappings in parentheses."""
    if isinstance(detail, dict):
        return "; ".join(f"{k}: ({_describe(v)})" if isinstance(v, dict) else f"{k}: {number(v)}"
                         for k, v in detail.items())
    return "" if detail is None or detail == "" else number(detail)


def _ticks(end: float) -> list[float]:
    """Round times from 0 to `end`, about eight of them."""
    raw = end / 8
    step = 10 ** math.floor(math.log10(raw))
    step *= next(m for m in (1, 2, 2.5, 5, 10) if m * step >= raw)
    return [k * step for k in range(int(end / step + 1e-9) + 1)]


def svg(found: list[dict], end: float) -> str:
    """The timeline from 0 to `end` s: a lane per kind of event that occurred."""
    timed = [e for e in found if e["t_start"] is not None]
    lanes = [lane for lane in _LANES if any(e["lane"] == lane[0] for e in timed)]
    if not lanes:
        return ""
    end = max([end] + [e["t_end"] or e["t_start"] for e in timed])
    end = end if end > 0 else 1.0
    span = _WIDTH - _LEFT - _RIGHT
    height = _TOP + _LANE * len(lanes) + _AXIS

    def x(t: float) -> float:
        return _LEFT + span * min(max(t, 0.0), end) / end

    parts = [f'<svg class="timeline" viewBox="0 0 {_WIDTH} {height}" role="img" '
             f'xmlns="http://www.w3.org/2000/svg" font-family="system-ui, sans-serif" font-size="12">',
             f"<title>events against time, 0 to {number(end)} s</title>"]
    for i, (lane, _, colour) in enumerate(lanes):
        top = _TOP + i * _LANE
        mid = top + _LANE / 2
        fill = "#f4f6f9" if i % 2 == 0 else "#ffffff"
        parts.append(f'<rect x="{_LEFT}" y="{top}" width="{span}" height="{_LANE}" fill="{fill}"/>')
        parts.append(f'<text x="{_LEFT - 8}" y="{mid + 4}" text-anchor="end" fill="{colour}" '
                     f'font-weight="600">{esc(lane)}</text>')
        marks = sorted((e for e in timed if e["lane"] == lane), key=lambda e: e["t_start"])
        last_label_end = -math.inf
        for e in marks:
            x0 = x(e["t_start"])
            when = f"t = {number(e['t_start'])} s" if e["t_end"] is None else \
                f"t = {number(e['t_start'])} to {number(e['t_end'])} s"
            tip = f"<title>{esc(e['kind'])}, {esc(when)}</title>"
            if e["t_end"] is None:
                parts.append(f'<g class="mark"><path d="M{x0:.1f} {top + _MARK_TOP} l5 6 l-5 6 l-5 -6 z '
                             f'M{x0:.1f} {top + _MARK_TOP + 12} V{top + _LANE - 3}" fill="{colour}" '
                             f'stroke="{colour}" stroke-width="2"/>{tip}</g>')
            else:
                w = max(x(e["t_end"]) - x0, 2.0)
                parts.append(f'<g class="mark"><rect x="{x0:.1f}" y="{top + _MARK_TOP + 1}" width="{w:.1f}" '
                             f'height="{_LANE - _MARK_TOP - 4}" fill="{colour}" fill-opacity="0.75" rx="2"/>{tip}</g>')
            label = f"{e['kind']} {number(e['t_start'], 3)} s"
            width = _CHAR * len(label)
            start = x0 - 5 + width < _WIDTH  # starting over the mark's left edge, else ending over its right one
            left = x0 - 5 if start else x0 + 5 - width
            if len(marks) <= _MAX_LABELS and left > last_label_end:
                anchor, at = ("start", x0 - 5) if start else ("end", x0 + 5)
                parts.append(f'<text class="label" x="{at:.1f}" y="{top + _LABEL_BASE}" text-anchor="{anchor}" '
                             f'font-size="10.5" fill="#1d2330">{esc(label)}</text>')
                last_label_end = left + width + 6
    base = _TOP + _LANE * len(lanes)
    parts.append(f'<line x1="{_LEFT}" y1="{base}" x2="{_LEFT + span}" y2="{base}" stroke="#1d2330"/>')
    for t in _ticks(end):
        parts.append(f'<line x1="{x(t):.1f}" y1="{base}" x2="{x(t):.1f}" y2="{base + 5}" stroke="#1d2330"/>'
                     f'<text x="{x(t):.1f}" y="{base + 18}" text-anchor="middle">{number(t)}</text>')
    parts.append(f'<text x="{_LEFT + span}" y="{base + 31}" text-anchor="end" fill="#5b6475">time (s)</text>')
    parts.append("</svg>")
    return "\n".join(parts) + "\n"


def table(found: list[dict]) -> str:
    """The events in time order (untimed ones last), one row each."""
    if not found:
        return ""
    ordered = sorted(found, key=lambda e: (e["t_start"] is None, e["t_start"] or 0.0))
    rows = "".join(
        f'<tr><td>{esc(e["lane"])}</td><td class="kind">{esc(e["kind"])}</td>'
        f'<td class="n">{esc(number(e["t_start"]) if e["t_start"] is not None else "")}</td>'
        f'<td class="n">{esc(number(e["t_end"]) if e["t_end"] is not None else "")}</td>'
        f'<td>{esc(_describe(e["detail"]))}</td></tr>\n' for e in ordered[:_MAX_ROWS])
    more = (f'<p class="note">The first {_MAX_ROWS} of {len(ordered)} events; all are in report.json.</p>\n'
            if len(ordered) > _MAX_ROWS else "")
    return ('<div class="scroll"><table class="events"><thead><tr><th>lane</th><th>kind</th><th>start (s)</th>'
            f"<th>end (s)</th><th>detail</th></tr></thead>\n<tbody>\n{rows}</tbody></table></div>\n{more}")
