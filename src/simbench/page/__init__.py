"""A page per result: a self-contained `index.html` beside a run's, a reproduction's, a comparison's or a sweep's
outputs, to read in any browser with no server and no network.

    html = run_page(out, report)                       # a run folder and its report.json document
    html = table_page(out, "Table 2", intro, [("case 1", "table2_case1.csv")], ["plots/q.png"], config)
    write_page(out, html)                              # out/index.html, in one step

Plain HTML with inline CSS and SVG (the run's timeline), no JavaScript. Images and the video are referenced by
their paths relative to the folder, so the folder can be moved or archived whole; every text taken from a
report or a table is escaped, so a description holding markup shows as text.
"""

from __future__ import annotations

from pathlib import Path

from simbench.atomic import write_text
from simbench.page.run import run_page
from simbench.page.tables import table_page

__all__ = ["PAGE", "run_page", "table_page", "write_page"]

PAGE = "index.html"


def write_page(folder: Path, html: str) -> Path:
    """Write `html` to folder/index.html in one step (simbench.atomic); returns its path."""
    path = Path(folder) / PAGE
    write_text(path, html)
    return path
