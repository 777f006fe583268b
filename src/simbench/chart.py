"""A light raster renderer for simbench's plots: panels of lines over one time axis, and a 3-D trace in a box.

Why not matplotlib's own drawing: a run's five PNGs took 0.7 s through matplotlib's artists, most of it building
ticks and laying out and rendering text, against the tens of milliseconds of the physics (issue 14). This module
draws the same figures with Pillow, on a canvas twice the size reduced at the end (so lines and text come out
smoothed), and takes from matplotlib all that decides how a plot reads: the limits (the data's extent with 5 %
margins, the locator's `nonsingular` for a flat series), the tick positions (`MaxNLocator` with AutoLocator's
steps and as many bins as matplotlib gives an axis of that length), the tick labels and their offset
(`ScalarFormatter`), the line styles' dash patterns, the colours and the DejaVu Sans font. The 3-D box is seen
orthographically (matplotlib's is in perspective).

A `Panel` answers the matplotlib `Axes` calls simbench's plots make (`plot`, `axhline`, `axvline`, `axvspan`,
`annotate`, `set_xlabel`, `set_ylabel`, `set_title`, `set_ylim`, `set_yscale`, `grid`, `legend`), with the same
arguments (a log y axis with matplotlib's `LogLocator` ticks, major and minor, and `LogFormatterSciNotation`
labels, written as matplotlib's mathtext writes them: 10 with a raised exponent), so
that a robot's own plots (`simbench.plots.time_panels`) read as matplotlib code does; a `Box3D` draws a 3-D
trace (`plot`, `scatter`) seen as matplotlib's default 3-D view (elevation 30 deg, azimuth -60 deg). Calls are
recorded and drawn when the figure is saved, once the limits are known.
"""

from __future__ import annotations

import functools
import math
import re
import struct
import zlib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

DPI = 110
_SCALE = 2  # the canvas is drawn at twice the size and reduced: smooth lines and text
_PT = DPI / 72 * _SCALE  # canvas pixels a point
_MARGIN = 0.05  # of the data's extent, either side (matplotlib's axes.xmargin and ymargin)
_STEPS = [1, 2, 2.5, 5, 10]  # matplotlib's AutoLocator
_TICK_SIZE, _TICK_PAD, _LABEL_PT, _TITLE_PT = 3.5, 3.5, 10.0, 12.0  # pt (matplotlib's defaults)
_MINOR_TICK = 2.0  # pt: a minor tick's length (matplotlib's ytick.minor.size)
_SUPERSCRIPT = (0.7, 0.45)  # a mathtext exponent's size and the rise of its baseline, in the label's font size
_FRAME_PT = 0.8  # spines and ticks, pt
_GRID = "#b0b0b0"
_DASHES = {"--": (3.7, 1.6), ":": (1.0, 1.65), "-.": (6.4, 1.6, 1.0, 1.6)}  # in line widths, as matplotlib's


@functools.cache
def color_cycle() -> list[str]:
    """matplotlib's default colour cycle. matplotlib is imported when a figure is first drawn, not with this
    module: a run without plots (a sweep's, simbench.evaluate) does not pay its 17 MB and 0.14 s."""
    import matplotlib

    return [c["color"] for c in matplotlib.rcParams["axes.prop_cycle"]]


@functools.cache
def _font(size_pt: float) -> ImageFont.FreeTypeFont:
    """DejaVu Sans (matplotlib's default font, from its own data) at `size_pt` on the canvas."""
    import matplotlib

    return ImageFont.truetype(str(Path(matplotlib.get_data_path()) / "fonts" / "ttf" / "DejaVuSans.ttf"),
                              max(1, round(size_pt * _PT)))


@functools.cache
def _rgb(color, alpha: float = 1.0) -> tuple[int, int, int]:
    """An opaque colour: `color` (any matplotlib colour) at `alpha` over white."""
    from matplotlib.colors import to_rgb

    r, g, b = (round(255 * (alpha * c + 1.0 - alpha)) for c in to_rgb(color))
    return r, g, b


def _rgba(color, alpha: float) -> tuple[int, int, int, int]:
    return (*_rgb(color), round(255 * alpha))


def _width(lw: float) -> int:
    """A line width in pt as canvas pixels (at least one)."""
    return max(1, round(lw * _PT))


def _style(fmt: str | None, ls: str | None) -> str:
    """The line style of a matplotlib format string ('--', 'k:', '-.', '-') or ls argument."""
    for style in ("--", "-.", ":", "-"):
        if style in (ls or fmt or "-"):
            return style
    return "-"


