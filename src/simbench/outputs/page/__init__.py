"""A self-contained `index.html` beside a run's, a reproduction's, a comparison's or a sweep's outputs: plain
HTML with inline CSS and SVG, no JavaScript, no network; files referenced by relative paths so that the folder
moves whole; all text escaped."""

from __future__ import annotations

from pathlib import Path

from simbench.core.atomic import write_text
from simbench.outputs.page.run import run_page
from simbench.outputs.page.tables import table_page

__all__ = ["PAGE", "run_page", "table_page", "write_page"]

PAGE = "index.html"


def write_page(folder: Path, html: str) -> Path:
    """Write `html` to folder/index.html in one step (simbench.core.atomic); returns its path."""
    path = Path(folder) / PAGE
    write_text(path, html)
    return path
