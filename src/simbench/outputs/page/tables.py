"""The page of a result made of tables and figures: a paper's reproduction, a comparison of methods, a sweep."""

from __future__ import annotations

import csv
import os
from collections.abc import Sequence
from pathlib import Path

from simbench.outputs.csv_cells import restored
from simbench.outputs.page.html import config_section, document, esc, figure_grid, href, paragraphs, table

MAX_ROWS = 500  # rows shown of one table; the rest are in its file


def table_page(out: Path, title: str, intro: str, tables: Sequence[tuple[str, Path]],
               figures: Sequence[str | os.PathLike], config: dict | None = None, *, digits: int | None = 6) -> str:
    """A page of `title`, `intro`, `tables` ((caption, a CSV file's path relative to `out`), each linked), `figures`
    (paths relative to `out`) and `config`, as HTML text."""
    out = Path(out)
    body = [f"<h1>{esc(title)}</h1>\n", paragraphs(intro)]
    if tables:
        body.append('<h2 id="tables">Tables</h2>\n')
        body += [_table(out, caption, data, digits) for caption, data in tables]
    if figures:
        body.append(f'<h2 id="figures">Figures</h2>\n{figure_grid(out, figures)}')
    body.append(config_section(config))
    return document(f"simbench: {title}", "".join(body))


def _table(out: Path, caption: str, data: Path, digits: int | None) -> str:
    head = f'<h3>{esc(caption)} <a href="{href(data)}">{esc(data.as_posix())}</a></h3>\n'
    with open(out / data, encoding="utf-8", newline="") as f:  # as the csv module reads: a quoted line break kept
        rows = [list(map(restored, row)) for row in csv.reader(f)]
    if not rows or not rows[0]:
        return f'{head}<p class="note">(empty)</p>\n'
    more = (f'<p class="note">The first {MAX_ROWS} of {len(rows) - 1} rows; all are in the file above.</p>\n'
            if len(rows) > MAX_ROWS + 1 else "")
    return f"{head}{table(rows[0], rows[1:MAX_ROWS + 1], None, digits)}{more}"