def _runs(points: np.ndarray) -> list[np.ndarray]:
    """The stretches of a polyline (n, 2) between its gaps (non-finite vertices), each of two vertices or more
    (a lone vertex drawn as a dot's worth of line)."""
    finite = np.isfinite(points).all(axis=1)
    if finite.all():
        return [points]
    edges = np.flatnonzero(np.diff(np.concatenate([[0], finite.astype(np.int8), [0]])))
    return [points[a:b] if b - a > 1 else np.repeat(points[a:b], 2, axis=0) for a, b in zip(edges[::2], edges[1::2])]


def _dashes(points: np.ndarray, pattern: tuple[float, ...]) -> list[np.ndarray]:
    """The pieces a dashed polyline (n, 2, canvas pixels) shows: `pattern` alternates on and off lengths in
    pixels, restarted at the polyline's start as matplotlib does."""
    along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])
    period = sum(pattern)
    if along[-1] <= 0 or period <= 0:
        return [points]
    starts = np.cumsum([0.0, *pattern[:-1]])
    cycles = np.arange(0.0, along[-1], period)
    on = (cycles[:, None] + starts[None, ::2]).ravel()
    off = np.minimum(on + np.maximum(np.asarray(pattern[::2] * len(cycles)) - 1.0, 0.0), along[-1])  # less the
    # pixel Pillow adds by drawing both ends
    keep = on < along[-1]
    on, off = on[keep], off[keep]
    at = np.sort(np.concatenate([along, on, off]))  # every vertex and every dash's ends, along the line
    dash = np.searchsorted(on, at, side="right") - 1  # the last dash begun at each
    shown = (dash >= 0) & (at <= off[np.maximum(dash, 0)])
    at, dash = at[shown], dash[shown]
    xy = np.column_stack([np.interp(at, along, points[:, 0]), np.interp(at, along, points[:, 1])])
    return np.split(xy, np.flatnonzero(np.diff(dash)) + 1)


def _distinct(points: np.ndarray) -> np.ndarray:
    """A polyline's vertices less those in the same canvas pixel as the one before (a long series drawn at the
    picture's resolution: no change a pixel can show, at half an output pixel)."""
    if len(points) < 3:
        return points
    cell = np.round(points)
    moved = np.concatenate([[True], (cell[1:] != cell[:-1]).any(axis=1)])
    moved[-1] = True
    return points[moved]


def _polyline(draw: ImageDraw.ImageDraw, points: np.ndarray, color, lw: float, style: str) -> None:
    """A polyline (n, 2, canvas pixels) in a matplotlib line style; gaps (NaN) left blank."""
    width, fill = _width(lw), _rgb(color)
    for run in _runs(points):
        run = _distinct(run)
        pieces = _dashes(run, tuple(lw * _PT * d for d in _DASHES[style])) if style in _DASHES else [run]
        for piece in pieces:
            draw.line(piece.ravel().tolist(), fill=fill, width=width, joint="curve" if width > 2 else None)


def _text(canvas: Image.Image, xy: tuple[float, float], text: str, size_pt: float, anchor: str,
          color="black", rotation: int = 0) -> None:
    """Text at canvas point xy, placed by Pillow's two-letter `anchor` (l/m/r, a/m/s/d/t/b); rotated by 90 or 270
    degrees, anchored by the rotated text's box ('lt': its top left, 'mm': its middle, ...)."""
    if not text:
        return
    font, fill = _font(size_pt), _rgb(color)
    if rotation % 360 == 0:
        ImageDraw.Draw(canvas).text(xy, text, font=font, fill=fill, anchor=anchor)
        return
    left, top, right, bottom = (int(v) for v in font.getbbox(text, anchor="ls"))
    mask = Image.new("L", (right - left, bottom - top))
    ImageDraw.Draw(mask).text((-left, -top), text, font=font, fill=255, anchor="ls")
    mask = mask.rotate(rotation, expand=True)
    w, h = mask.size
    x = xy[0] - {"l": 0, "m": w / 2, "r": w}[anchor[0]]
    y = xy[1] - {"t": 0, "m": h / 2, "b": h}[anchor[1]]
    canvas.paste(fill, (round(x), round(y)), mask)


def _tick_text(canvas: Image.Image, xy: tuple[float, float], label: str, size_pt: float) -> None:
    """A y tick label right of xy's x, its middle at xy's y: plain text, or matplotlib's mathtext of a log axis'
    label ('$\\mathdefault{2\\times10^{-3}}$') as "2×10" with the exponent raised and smaller."""
    found = _MATH.fullmatch(label)
    if found is None:
        _text(canvas, xy, label, size_pt, "rm")
        return
    base = found["mantissa"].replace("\\times", "\u00d7") + "10"
    exponent = found["exponent"].replace("-", "\u2212")
    small = size_pt * _SUPERSCRIPT[0]
    x = xy[0] - _font(small).getlength(exponent)
    baseline = xy[1] + 0.35 * size_pt * _PT  # the digits' middle at xy's y
    _text(canvas, (x, baseline), base, size_pt, "rs")
    _text(canvas, (x, baseline - _SUPERSCRIPT[1] * size_pt * _PT), exponent, small, "ls")


