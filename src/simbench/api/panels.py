"""simbench's plot layout, for its own plots and for a plugin's (a robot's `plots`, say): figures made without
pyplot (no global state) at simbench's resolution, panels over one shared time axis with fixed margins, and text
drawn as written. matplotlib is imported only where a figure is made: a run without plots skips it."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from simbench.core.errors import printable

if TYPE_CHECKING:
    from matplotlib.figure import Figure

DPI = 110  # a PNG's pixels an inch
_MARGINS = (1.0, 0.15, 0.36, 0.59)  # in: left (tick labels and y label), right, top (title), bottom (x label)
_GAP = 0.22  # in: between panels that share their time axis
_COLUMN_GAP = 1.05  # in: between columns of panels (the next column's tick labels and y label)


def plot_text(text: str) -> str:
    """A name (a model's joint, say) as a figure's label or title draws it as written: control characters and line
    breaks escaped (an SVG copies the text into an XML comment, where they are not allowed, and the fonts have no
    glyph for them) and '$' escaped (two would start mathtext, and a formula matplotlib cannot parse fails the save)."""
    return printable(text).replace("$", r"\$")


def figure(width: float, height: float) -> Figure:
    """An empty figure at simbench's resolution (matplotlib imported here: a run without plots skips it).

    Args:
        width: Its width (inches).
        height: Its height (inches).

    Returns:
        The figure.
    """
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), dpi=DPI)


def time_panels(rows: int, width: float, height: float, cols: int = 1, gap: float = _GAP,
                top: float = _MARGINS[2]) -> tuple[Figure, np.ndarray]:
    """Panels over one shared time axis, laid out as simbench's own plots (fixed margins).

    Args:
        rows: Panels in a column.
        width: The figure's width (inches).
        height: The figure's height (inches).
        cols: Columns of panels.
        gap: Between rows (inches).
        top: Over the first row, for a title (inches).

    Returns:
        The figure and its matplotlib Axes (rows, cols).
    """
    left, right, _, bottom = _MARGINS
    panel = (height - top - bottom - (rows - 1) * gap) / rows
    column = (width - left - right - (cols - 1) * _COLUMN_GAP) / cols
    fig = figure(width, height)
    fig.subplots_adjust(left=left / width, right=1 - right / width, top=1 - top / height, bottom=bottom / height,
                        hspace=gap / panel, wspace=_COLUMN_GAP / column)
    return fig, fig.subplots(rows, cols, sharex=True, squeeze=False)
