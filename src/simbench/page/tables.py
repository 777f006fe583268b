"""The page of a result made of tables and figures: a paper's reproduction, a comparison of methods, a sweep."""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Union

from simbench.csv_cells import restored
from simbench.page.html import cards, config_section, document, esc, figure_grid, href, number, paragraphs, table

Rows = Union[str, os.PathLike, Sequence[Sequence[object]], Sequence[Mapping[str, object]]]
Figure = Union[str, os.PathLike, tuple[Union[str, os.PathLike], str]]

MAX_ROWS = 500  # rows shown of one table; the rest are in its file


def table_page(out: Path, title: str, intro: str, tables: Sequence[tuple[str, Rows]], figures: Sequence[Figure],
               config: dict | None = None, *, headline: Mapping[str, object] | Iterable[tuple] | None = None,
               digits: int | None = 6, max_rows: int = MAX_ROWS) -> str:
    """A page of `title`, `intro`, `headline` figures ({label: value} or (label, value[, note])), `tables`,
    `figures` (paths relative to `out`, or (path, caption)) and `config`, as HTML text. A table is (caption,
    data): CSV text, a CSV file (a Path; linked if inside `out`), rows with a header row first, or mappings."""
    out = Path(out)
    body = [f"<h1>{esc(title)}</h1>\n", paragraphs(intro)]
    if headline:
        items = headline.items() if isinstance(headline, Mapping) else headline
        body.append(cards((str(i[0]), number(i[1]), str(i[2]) if len(i) > 2 else "") for i in map(tuple, items)))
    if tables:
        body.append('<h2 id="tables">Tables</h2>\n')
        body += [_table(out, caption, data, digits, max_rows) for caption, data in tables]
    if figures:
        body.append(f'<h2 id="figures">Figures</h2>\n{figure_grid(out, figures)}')
    body.append(config_section(config))
    return document(f"simbench: {title}", "".join(body))


def _table(out: Path, caption: str, data: Rows, digits: int | None, max_rows: int) -> str:
    link = ""
    if isinstance(data, os.PathLike):
        path = Path(data) if Path(data).is_absolute() else out / data
        try:
            rel = path.resolve().relative_to(out.resolve())
            link = f' <a href="{href(rel)}">{esc(rel.as_posix())}</a>'
        except ValueError:
            pass
        with open(path, encoding="utf-8", newline="") as f:  # as the csv module reads: a quoted line break kept
            data = f.read()
    header, rows = _rows(data)  # type: ignore[arg-type]  # a PathLike was read above
    if not header:
        return f'<h3>{esc(caption)}{link}</h3>\n<p class="note">(empty)</p>\n'
    shown = table(header, rows[:max_rows], None, digits)
    more = (f'<p class="note">The first {max_rows} of {len(rows)} rows{"; all are in the file above" if link else ""}.'
            "</p>\n" if len(rows) > max_rows else "")
    return f"<h3>{esc(caption)}{link}</h3>\n{shown}{more}"


def _rows(data: str | Sequence[Sequence[object]] | Sequence[Mapping[str, object]]) \
        -> tuple[list[object], list[list[object]]]:
    """(header, rows) of CSV text, rows with a header row first, or mappings (the union of their keys)."""
    items: list = ([list(map(restored, row)) for row in csv.reader(io.StringIO(data))] if isinstance(data, str)
                   else list(data))
    if not items:
        return [], []
    if all(isinstance(r, Mapping) for r in items):
        keys = list(dict.fromkeys(k for r in items for k in r))
        return keys, [[r.get(k) for k in keys] for r in items]
    return list(items[0]), [list(r) for r in items[1:]]
