"""A run's page, from its report.json document: status, headline figures, events, video, plots and configuration."""

from __future__ import annotations

import json
import math
from pathlib import Path

from simbench.outputs.page import timeline
from simbench.outputs.page.html import (cards, config_section, document, esc, figure_grid, flatten, href, inside,
                                        number, paragraphs, scaled, table)

_MM, _DEG = 1e3, 180 / math.pi
_STATUS_TEXT = {"ok": "kept every promise its report makes", "limits": "broke a promise (below)",
                "failed": "the physics failed"}
# tracking entries shown as headline figures: (key, label, scale, unit, the key shown beside it as its RMS)
_HEADLINE = (
    ("tool_max", "tool off the planned path, max", _MM, "mm", "tool_rms"),
    ("tool_lag_max", "tool lag along the path, max", _MM, "mm", "tool_lag_rms"),
    ("tool_error_max", "tool against the reference point, max", _MM, "mm", "tool_error_rms"),
    ("tool_error_final", "tool from the plan's end, at the end", _MM, "mm", None),
    ("orientation_max", "orientation error, max", _DEG, "deg", "orientation_rms"),
    ("orientation_final", "orientation error at the end", _DEG, "deg", None),
    ("path_length", "planned path length", _MM, "mm", None),
)
_SHOWN = {"scenario", "robot", "planner", "control", "versions", "timestep", "duration", "hold", "settle",
          "time_law", "status", "violations", "expected", "failure", "samples", "tracking", "singularity_events",
          "limit_events", "switch_events", "warnings", "plan", "waypoints", "wall_time", "outputs", "config", "metrics",
          "record_every", "derived_arm"}
# a robot's own figures (report.json beyond the common entries), in the units a reader thinks in
_EXTRA_UNITS = {"closure_error_max": (_MM, "mm"), "rotor_error_max": (_DEG, "deg"),
                "orientation_error_max": (_DEG, "deg"), "gripping_gamma": (_DEG, "deg")}


def run_page(out: Path, report: dict) -> str:
    """The page of the run whose outputs are in `out` (write it after them), from its report.json document."""
    out = Path(out)
    scenario = report.get("scenario") or {}
    name = scenario.get("name") or "run"
    title = f"{name}: {report.get('robot', '?')} / {report.get('planner', '?')}"
    outputs = report.get("outputs") or {}
    body = [f"<h1>{esc(title)}</h1>\n", paragraphs(scenario.get("description"), "sub"), _subtitle(report),
            _status(report), _headline(report), _metrics(report), _events(report), _video(out, outputs)]
    plots = outputs.get("plots") or []
    if plots:
        body.append(f'<h2 id="plots">Plots</h2>\n{figure_grid(out, plots)}')
    body += [_derived(report), _plan(report), _facts(report), _files(out, report),
             config_section(report.get("config"), "As the run used it, after defaults and units: SI units, radians.")]
    return document(f"simbench: {title}", "".join(body))


def _subtitle(report: dict) -> str:
    control = report.get("control") or {}
    controller = control.get("controller", "?")
    if control.get("actuation"):
        controller += f" ({control['actuation']})"
    scenario = report.get("scenario") or {}
    bits = [f"robot <b>{esc(report.get('robot', '?'))}</b>", f"planner <b>{esc(report.get('planner', '?'))}</b>",
            f"controller <b>{esc(controller)}</b>"]
    if report.get("time_law"):
        bits.append(f"time law {esc(report['time_law'])}")
    if isinstance(report.get("duration"), (int, float)):
        bits.append(f"{esc(number(report['duration']))} s + {esc(number(report.get('hold', 0)))} s hold")
    if scenario.get("file"):
        bits.append(f"scenario file <code>{esc(scenario['file'])}</code>")
    return f'<p class="sub">{" &middot; ".join(bits)}</p>\n'


