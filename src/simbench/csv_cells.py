"""Text cells of a CSV file made safe to open in a spreadsheet, and read back as written; its rows.

A spreadsheet takes a cell that begins with '=', '+', '-' or '@' (or a tab or carriage return before one) for a
formula: a sweep's parameter or error text could run one (=HYPERLINK, =cmd|...). As OWASP's advice on CSV
injection says, such a text cell is written with a single quote before it, which a spreadsheet shows as text;
numbers are written as numbers (-0.5 stays -0.5: only text is quoted). A text cell that itself begins with a quote
gets one more, so that `restored` undoes `safe` exactly: it removes the quote before any of those characters (a
CSV file written otherwise reads the same unless a cell of it begins so).
"""

from __future__ import annotations

from collections.abc import Iterable

FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")
QUOTE = "'"


def safe(text: str) -> str:
    """`text` as a CSV text cell no spreadsheet runs: quoted where it could start a formula (or starts with a
    quote)."""
    return QUOTE + text if text.startswith((*FORMULA_STARTS, QUOTE)) else text


def restored(cell: str) -> str:
    """A cell of a CSV file written with `safe` text cells, as the text (or number) it holds."""
    return cell[1:] if cell.startswith(QUOTE) and cell[1:].startswith((*FORMULA_STARTS, QUOTE)) else cell


def row(cells: Iterable[str]) -> str:
    """One line of CSV (RFC 4180, ending in a line feed): a cell holding a comma, a double quote or a line break,
    a carriage return included, within double quotes (Python's csv.writer leaves a lone carriage return unquoted
    with a line feed as the line's end, and a reader then splits the row there)."""
    return ",".join('"' + cell.replace('"', '""') + '"' if any(c in cell for c in ',"\r\n') else cell
                    for cell in cells) + "\n"
