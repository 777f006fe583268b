"""CSV rows whose text cells are safe to open in a spreadsheet and read back as written: a text cell that could
start a formula (=HYPERLINK, say) gets a single quote before it, as OWASP advises, and so does one that starts
with a quote, so that `restored` undoes `safe` exactly. Numbers are written as numbers.
"""

from __future__ import annotations

from collections.abc import Iterable

FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")
QUOTE = "'"


def safe(text: str) -> str:
    """`text` as a CSV text cell no spreadsheet runs."""
    return QUOTE + text if text.startswith((*FORMULA_STARTS, QUOTE)) else text


def restored(cell: str) -> str:
    """A cell of a CSV file written with `safe` text cells, as the text (or number) it holds."""
    return cell[1:] if cell.startswith(QUOTE) and cell[1:].startswith((*FORMULA_STARTS, QUOTE)) else cell


def row(cells: Iterable[str]) -> str:
    """One line of CSV (RFC 4180), quoting a lone carriage return too (csv.writer does not: readers split there)."""
    return ",".join('"' + cell.replace('"', '""') + '"' if any(c in cell for c in ',"\r\n') else cell
                    for cell in cells) + "\n"