def _status(report: dict) -> str:
    status = str(report.get("status", "unknown"))
    css = status if status in _STATUS_TEXT else "other"
    parts = [f'<h2 id="status">Status</h2>\n<p><span class="status {css}">{esc(status)}</span> '
             f"{esc(_STATUS_TEXT.get(status, ''))}</p>\n"]
    failure = report.get("failure")
    if isinstance(failure, dict):
        where = f" ({failure['stage']})" if failure.get("stage") else ""
        parts.append(f'<p class="failure"><b>Failed{esc(where)} at t = {esc(number(failure.get("t")))} s:</b> '
                     f'{esc(failure.get("cause", ""))}</p>\n')
    violations = report.get("violations") or []
    if violations:
        items = "".join(f'<li><span class="kind">{esc(v.get("kind", "?"))}</span>'
                        + (f' at t = {esc(number(v["t"]))} s' if isinstance(v.get("t"), (int, float)) else "")
                        + f': {esc(v.get("message", ""))}</li>\n' for v in violations)
        parts.append(f'<ul class="violations">\n{items}</ul>\n')
    expected = report.get("expected")
    if isinstance(expected, dict):
        met = "met" if expected.get("met") else "NOT met"
        kinds = ", ".join(map(str, expected.get("violations") or [])) or "none"
        parts.append(f"<p>The scenario expects this failure (status {esc(expected.get('status', '?'))}, violations "
                     f"{esc(kinds)}): <b>{esc(met)}</b>. {esc(expected.get('reason', ''))}</p>\n")
    return "".join(parts)


def _headline(report: dict) -> str:
    tracking = report.get("tracking")
    if not isinstance(tracking, dict):
        return ('<h2 id="figures">Headline figures</h2>\n<p class="note">None: the run did not finish, so nothing '
                "was analysed.</p>\n") if report.get("status") == "failed" else ""
    items, used = [], set()
    for key, label, scale, unit, rms in _HEADLINE:
        if key in tracking:
            note = f"RMS {scaled(tracking[rms], scale, unit)}" if rms and rms in tracking else ""
            items.append((label, scaled(tracking[key], scale, unit), note))
            used |= {key, rms}
    for key, value in tracking.items():
        if key not in used and isinstance(value, (int, float)) and not isinstance(value, bool):
            items.append((key.replace("_", " "), number(value), "SI units"))
    parts = [f'<h2 id="figures">Headline figures</h2>\n{cards(items)}']
    rms, top = tracking.get("joint_rms"), tracking.get("joint_max")
    if isinstance(rms, dict) and isinstance(top, dict):
        names = list(top)
        parts.append(table(["", *names], [["RMS", *(rms.get(n) for n in names)], ["max", *(top.get(n) for n in names)]],
                           "Joint tracking error (rad for a revolute joint, m for a prismatic one)", 4))
    extras = [(key, value) for key, value in report.items() if key not in _SHOWN]
    if extras:
        rows = []
        for key, value in extras:
            scale, unit = _EXTRA_UNITS.get(key, (1.0, ""))
            for path, leaf in flatten({key: value}):
                rows.append([path, scaled(leaf, scale, unit) if unit else number(leaf)])
        parts.append(table(["figure", "value"], rows, "The robot's own figures"))
    return "".join(parts)


def _metrics(report: dict) -> str:
    """Each metric's figures (report.json metrics.<name>), a table each."""
    found = report.get("metrics")
    if not isinstance(found, dict) or not found:
        return ""
    tables = [table(["figure", "value"], [[path, _figure(report, f"{name}.{path}", value)]
                                          for path, value in flatten(figures)],
                    f"{name} (report.json metrics.{name}, SI units)") for name, figures in found.items()]
    return '<h2 id="metrics">Metrics</h2>\n' + "".join(tables)


def _figure(report: dict, path: str, value: object) -> str:
    """A metric's figure as text; singularity_handling's closest_approach, null for a robot without the
    `sigma_min_unit` measure it reads, with the singular events' own closest approach beside it."""
    if value is not None or path != "singularity_handling.closest_approach":
        return number(value)
    closest = [(e["detail"]["distance"], e) for e in report.get("singularity_events") or []
               if isinstance(e, dict) and isinstance(e.get("detail"), dict)
               and isinstance(e["detail"].get("distance"), (int, float))]
    if not closest:
        return "n/a"
    _, e = min(closest, key=lambda pair: pair[0])
    detail = e["detail"]
    gaps = detail.get("gaps_at_closest")
    value = (", ".join(f"{k} {number(v)}" for k, v in gaps.items()) if isinstance(gaps, dict) and gaps
             else f"distance {number(detail['distance'])}")
    return (f"n/a (no sigma_min_unit); closest event: {e.get('kind', '?')} at "
            f"{number(detail.get('t_closest', e.get('t_start')))} s, {value}")


