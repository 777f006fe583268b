"""The pieces every page is made of: escaped text, numbers as a reader wants them, tables, figures, the resolved
configuration, and the document around them with its inline style sheet."""

from __future__ import annotations

import html
import json
import math
import os
import re
from collections.abc import Iterable, Sequence
from pathlib import Path
from urllib.parse import quote
from xml.etree import ElementTree

from PIL import Image

from simbench.core.version import __version__

_STYLE = """
:root { --ink: #1d2330; --muted: #5b6475; --rule: #d9dde5; --band: #f4f6f9; --ok: #1e7b34; --limits: #b35c00;
        --failed: #b3261e; }
* { box-sizing: border-box; }
body { margin: 0 auto; max-width: 1180px; padding: 24px 28px 64px; color: var(--ink); background: #fff;
       font: 15px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, "DejaVu Sans", sans-serif; }
h1 { font-size: 26px; margin: 0 0 4px; }
h2 { font-size: 19px; margin: 32px 0 10px; padding-bottom: 4px; border-bottom: 1px solid var(--rule); }
h3 { font-size: 16px; margin: 18px 0 8px; }
p.sub { margin: 0 0 10px; color: var(--muted); }
.status { display: inline-block; padding: 2px 12px; border-radius: 12px; color: #fff; font-weight: 600;
          letter-spacing: 0.02em; }
.status.ok { background: var(--ok); } .status.limits { background: var(--limits); }
.status.failed { background: var(--failed); } .status.other { background: var(--muted); }
.cards { display: grid; grid-template-columns: repeat(auto-fill, minmax(190px, 1fr)); gap: 10px; margin: 12px 0; }
.card { border: 1px solid var(--rule); border-radius: 8px; padding: 10px 12px; background: var(--band); }
.card .label { color: var(--muted); font-size: 13px; }
.card .value { font-size: 21px; font-weight: 600; font-variant-numeric: tabular-nums; }
.card .note { color: var(--muted); font-size: 12px; }
.scroll { overflow-x: auto; margin: 8px 0 14px; }
table { border-collapse: collapse; font-size: 13.5px; }
caption { caption-side: top; text-align: left; font-weight: 600; padding: 4px 0; }
th, td { border: 1px solid var(--rule); padding: 3px 8px; vertical-align: top; text-align: left; }
th { background: var(--band); font-weight: 600; }
td.n { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
td.key { font-family: ui-monospace, "DejaVu Sans Mono", monospace; white-space: nowrap; }
ul.violations li { margin: 4px 0; }
.kind { font-family: ui-monospace, "DejaVu Sans Mono", monospace; font-weight: 600; }
.figures { display: grid; grid-template-columns: repeat(auto-fill, minmax(520px, 1fr)); gap: 16px; }
figure.wide { grid-column: 1 / -1; }
figure { margin: 0; border: 1px solid var(--rule); border-radius: 8px; padding: 8px; background: #fff; }
figure img, figure video { display: block; max-width: 100%; height: auto; margin: 0 auto; }
figcaption { color: var(--muted); font-size: 13px; text-align: center; margin-top: 4px; }
svg.timeline { width: 100%; max-width: 1120px; height: auto; display: block; }
details { margin: 8px 0; } summary { cursor: pointer; color: var(--muted); }
pre { background: var(--band); border: 1px solid var(--rule); padding: 10px; overflow-x: auto; font-size: 12.5px; }
.note, .missing { color: var(--muted); font-size: 13px; }
.missing { color: var(--failed); }
footer { margin-top: 40px; color: var(--muted); font-size: 12px; }
"""


def esc(value: object) -> str:
    """Text made safe inside an element or a quoted attribute."""
    return html.escape(str(value), quote=True)


def href(path: str | os.PathLike) -> str:
    """A relative path as an escaped URL for src= or href= (spaces, '#', '?' and '%' quoted)."""
    return esc(quote(Path(path).as_posix(), safe="/"))


def number(value: object, digits: int = 4) -> str:
    """A value as text: floats to `digits` significant digits, None (a NaN in the report) as 'n/a'."""
    if value is None:
        return "n/a"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:.{digits}g}" if math.isfinite(value) else str(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(number(v, digits) for v in value) + "]"
    return str(value)


def scaled(value: object, scale: float, unit: str, digits: int = 4) -> str:
    """A number in SI shown in a reader's unit (mm for m: scale 1e3, deg for rad: scale 180/pi)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return f"{number(float(value) * scale, digits)} {unit}"
    return number(value)


_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


def cell(value: object, digits: int | None = 6) -> str:
    """One <td>: numbers right-aligned, floats to `digits` significant digits with the value as given as tooltip."""
    text = value.strip() if isinstance(value, str) else None
    if text is not None and _NUMBER.fullmatch(text):
        if digits is None or not any(c in text for c in ".eE"):
            return f'<td class="n">{esc(text)}</td>'
        value = float(text)
    if isinstance(value, float) and digits is not None:
        shown = number(value, digits)
        given = text if text is not None else repr(value)
        title = f' title="{esc(given)}"' if shown != given else ""
        return f'<td class="n"{title}>{esc(shown)}</td>'
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return f'<td class="n">{esc(repr(value))}</td>'
    return "<td></td>" if value is None else f"<td>{esc(number(value))}</td>"


def table(header: Sequence[object], rows: Iterable[Sequence[object]], caption: str | None = None,
          digits: int | None = 6) -> str:
    """A table in a horizontally scrolling box (a wide sweep table does not widen the page)."""
    head = "".join(f"<th>{esc(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(cell(v, digits) for v in row) + "</tr>\n" for row in rows)
    cap = f"<caption>{esc(caption)}</caption>" if caption else ""
    return f'<div class="scroll"><table>{cap}<thead><tr>{head}</tr></thead>\n<tbody>\n{body}</tbody></table></div>\n'


def cards(items: Iterable[tuple[str, str, str]]) -> str:
    """Headline figures: (label, value, note) each in a box."""
    boxes = "".join(f'<div class="card"><div class="label">{esc(label)}</div><div class="value">{esc(value)}</div>'
                    + (f'<div class="note">{esc(note)}</div>' if note else "") + "</div>\n"
                    for label, value, note in items)
    return f'<div class="cards">\n{boxes}</div>\n' if boxes else ""


def png_size(path: Path) -> tuple[int, int] | None:
    """A picture's width and height from its header alone, or None if Pillow cannot read it."""
    try:
        with Image.open(path) as picture:
            return picture.size
    except (OSError, ValueError, Image.DecompressionBombError):
        return None