_MATH = re.compile(r"\$\\mathdefault\{(?P<mantissa>(?:[0-9.]+\\times)?)10\^\{(?P<exponent>-?[0-9]+)\}\}\$")


def _extent(arrays: list[np.ndarray]) -> tuple[float, float] | None:
    """The least and greatest finite value in these arrays (NaN and infinite values are not drawn, as in
    matplotlib), or None if there is none."""
    finite = [a[np.isfinite(a)] for a in arrays]
    finite = [a for a in finite if a.size]
    if not finite:
        return None
    return float(min(a.min() for a in finite)), float(max(a.max() for a in finite))


def _view(lo: float, hi: float) -> tuple[float, float]:
    """Axis limits for data spanning [lo, hi], as matplotlib's autoscale makes them."""
    from matplotlib.ticker import MaxNLocator

    lo, hi = MaxNLocator().nonsingular(lo, hi)
    pad = _MARGIN * (hi - lo)
    return lo - pad, hi + pad


def _view_log(lo: float, hi: float) -> tuple[float, float]:
    """Log-axis limits for positive data spanning [lo, hi], as matplotlib's autoscale makes them: a flat series
    widened to the powers of ten either side (LogLocator.nonsingular), then margins of 5 % of the decades."""
    if lo == hi:
        lo, hi = _decade(lo, -1), _decade(hi, 1)
    a, b = np.log10(lo), np.log10(hi)
    pad = _MARGIN * (b - a)
    return float(10.0 ** (a - pad)), float(10.0 ** (b + pad))


def _decade(x: float, direction: int) -> float:
    """The nearest power of ten below (direction -1) or above (+1) x > 0, x itself excluded."""
    power = 10.0 ** (math.floor(math.log10(x)) if direction < 0 else math.ceil(math.log10(x)))
    return power * 10.0 ** direction if power == x else power


