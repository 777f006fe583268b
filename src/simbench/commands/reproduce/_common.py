"""What the four reproductions share: the classes of a difference, a paper's part of the summary, tables written
as CSV and Markdown, figures of one size, and the paper's differences and summary page."""

from __future__ import annotations

import csv
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from matplotlib.figure import Figure

from simbench.outputs.page import table_page, write_page
from simbench.outputs.plots import plain_ticks

TYPO = "typo in the paper"
ERROR = "error in the paper"
OURS = "ours"
CLASSES = (TYPO, ERROR, OURS)

FIGSIZE = (10.0, 6.0)  # inches
DPI = 100  # so every figure is 1000 x 600 pixels
PIXELS = (int(FIGSIZE[0] * DPI), int(FIGSIZE[1] * DPI))


@dataclass(frozen=True)
class Difference:
    """One difference between the paper and simbench: class, where, printed value, simbench's, the numbers."""

    kind: str  # one of CLASSES
    where: str
    printed: str
    simbench: str
    shown: str

    def __post_init__(self):
        if self.kind not in CLASSES:
            raise ValueError(f"a difference's class is one of {CLASSES}, not {self.kind!r}")


@dataclass(frozen=True)
class PaperSummary:
    """One paper's reproduction: printed values (or claims) compared and reproduced, its differences, a few
    headline lines, the files written."""

    paper: str
    title: str
    compared: int
    reproduced: int
    differences: tuple[Difference, ...]
    headline: tuple[str, ...] = ()
    files: tuple[str, ...] = ()
    seconds: float = 0.0
    facts: dict = field(default_factory=dict)  # numbers a caller may want (rows reproduced, KCI means, ...)

    def count(self, kind: str) -> int:
        """How many differences of this class."""
        return sum(d.kind == kind for d in self.differences)


def fmt(value: float, digits: int = 4) -> str:
    """A number as the tables print it (NaN as 'none', never '-0.000')."""
    if value != value:
        return "none"
    text = f"{value:.{digits}f}"
    return text[1:] if text.startswith("-") and float(text) == 0 else text


def _md_cell(value) -> str:
    return str(value).replace("|", "\\|").replace("\n", " ")


def markdown_table(header: Sequence[str], rows: Iterable[Sequence]) -> str:
    """A GitHub Markdown table."""
    lines = ["| " + " | ".join(_md_cell(h) for h in header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_md_cell(c) for c in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def write_table(folder: Path, name: str, header: Sequence[str], rows: Sequence[Sequence], title: str,
                notes: Sequence[str] = ()) -> list[str]:
    """`name`.csv (header and rows) and `name`.md (the title, the table, the notes) in `folder`; their names."""
    with open(folder / f"{name}.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows(rows)
    text = f"# {title}\n\n" + markdown_table(header, rows)
    if notes:
        text += "\n" + "\n".join(f"- {n}" for n in notes) + "\n"
    (folder / f"{name}.md").write_text(text)
    return [f"{name}.csv", f"{name}.md"]


DIFFERENCES_HEADER = ("class", "where", "printed", "simbench", "shown by")
CHECKS_HEADER = ("where", "the paper", "status", "simbench")


def figure(nrows: int = 1, ncols: int = 1, **kwargs):
    """A figure of the common size and its axes (as pyplot.subplots gives them, without pyplot's global state)."""
    fig = Figure(figsize=FIGSIZE, dpi=DPI)
    return fig, fig.subplots(nrows, ncols, **kwargs)


def save(fig: Figure, path: Path) -> str:
    """Save a figure at the common size (no tight bounding box, so every PNG has PIXELS)."""
    plain_ticks(fig)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    return path.name


def finish(folder: Path, part: PaperSummary, files: Sequence[str], title: str,
           notes: Sequence[str] = ()) -> PaperSummary:
    """Write differences.csv and .md (under `title`) and the summary page (summary.md and index.html: the paper's
    headline, counts, differences, notes, tables and figures); `part` with every file it wrote."""
    differences = [[d.kind, d.where, d.printed, d.simbench, d.shown] for d in part.differences]
    files = [*files, *write_table(folder, "differences", DIFFERENCES_HEADER, differences, title)]
    part = replace(part, files=tuple(files) + ("summary.md", "index.html"))
    counts = ", ".join(f"{k} {part.count(k)}" for k in CLASSES)
    found = f"{part.reproduced} of {part.compared} printed values and claims reproduced; differences: {counts}."
    text = [f"# Paper {part.paper}: {part.title}", "", found, ""]
    text += [f"- {line}" for line in part.headline]
    text += ["", "## Differences", "", markdown_table(DIFFERENCES_HEADER, differences)]
    if notes:
        text += ["## Notes", ""] + [f"- {n}" for n in notes] + [""]
    text += ["## Files", ""] + [f"- `{name}`" for name in sorted(part.files)] + [""]
    (folder / "summary.md").write_text("\n".join(text), encoding="utf-8")
    write_page(folder, table_page(
        folder, f"Paper {part.paper}: {part.title}",
        f"{found}\n\n" + "\n".join(part.headline) + ("\n\n" + "\n".join(notes) if notes else ""),
        [(name, Path(name)) for name in sorted(part.files) if name.endswith(".csv")],
        [name for name in sorted(part.files) if name.endswith(".png")], digits=None))
    return part