def svg_size(path: Path) -> tuple[float, float] | None:
    """An SVG's width and height in its own units, from its root's viewBox (matplotlib writes one), or None."""
    try:
        _, root = next(ElementTree.iterparse(path, events=("start",)))
        box = [float(v) for v in root.get("viewBox", "").replace(",", " ").split()]
    except (OSError, StopIteration, ElementTree.ParseError, ValueError):
        return None
    return (box[2], box[3]) if len(box) == 4 else None


def inside(out: Path, rel: str | os.PathLike) -> None:
    """Refuse a path that is not relative to `out` and inside it: the page must move with its folder."""
    if Path(rel).is_absolute() or not (Path(out) / rel).resolve().is_relative_to(Path(out).resolve()):
        raise ValueError(f"{rel}: expected a path relative to {out} and inside it, so that the page moves with "
                         "its folder")


def figure_grid(out: Path, items: Iterable[str | os.PathLike]) -> str:
    """Images by their paths relative to `out`, each a <figure> captioned by its stem (a PDF as a link); a missing
    one is named rather than shown broken."""
    shown, missing = [], []
    for rel in items:
        caption = Path(rel).stem.replace("_", " ")
        inside(out, rel)
        if not (Path(out) / rel).is_file():
            missing.append(str(rel))
            continue
        if Path(rel).suffix == ".pdf":
            shown.append(f'<figure><a href="{href(rel)}">{esc(caption)} (PDF)</a>'
                         f"<figcaption>{esc(caption)}</figcaption></figure>\n")
            continue
        size = png_size(Path(out) / rel)
        dims = f' width="{size[0]}" height="{size[1]}"' if size else ""
        shape = size or svg_size(Path(out) / rel)
        wide = ' class="wide"' if shape and shape[0] > 1.6 * shape[1] else ""  # a row of panels: the page's width
        shown.append(f'<figure{wide}><img src="{href(rel)}" alt="{esc(caption)}"{dims}>'
                     f"<figcaption>{esc(caption)}</figcaption></figure>\n")
    body = f'<div class="figures">\n{"".join(shown)}</div>\n' if shown else ""
    if missing:
        body += f'<p class="missing">Not found in this folder: {esc(", ".join(missing))}</p>\n'
    return body


def flatten(value: object, prefix: str = "") -> list[tuple[str, object]]:
    """A nested document as (dotted path, value) rows; lists of scalars stay one value."""
    if isinstance(value, dict):
        if not value:
            return [(prefix, {})] if prefix else []
        rows: list[tuple[str, object]] = []
        for key, item in value.items():
            rows += flatten(item, f"{prefix}.{key}" if prefix else str(key))
        return rows
    if isinstance(value, list) and any(isinstance(v, (dict, list)) for v in value):
        rows = []
        for i, item in enumerate(value):
            rows += flatten(item, f"{prefix}[{i}]")
        return rows or [(prefix, [])]
    return [(prefix, value)]


def config_section(config: dict | None, note: str = "") -> str:
    """The resolved configuration: a table of its fields, then the whole document as JSON."""
    if config is None:
        return ""
    rows = "".join(f'<tr><td class="key">{esc(key)}</td><td>{esc(number(value, 6))}</td></tr>\n'
                   for key, value in flatten(config))
    text = json.dumps(config, indent=2, ensure_ascii=False, default=str)
    return (f'<h2 id="config">Configuration</h2>\n{paragraphs(note)}'
            f'<div class="scroll"><table><thead><tr><th>field</th><th>value</th></tr></thead>\n<tbody>\n{rows}'
            f"</tbody></table></div>\n<details><summary>as JSON</summary><pre>{esc(text)}</pre></details>\n")


def paragraphs(text: str | None, css: str = "") -> str:
    """Plain text as paragraphs (a blank line between them), escaped."""
    if not text:
        return ""
    cls = f' class="{css}"' if css else ""
    return "".join(f"<p{cls}>{esc(p.strip())}</p>\n" for p in str(text).split("\n\n") if p.strip())


def document(title: str, body: str) -> str:
    """The whole page: no script, no request beyond its folder (the empty icon stops a favicon request); ASCII
    with character references, so that any encoding reads it."""
    page = ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
            f'<link rel="icon" href="data:,">\n<title>{esc(title)}</title>\n<style>{_STYLE}</style>\n</head>\n'
            f"<body>\n{body}<footer>Written by simbench {esc(__version__)}.</footer>\n</body>\n</html>\n")
    return page.encode("ascii", "xmlcharrefreplace").decode("ascii")