def log_ticks(lo: float, hi: float, length_pt: float, per_label_pt: float
              ) -> tuple[np.ndarray, list[str], np.ndarray, list[str]]:
    """Major and minor tick positions within [lo, hi] of a log axis `length_pt` long and their labels ('' for a
    minor tick left unlabelled), as matplotlib's log scale makes them: `LogLocator` (at most one tick a
    `per_label_pt`, 2 to 9) for both, minor ticks at a major one's place dropped, `LogFormatterSciNotation`
    labelling majors and, on an axis of few decades, some minors."""
    from matplotlib.ticker import LogFormatterSciNotation, LogLocator

    count = int(np.clip(int(length_pt // per_label_pt), 2, 9))
    major = LogLocator(numticks=count).tick_values(lo, hi)
    minor = LogLocator(subs="auto", numticks=count).tick_values(lo, hi)
    span = np.log10(hi) - np.log10(lo)
    if major.size and minor.size:
        minor = minor[~np.isclose(np.log10(minor)[:, None], np.log10(major)[None, :], atol=1e-5 * span,
                                  rtol=0).any(axis=1)]
    inside = [locs[(locs >= lo * (1 - 1e-10)) & (locs <= hi * (1 + 1e-10))] for locs in (major, minor)]
    labels = []
    for locs, only_base in zip(inside, (True, False)):
        formatter = LogFormatterSciNotation(labelOnlyBase=only_base)
        formatter.create_dummy_axis()
        formatter.axis.set_view_interval(lo, hi)
        labels.append(formatter.format_ticks(list(locs)))
    return inside[0], labels[0], inside[1], labels[1]


def ticks(lo: float, hi: float, length_pt: float, per_label_pt: float) -> tuple[np.ndarray, list[str], str]:
    """Tick positions within [lo, hi], their labels and the axis' offset text, as matplotlib's AutoLocator and
    ScalarFormatter make them for an axis `length_pt` long (bins: one a `per_label_pt`, at most 9)."""
    from matplotlib.ticker import MaxNLocator, ScalarFormatter

    bins = max(min(int(length_pt // per_label_pt), 9), 1)
    tol = 1e-10 * (hi - lo)
    locs = np.asarray(MaxNLocator(nbins=bins, steps=_STEPS).tick_values(lo, hi))
    locs = locs[(locs >= lo - tol) & (locs <= hi + tol)]
    formatter = ScalarFormatter()
    formatter.create_dummy_axis()
    formatter.axis.set_view_interval(lo, hi)
    return locs, formatter.format_ticks(list(locs)), formatter.get_offset()


@dataclass
class _Line:
    x: np.ndarray
    y: np.ndarray
    color: str
    lw: float
    style: str
    label: str | None
    marker: bool = False
    across: str = ""  # "x": a horizontal line at y across the panel; "y": a vertical one at x


@dataclass
class _Legend:
    loc: str
    fontsize: float


def _plotted(x, y, fmt: str | None, kwargs: dict, drawn: int) -> _Line:
    """The line of a matplotlib plot call from its format string and keywords (colour, width, style, label); by
    default the colour cycle's next colour after `drawn` lines."""
    cycle = color_cycle()
    color = kwargs.get("color", kwargs.get("c", cycle[drawn % len(cycle)]))
    return _Line(np.asarray(x, float), np.asarray(y, float), color, kwargs.get("lw", kwargs.get("linewidth", 1.5)),
                 _style(fmt, kwargs.get("ls", kwargs.get("linestyle"))), kwargs.get("label"))


@dataclass
class Panel:
    """One panel of a figure: a rectangle (figure pixels: left, top, right, bottom) and what is drawn in it."""

    rect: tuple[float, float, float, float]
    lines: list[_Line] = field(default_factory=list)
    spans: list[tuple[float, float, str, float]] = field(default_factory=list)
    notes: list[tuple[str, float, float, float, int]] = field(default_factory=list)
    xlabel: str = ""
    ylabel: str = ""
    title: str = ""
    title_pt: float = _TITLE_PT
    ylim: tuple[float, float] | None = None
    ylog: bool = False
    grid_alpha: float | None = None
    grid_minor: bool = False
    legend_spec: _Legend | None = None
    xticklabels: bool = True
    ylabel_x: float = 0.0  # figure pixels left of the panel to the y label's centre
    xlabel_y: float = 0.0  # figure pixels below the panel to the x label's top

    def plot(self, x, y, fmt: str | None = None, **kwargs) -> None:
        """A line y(x) (matplotlib's Axes.plot: format '--', ':', '-.'; color, lw, ls, label)."""
        self.lines.append(_plotted(x, y, fmt, kwargs, len(self.lines)))

    def axhline(self, y: float, color="k", ls: str = "-", lw: float = 1.5, label: str | None = None) -> None:
        """A horizontal line across the panel at y (counted in the y limits, as matplotlib does)."""
        self.lines.append(_Line(np.array([np.nan]), np.array([float(y)]), color, lw, _style(None, ls), label,
                                across="x"))

    def axvline(self, x: float, color="k", ls: str = "-", lw: float = 1.5, label: str | None = None) -> None:
        """A vertical line across the panel at x (counted in the x limits)."""
        self.lines.append(_Line(np.array([float(x)]), np.array([np.nan]), color, lw, _style(None, ls), label,
                                across="y"))

    def axvspan(self, x0: float, x1: float, color="tab:orange", alpha: float = 1.0, **_) -> None:
        """A shaded span from x0 to x1 across the panel."""
        self.spans.append((float(x0), float(x1), color, alpha))

    def annotate(self, text: str, xy: tuple[float, float], xycoords=("data", "axes fraction"), fontsize: float = 10,
                 rotation: int = 0, va: str = "baseline") -> None:
        """Text at (x in data, y as a fraction of the panel's height), its box's top left at that point (rotated
        90 deg with va='top': hung from it, as simbench's plots name a kind of event over its start)."""
        if tuple(xycoords) != ("data", "axes fraction"):
            raise ValueError(f"annotate: xycoords {xycoords!r} is not drawn; expected ('data', 'axes fraction')")
        self.notes.append((text, float(xy[0]), float(xy[1]), fontsize, rotation))

    def set_xlabel(self, text: str) -> None:
        self.xlabel = text

    def set_ylabel(self, text: str) -> None:
        self.ylabel = text

    def set_title(self, text: str, y: float = 1.0, fontsize: float = _TITLE_PT) -> None:
        self.title, self.title_pt = text, fontsize

    def set_ylim(self, lo: float, hi: float) -> None:
        self.ylim = (float(lo), float(hi))

    def set_yscale(self, scale: str) -> None:
        """'linear' or 'log' (values at or below 0 are then not drawn)."""
        if scale not in ("linear", "log"):
            raise ValueError(f"set_yscale: {scale!r} is not drawn; expected 'linear' or 'log'")
        self.ylog = scale == "log"

    def grid(self, alpha: float = 1.0, which: str = "major") -> None:
        """Grid lines at the major ticks, or with which='both' at the minor ones too."""
        self.grid_alpha, self.grid_minor = alpha, which == "both"

    def legend(self, loc: str = "best", fontsize: float = 10) -> None:
        self.legend_spec = _Legend(loc, fontsize)

    def data_x(self) -> tuple[float, float]:
        """The extent of what is drawn along x (lines, vertical lines, spans)."""
        return _extent([np.array([x0, x1]) for x0, x1, *_ in self.spans] + [ln.x for ln in self.lines]) or (0.0, 1.0)

    def _ylimits(self) -> tuple[float, float]:
        if self.ylim is not None:
            return self.ylim
        if self.ylog:
            extent = _extent([ln.y[ln.y > 0] for ln in self.lines])
            return _view_log(*extent) if extent else (1.0, 10.0)
        extent = _extent([ln.y for ln in self.lines])
        return _view(*extent) if extent else (0.0, 1.0)

    def _yticks(self, ylim: tuple[float, float], length_pt: float):
        """(major positions, their labels, the offset text, minor positions, their labels), positions as drawn
        (log10 on a log axis; a linear axis has no minor ticks)."""
        if not self.ylog:
            return (*ticks(*ylim, length_pt, 2 * _LABEL_PT), np.empty(0), [])
        major, labels, minor, minor_labels = log_ticks(*ylim, length_pt, 2 * _LABEL_PT)
        return np.log10(major), labels, "", np.log10(minor), minor_labels

    def draw(self, canvas: Image.Image, xlim: tuple[float, float]) -> None:
        """Everything of this panel onto the figure's canvas, over x limits `xlim`."""
        left, top, right, bottom = (v * _SCALE for v in self.rect)
        w, h = round(right - left), round(bottom - top)
        yt, ylabels, yoffset, minor, minor_labels = self._yticks(self._ylimits(), h / _PT)
        ylim = tuple(np.log10(self._ylimits())) if self.ylog else self._ylimits()
        sx, sy = w / (xlim[1] - xlim[0]), h / (ylim[1] - ylim[0])
        inner = Image.new("RGB", (w, h), "white")
        draw = ImageDraw.Draw(inner, "RGBA")
        for x0, x1, color, alpha in self.spans:
            draw.rectangle(((x0 - xlim[0]) * sx, 0, max((x1 - xlim[0]) * sx, (x0 - xlim[0]) * sx + 1), h),
                           fill=_rgba(color, alpha))
        xt, xlabels, xoffset = ticks(*xlim, w / _PT, 3 * _LABEL_PT)
        px, py, pminor = (xt - xlim[0]) * sx, (ylim[1] - yt) * sy, (ylim[1] - minor) * sy
        if self.grid_alpha is not None:
            grid, width = _rgb(_GRID, self.grid_alpha), _width(_FRAME_PT)
            for x in px:
                draw.line((x, 0, x, h), fill=grid, width=width)
            for y in [*py, *(pminor if self.grid_minor else ())]:
                draw.line((0, y, w, y), fill=grid, width=width)
        for ln in self.lines:
            shown = replace(ln, y=np.log10(np.where(ln.y > 0, ln.y, np.nan))) if self.ylog else ln
            _polyline(draw, _pixels(shown, xlim, ylim, w, h), ln.color, ln.lw, ln.style)
        for text, x, frac, size, rotation in self.notes:
            _text(inner, ((x - xlim[0]) * sx, (1 - frac) * h), text, size, "lt", rotation=rotation)
        if self.legend_spec is not None:
            _legend(inner, self.lines, self.legend_spec)
        canvas.paste(inner, (round(left), round(top)))
        self._frame(canvas, (left, top, left + w, top + h), px, py, xlabels, ylabels, xoffset, yoffset,
                    (pminor, minor_labels))

    def _frame(self, canvas, box, px, py, xlabels, ylabels, xoffset, yoffset, minor) -> None:
        """Spines, ticks, tick labels, offsets, axis labels and title around the panel's box (canvas pixels);
        `minor`: the minor y ticks' pixels and labels."""
        left, top, right, bottom = box
        draw = ImageDraw.Draw(canvas)
        width, tick, pad = _width(_FRAME_PT), _TICK_SIZE * _PT, (_TICK_SIZE + _TICK_PAD) * _PT
        draw.rectangle(box, outline=(0, 0, 0), width=width)
        for y, label in zip(*minor):
            draw.line((left - _MINOR_TICK * _PT, top + y, left, top + y), fill=(0, 0, 0), width=width)
            _tick_text(canvas, (left - (_MINOR_TICK + _TICK_PAD) * _PT, top + y), label, _LABEL_PT)
        for x, label in zip(px, xlabels):
            draw.line((left + x, bottom, left + x, bottom + tick), fill=(0, 0, 0), width=width)
            if self.xticklabels:
                _text(canvas, (left + x, bottom + pad), label, _LABEL_PT, "mt")
        for y, label in zip(py, ylabels):
            draw.line((left - tick, top + y, left, top + y), fill=(0, 0, 0), width=width)
            _tick_text(canvas, (left - pad, top + y), label, _LABEL_PT)
        _text(canvas, (left, top - 2 * _PT), yoffset, _LABEL_PT, "ld")
        if self.xticklabels:
            _text(canvas, (right, bottom + pad + 1.3 * _LABEL_PT * _PT), xoffset, _LABEL_PT, "rt")
        _text(canvas, ((left + right) / 2, top - 6 * _PT), self.title, self.title_pt, "ms")
        _text(canvas, ((left + right) / 2, bottom + self.xlabel_y * _SCALE), self.xlabel, _LABEL_PT, "mt")
        _text(canvas, (left - self.ylabel_x * _SCALE, (top + bottom) / 2), self.ylabel, _LABEL_PT, "mm",
              rotation=90)


def _pixels(ln: _Line, xlim: tuple[float, float], ylim: tuple[float, float], w: int, h: int) -> np.ndarray:
    """A line's vertices as pixels (n, 2) of a w x h panel showing xlim x ylim (y down); a line across the panel
    (axhline, axvline) from edge to edge."""
    x = (ln.x - xlim[0]) * (w / (xlim[1] - xlim[0])) - 0.5  # Pillow's pixel i is centred on coordinate i
    y = (ylim[1] - ln.y) * (h / (ylim[1] - ylim[0])) - 0.5
    if ln.across == "x":
        x, y = np.array([0.0, w]), np.repeat(y, 2)
    elif ln.across == "y":
        x, y = np.repeat(x, 2), np.array([0.0, h])
    return np.column_stack([x, y])


def _legend(canvas: Image.Image, lines: list[_Line], spec: _Legend) -> None:
    """matplotlib's legend of the labelled lines in a corner of the panel ('best': the corner over the fewest
    of the lines' vertices)."""
    shown = [ln for ln in lines if ln.label]
    names = [str(ln.label) for ln in shown]
    if not shown:
        return
    em = spec.fontsize * _PT
    font = _font(spec.fontsize)
    widths = [font.getlength(name) for name in names]
    handle, gap, border, spacing = 2.0 * em, 0.8 * em, 0.4 * em, 0.5 * em
    w = border * 2 + handle + gap + max(widths)
    h = border * 2 + len(shown) * em + (len(shown) - 1) * spacing
    pad = 0.5 * em
    corners = {"upper right": (canvas.width - pad - w, pad), "upper left": (pad, pad),
               "lower left": (pad, canvas.height - pad - h), "lower right": (canvas.width - pad - w,
                                                                             canvas.height - pad - h)}
    if spec.loc in corners:
        x, y = corners[spec.loc]
    else:
        x, y = min(corners.values(), key=lambda c: _covered(canvas, c, w, h))
    draw = ImageDraw.Draw(canvas, "RGBA")
    draw.rounded_rectangle((x, y, x + w, y + h), radius=0.2 * em, fill=(255, 255, 255, 204),
                           outline=_rgb("0.8"), width=_width(_FRAME_PT))
    for i, (ln, name) in enumerate(zip(shown, names)):
        mid = y + border + i * (em + spacing) + em / 2
        if ln.marker:
            r = em / 4
            draw.ellipse((x + border + handle / 2 - r, mid - r, x + border + handle / 2 + r, mid + r),
                         fill=_rgb(ln.color))
        else:
            _polyline(draw, np.array([[x + border, mid], [x + border + handle, mid]]), ln.color, ln.lw, ln.style)
        _text(canvas, (x + border + handle + gap, mid), name, spec.fontsize, "lm")


def _covered(canvas: Image.Image, corner: tuple[float, float], w: float, h: float) -> int:
    """How many dark pixels (the lines; not the light grid and shading) a box at this corner would cover."""
    x, y = corner
    patch = np.asarray(canvas.crop((round(x), round(y), round(x + w), round(y + h))).convert("L"))
    return int((patch < 200).sum())


class Figure:
    """A figure of `width` x `height` inches at DPI, holding panels and 3-D boxes drawn when saved."""

    def __init__(self, width: float, height: float):
        self.size = (round(width * DPI), round(height * DPI))
        self.panels: list[Panel] = []
        self.boxes: list[Box3D] = []
        self.title = ""

    def suptitle(self, text: str) -> None:
        """A title over the whole figure (matplotlib's Figure.suptitle, at its default size)."""
        self.title = text

    def panel(self, rect: tuple[float, float, float, float]) -> Panel:
        """A new panel at rect (figure pixels: left, top, right, bottom); panels share the x limits."""
        self.panels.append(Panel(rect))
        return self.panels[-1]

    def box3d(self, rect: tuple[float, float, float, float]) -> Box3D:
        """A new 3-D box in rect (figure pixels)."""
        self.boxes.append(Box3D(rect))
        return self.boxes[-1]

    def render(self) -> Image.Image:
        """The figure as an RGB picture at DPI."""
        canvas = Image.new("RGB", (self.size[0] * _SCALE, self.size[1] * _SCALE), "white")
        if self.panels:
            extents = np.array([p.data_x() for p in self.panels])
            xlim = _view(extents[:, 0].min(), extents[:, 1].max())
            for p in self.panels:
                p.draw(canvas, xlim)
        for box in self.boxes:
            box.draw(canvas)
        _text(canvas, (canvas.width / 2, 0.1 * DPI * _SCALE), self.title, _TITLE_PT, "mt")
        return canvas.reduce(_SCALE)

    def save(self, path: Path) -> None:
        """Draw the figure into a PNG at `path`."""
        Path(path).write_bytes(png(np.asarray(self.render())))


def png(rgb: np.ndarray) -> bytes:
    """An RGB picture (h, w, 3, uint8) as a PNG file: rows unfiltered, deflated at zlib's fastest level. A plot is
    mostly runs of one colour, which deflate well without the PNG filters; written so in a third of the time
    Pillow's encoder takes (issue 14), the file some 15 % larger."""
    h, w, _ = rgb.shape
    rows = np.concatenate([np.zeros((h, 1), np.uint8), rgb.reshape(h, -1)], axis=1)  # filter byte 0: none

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    return b"".join([b"\x89PNG\r\n\x1a\n", chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)),
                     chunk(b"IDAT", zlib.compress(rows.tobytes(), 1)), chunk(b"IEND", b"")])


# --- 3-D ------------------------------------------------------------------------------------------------------

_ELEV, _AZIM = np.deg2rad(30.0), np.deg2rad(-60.0)  # matplotlib's default view
_ASPECT = np.array([4.0, 4.0, 3.0])  # matplotlib's default box aspect
_PANE = (0.95, 0.95, 0.95)


def _projection() -> np.ndarray:
    """Rows: the screen's right, up and toward-the-viewer directions in the box's axes (orthographic view)."""
    ce, se, ca, sa = np.cos(_ELEV), np.sin(_ELEV), np.cos(_AZIM), np.sin(_AZIM)
    return np.array([[-sa, ca, 0.0], [-se * ca, -se * sa, ce], [ce * ca, ce * sa, se]])


@dataclass
class Box3D:
    """A 3-D box of axes in a rectangle of the figure (figure pixels), with lines and points drawn in it."""

    rect: tuple[float, float, float, float]
    lines: list[_Line] = field(default_factory=list)
    z: list[np.ndarray] = field(default_factory=list)
    labels: list[str] = field(default_factory=lambda: ["", "", ""])
    legend_spec: _Legend | None = None

    def plot(self, x, y, z, fmt: str | None = None, **kwargs) -> None:
        """A 3-D polyline (matplotlib's Axes3D.plot)."""
        self.lines.append(_plotted(x, y, fmt, kwargs, len(self.lines)))
        self.z.append(np.asarray(z, float))

    def scatter(self, x, y, z, color="k", s: float = 20, label: str | None = None) -> None:
        """Points of area `s` pt^2 (matplotlib's Axes3D.scatter)."""
        self.lines.append(_Line(np.asarray(x, float), np.asarray(y, float), color, float(np.sqrt(s)), "-", label,
                                marker=True))
        self.z.append(np.asarray(z, float))

    def set_xlabel(self, text: str) -> None:
        self.labels[0] = text

    def set_ylabel(self, text: str) -> None:
        self.labels[1] = text

    def set_zlabel(self, text: str) -> None:
        self.labels[2] = text

    def legend(self, loc: str = "upper left", fontsize: float = 10) -> None:
        self.legend_spec = _Legend(loc, fontsize)

    def draw(self, canvas: Image.Image) -> None:
        """The box (back panes, grid, ticks, labels), the lines and points, and the legend onto the canvas."""
        points = [np.column_stack([ln.x, ln.y, z]) for ln, z in zip(self.lines, self.z)]
        every = np.concatenate(points)
        limits = np.array([_view(*(_extent([every[:, i]]) or (0.0, 1.0))) for i in range(3)])
        rows = _projection()
        corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float)
        flat = (corners * _ASPECT) @ rows[:2].T
        left, top, right, bottom = (v * _SCALE for v in self.rect)
        pad = 0.11 * (right - left)  # room for the tick and axis labels outside the box
        scale = min((right - left - 2 * pad) / np.ptp(flat[:, 0]), (bottom - top - 2 * pad) / np.ptp(flat[:, 1]))
        centre = np.array([(left + right) / 2, (top + bottom) / 2])
        middle = flat.mean(axis=0)

        def screen(unit: np.ndarray) -> np.ndarray:
            """Canvas pixels of points in the box's unit coordinates (n, 3)."""
            uv = (unit * _ASPECT) @ rows[:2].T
            return np.column_stack([centre[0] + (uv[:, 0] - middle[0]) * scale,
                                    centre[1] - (uv[:, 1] - middle[1]) * scale])

        def unit(xyz: np.ndarray) -> np.ndarray:
            return (xyz - limits[:, 0]) / (limits[:, 1] - limits[:, 0])

        back = (rows[2] < 0).astype(float)  # each axis' far side (the panes), in unit coordinates
        front = 1.0 - back
        draw = ImageDraw.Draw(canvas, "RGBA")
        width = _width(_FRAME_PT)
        for axis in range(3):
            pane = np.array([c for c in corners if c[axis] == back[axis]])
            a, b = [k for k in range(3) if k != axis]
            order = sorted(range(4), key=lambda i: np.arctan2(pane[i, b] - 0.5, pane[i, a] - 0.5))
            draw.polygon([tuple(p) for p in screen(pane[order])], fill=_rgb(_PANE, 0.5),
                         outline=_rgb("0.7"), width=width)
        grid = _rgb(_GRID)
        for axis in range(3):
            length = np.hypot(*np.ptp(screen(np.eye(3)[[axis]] * np.array([[0], [1]])), axis=0)) / _PT
            locs, texts, offset = ticks(*limits[axis], length, 3 * _LABEL_PT)
            values = unit(np.column_stack([locs] * 3))[:, axis]
            for value in values:
                for other in (k for k in range(3) if k != axis):  # its grid line on each back pane
                    third = 3 - axis - other
                    ends = np.zeros((2, 3))
                    ends[:, axis], ends[:, other], ends[:, third] = value, back[other], (0.0, 1.0)
                    draw.line([tuple(p) for p in screen(ends)], fill=grid, width=width)
            self._axis(canvas, draw, screen(self._edge(axis, front)), values, texts, offset, self.labels[axis],
                       screen(np.full((1, 3), 0.5))[0])
        for ln, xyz in zip(self.lines, points):
            p = screen(unit(xyz))
            if ln.marker:
                r = ln.lw * _PT / 2
                for x, y in p:
                    draw.ellipse((x - r, y - r, x + r, y + r), fill=_rgb(ln.color))
            else:
                _polyline(draw, p, ln.color, ln.lw, ln.style)
        if self.legend_spec is not None:
            area = canvas.crop((round(left), round(top), round(right), round(bottom)))
            _legend(area, self.lines, self.legend_spec)
            canvas.paste(area, (round(left), round(top)))

    @staticmethod
    def _edge(axis: int, front: np.ndarray) -> np.ndarray:
        """The box edge along `axis` that carries its ticks, in unit coordinates (2, 3), from its least to its
        greatest value: for x and y the bottom edge nearest the viewer, for z the vertical edge at the right of
        the picture."""
        start = front.copy()
        if axis < 2:
            start[2] = 0.0
        else:
            right = _projection()[0]
            start[:2] = (right[:2] > 0).astype(float)
        ends = np.array([start, start])
        ends[:, axis] = (0.0, 1.0)
        return ends

    @staticmethod
    def _axis(canvas, draw, ends: np.ndarray, values: np.ndarray, texts: list[str], offset: str, label: str,
              middle: np.ndarray) -> None:
        """An axis along its edge (canvas pixels, from its least to its greatest value): ticks at `values` (0 to 1
        along it) pointing away from the box's `middle`, their labels beyond them, the axis' name beyond the
        widest label at the edge's middle, and the offset text (ScalarFormatter's) beyond the edge's end."""
        away = ends.mean(axis=0) - middle
        away /= np.hypot(*away)
        along = (ends[1] - ends[0]) / np.hypot(*(ends[1] - ends[0]))
        tick, em = _TICK_SIZE * _PT, _LABEL_PT * _PT
        font = _font(_LABEL_PT)
        reach = max((abs(away[0]) * font.getlength(t) + abs(away[1]) * em for t in texts), default=0.0)  # the
        # widest tick label's extent along `away`
        for value, text in zip(values, texts):
            at = ends[0] + value * (ends[1] - ends[0])
            draw.line((*at, *(at + tick * away)), fill=(0, 0, 0), width=_width(_FRAME_PT))
            _text(canvas, tuple(at + (tick + 0.5 * em + reach / 2) * away), text, _LABEL_PT, "mm")
        upright = abs(along[0]) < abs(along[1])  # an upright edge's name is written upright, as matplotlib's z
        own = em if upright else abs(away[0]) * font.getlength(label) + abs(away[1]) * em
        _text(canvas, tuple(ends.mean(axis=0) + (tick + 1.2 * em + reach + own / 2) * away), label, _LABEL_PT, "mm",
              rotation=90 if upright else 0)
        _text(canvas, tuple(ends[1] + 1.5 * em * along + (tick + 0.5 * em + reach / 2) * away), offset, _LABEL_PT,
              "mm")