def _events(report: dict) -> str:
    found = timeline.events(report)
    head = '<h2 id="events">Events</h2>\n'
    if not found:
        return head + '<p class="note">No singularity, limit, switch or warning event.</p>\n'
    end = sum(v for v in (report.get("duration"), report.get("hold")) if isinstance(v, (int, float)))
    counts: dict[str, int] = {}
    for e in found:
        counts[e["lane"]] = counts.get(e["lane"], 0) + 1
    summary = "; ".join(f"{lane}: {n}" for lane, n in counts.items())
    return (f"{head}<p>{esc(summary)}. Spans are bars, instants diamonds; hover a mark for its kind and time (a mark "
            "whose label would overlap the one before is unlabelled; the table below lists them).</p>\n"
            f"{timeline.svg(found, end)}{timeline.table(found)}")


def _video(out: Path, outputs: dict) -> str:
    video = outputs.get("video")
    if not video:
        return ""
    head = '<h2 id="video">Video</h2>\n'
    inside(out, video)
    if not (out / video).is_file():
        return f'{head}<p class="missing">Not found in this folder: {esc(video)}</p>\n'
    info = outputs.get("video_info") or {}
    dims = "".join(f' {k}="{int(info[k])}"' for k in ("width", "height") if isinstance(info.get(k), int))
    note = ", ".join(f"{k} {info[k]}" for k in ("frames", "fps", "camera", "quality") if info.get(k) is not None)
    return (f'{head}<figure><video controls preload="metadata" src="{href(video)}"{dims}>'
            f'<a href="{href(video)}">{esc(video)}</a></video>'
            f"<figcaption>{esc(video)}{esc(': ' + note if note else '')}</figcaption></figure>\n")


def _derived(report: dict) -> str:
    """An arm derived from its model: what simbench made of the file, and each servo designed for the run."""
    arm = report.get("derived_arm")
    if not isinstance(arm, dict):
        return ""
    servos = [s for s in arm.get("servos") or [] if isinstance(s, dict)]
    facts = [[key.replace("_", " "), value if isinstance(value, (int, float, str)) else json.dumps(value)]
             for key, value in arm.items() if key != "servos"]
    parts = ['<h2 id="plant">The plant (report.json derived_arm)</h2>\n', table(["", "value"], facts, None, 4)]
    if servos:
        rows = [[s.get(key) for key in ("joint", "kp", "kv", "bandwidth", "reason", "inertia")] for s in servos]
        parts.append(table(["joint", "kp", "kv", "bandwidth (rad/s)", "set by", "inertia"], rows,
                           "The servos designed for this plan (SI: N m/rad, N m s/rad, kg m^2)", 4))
    return "".join(parts)


def _plan(report: dict) -> str:
    parts = []
    plan = report.get("plan")
    if plan:
        parts.append(f"<details><summary>the planner's choices (report.json plan)</summary>"
                     f"<pre>{esc(json.dumps(plan, indent=2, ensure_ascii=False))}</pre></details>\n")
    waypoints = report.get("waypoints") or []
    if waypoints:
        rows = [[number(w.get("s")), scaled_list(w.get("X"), _MM), number(w.get("q"))] for w in waypoints]
        parts.append("<details><summary>the method's points (report.json waypoints)</summary>"
                     + table(["s", "X (mm)", "q (rad or m)"], rows, None) + "</details>\n")
    return '<h2 id="plan">Plan</h2>\n' + "".join(parts) if parts else ""


def scaled_list(values, scale: float) -> str:
    if not isinstance(values, list):
        return number(values)
    return number([v * scale if isinstance(v, (int, float)) else v for v in values])


def _facts(report: dict) -> str:
    seconds = ("timestep", "duration", "hold", "settle")
    rows = [[f"{key} (s)" if key in seconds else key, number(report[key])]
            for key in ("samples", *seconds, "record_every", "time_law") if key in report]
    for group in ("control", "versions", "wall_time"):
        if isinstance(report.get(group), dict):
            unit = " (s)" if group == "wall_time" else ""
            rows += [[path + unit, number(value)] for path, value in flatten({group: report[group]})]
    return '<h2 id="run">Run</h2>\n' + table(["", "value"], rows, None, 4) if rows else ""


def _files(out: Path, report: dict) -> str:
    outputs = report.get("outputs") or {}
    names = [v for v in outputs.values() if isinstance(v, str) and v != "index.html"]  # not the page itself
    links = [f'<a href="{href(n)}">{esc(n)}</a>' for n in names if (out / n).exists()]
    return f'<p class="note">Files: {" &middot; ".join(links)}</p>\n' if links else ""
