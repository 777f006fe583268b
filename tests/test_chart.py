"""simbench.chart, the light renderer of the plots, against matplotlib itself: the same limits, ticks and tick
labels for the same data on a panel of the same size, and lines where their data puts them."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure as MplFigure
from PIL import Image

from simbench import chart
from simbench.plots import time_line, time_panels

WIDTH, HEIGHT = 8.0, 4.0  # in


def _series(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A random time series: any duration, scale and offset, flat now and then (matplotlib's nonsingular case)."""
    t = np.linspace(0.0, rng.uniform(0.5, 600.0), 500)
    scale = 10.0 ** rng.uniform(-7, 5)
    y = rng.uniform(-1e3, 1e3) * (rng.random() < 0.3) + scale * np.cumsum(rng.normal(size=t.size))
    if rng.random() < 0.1:
        y[:] = y[0]
    return t, y


def _drawn_axes(t: np.ndarray, y: np.ndarray, rect_px: tuple[float, float, float, float], yscale: str = "linear"):
    """matplotlib's own axes of y(t) at the same size and place on a figure of the same size, drawn."""
    fig = MplFigure(figsize=(WIDTH, HEIGHT), dpi=chart.DPI)
    FigureCanvasAgg(fig)
    left, top, right, bottom = (v / chart.DPI for v in rect_px)
    ax = fig.add_axes((left / WIDTH, 1 - bottom / HEIGHT, (right - left) / WIDTH, (bottom - top) / HEIGHT))
    ax.plot(t, y)
    ax.set_yscale(yscale)
    fig.canvas.draw()
    return ax


def _panel(t: np.ndarray, y: np.ndarray, yscale: str = "linear") -> tuple[chart.Panel, float, float]:
    """A one-panel figure of y(t), and the panel's width and height in pt."""
    _, axes = time_panels(1, WIDTH, HEIGHT)
    panel = axes[0, 0]
    panel.plot(t, y)
    panel.set_yscale(yscale)
    return panel, *((panel.rect[i + 2] - panel.rect[i]) / chart.DPI * 72 for i in (0, 1))


def _matplotlib(t: np.ndarray, y: np.ndarray, rect_px: tuple[float, float, float, float]):
    """matplotlib's own axes of the same size and place on a figure of the same size: (x limits, y limits, x
    ticks in view, y ticks in view, y tick labels, y offset text)."""
    ax = _drawn_axes(t, y, rect_px)
    xlim, ylim = ax.get_xlim(), ax.get_ylim()

    def inside(locs, lim):
        return locs[(locs >= lim[0] - 1e-10 * (lim[1] - lim[0])) & (locs <= lim[1] + 1e-10 * (lim[1] - lim[0]))]

    labels = [label.get_text() for label, loc in zip(ax.get_yticklabels(), ax.get_yticks())
              if loc in inside(ax.get_yticks(), ylim)]
    return (xlim, ylim, inside(ax.get_xticks(), xlim), inside(ax.get_yticks(), ylim), labels,
            ax.yaxis.get_offset_text().get_text())


def test_limits_ticks_and_labels_are_matplotlibs_on_random_series():
    rng = np.random.default_rng(14)
    for _ in range(40):
        t, y = _series(rng)
        panel, width_pt, height_pt = _panel(t, y)
        xlim = chart._view(*panel.data_x())
        ylim = panel._ylimits()
        xt, _, _ = chart.ticks(*xlim, width_pt, 3 * chart._LABEL_PT)
        yt, ylabels, yoffset = chart.ticks(*ylim, height_pt, 2 * chart._LABEL_PT)
        m_xlim, m_ylim, m_xt, m_yt, m_labels, m_offset = _matplotlib(t, y, panel.rect)
        assert np.allclose(xlim, m_xlim, rtol=1e-12, atol=0) and np.allclose(ylim, m_ylim, rtol=1e-12, atol=0)
        assert np.allclose(xt, m_xt) and np.allclose(yt, m_yt), (xt, m_xt, yt, m_yt)
        assert ylabels == m_labels and yoffset == m_offset


def _positive_series(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A random positive time series for a log axis: spanning from a tenth of a decade to eight, at any scale,
    flat now and then (on a power of ten or not)."""
    t = np.linspace(0.0, rng.uniform(0.5, 60.0), 400)
    walk = np.cumsum(rng.normal(size=t.size))
    span = 10.0 ** rng.uniform(-1, np.log10(8))
    y = 10.0 ** (rng.uniform(-6, 4) + span * (walk - walk.min()) / max(np.ptp(walk), 1e-12))
    if rng.random() < 0.1:
        y[:] = 10.0 ** rng.integers(-4, 3) if rng.random() < 0.5 else y[0]
    return t, y


def _matplotlib_log(t: np.ndarray, y: np.ndarray, rect_px: tuple[float, float, float, float]):
    """matplotlib's own log y axis of the same size and place: (y limits, major ticks in view, their labels,
    minor ticks in view, their labels)."""
    ax = _drawn_axes(t, y, rect_px, "log")
    lo, hi = ax.get_ylim()
    found = []
    for minor in (False, True):
        pairs = [(loc, label.get_text()) for loc, label in zip(ax.get_yticks(minor=minor),
                                                                ax.get_yticklabels(minor=minor))
                 if lo * (1 - 1e-10) <= loc <= hi * (1 + 1e-10)]
        found += [np.array([p[0] for p in pairs]), [p[1] for p in pairs]]
    return (lo, hi), *found


def test_a_log_axis_has_matplotlibs_limits_ticks_and_labels_on_random_series():
    """set_yscale('log'): the limits, the major and minor ticks and their labels (mathtext, labelled minors on
    an axis of few decades) of matplotlib's own log axis, on 40 random positive series."""
    rng = np.random.default_rng(25)
    for _ in range(40):
        t, y = _positive_series(rng)
        panel, _, height_pt = _panel(t, y, "log")
        ylim = panel._ylimits()
        major, labels, minor, minor_labels = chart.log_ticks(*ylim, height_pt, 2 * chart._LABEL_PT)
        m_ylim, m_major, m_labels, m_minor, m_minor_labels = _matplotlib_log(t, y, panel.rect)
        assert np.allclose(ylim, m_ylim, rtol=1e-12, atol=0), (ylim, m_ylim)
        assert np.allclose(major, m_major, rtol=1e-12) and labels == m_labels, (major, m_major, labels, m_labels)
        assert np.allclose(minor, m_minor, rtol=1e-12) and minor_labels == m_minor_labels, (minor, m_minor)
        assert all(not label or chart._MATH.fullmatch(label) for label in labels + minor_labels)  # all drawn


def test_a_log_axis_places_its_lines_and_writes_its_exponents(tmp_path):
    """On a log axis from 10^-3 to 10^3, horizontal lines at 10^-2 and 10^2 are drawn at the rows the decades
    map them to (within a pixel), values at or below 0 are not drawn, and a mathtext label is read as its base
    and exponent."""
    fig, axes = time_panels(1, WIDTH, HEIGHT)
    panel = axes[0, 0]
    panel.set_yscale("log")
    panel.set_ylim(1e-3, 1e3)
    panel.plot([0.0, 10.0], [1e-2, 1e-2], color="k")
    panel.plot([0.0, 10.0], [1e2, 1e2], color="k")
    panel.plot([0.0, 10.0], [0.0, -1.0], color="k")  # not drawn
    picture = fig.render()
    left, top, right, bottom = (round(v) for v in panel.rect)
    inside = _dark(picture)[top + 3:bottom - 3, left + 3:right - 3]
    rows = np.flatnonzero(inside.mean(axis=1) > 0.5) + 3
    height = bottom - top
    expected = [height * (3 - 2) / 6, height * (3 + 2) / 6]  # 10^2 and 10^-2, from the top
    assert len(rows) >= 2 and all(min(abs(rows - e)) <= 1.0 for e in expected), (rows, expected)
    found = chart._MATH.fullmatch("$\\mathdefault{2\\times10^{-3}}$")
    assert found is not None and (found["mantissa"], found["exponent"]) == ("2\\times", "-3")


def _dark(picture: Image.Image) -> np.ndarray:
    """Boolean mask of the picture's dark pixels."""
    return np.asarray(picture.convert("L")) < 128


def test_lines_are_drawn_where_their_data_puts_them(tmp_path):
    """A horizontal and a vertical line at random values on a panel of fixed limits: the dark rows and columns
    inside the panel are those the limits map the values to (their centres within a pixel)."""
    rng = np.random.default_rng(3)
    for _ in range(6):
        fig, axes = time_panels(1, WIDTH, HEIGHT)
        panel = axes[0, 0]
        panel.set_ylim(-1.0, 1.0)
        panel.plot([0.0, 10.0], [-1.0, -1.0], color="white")  # the x limits: 0-10 s with matplotlib's margins
        v, s = rng.uniform(-0.8, 0.8), rng.uniform(1.0, 9.0)
        panel.axhline(v, color="k", lw=1.0)
        panel.axvline(s, color="k", lw=1.0)
        fig.save(tmp_path / "lines.png")
        dark = _dark(Image.open(tmp_path / "lines.png"))
        left, top, right, bottom = (round(c) for c in panel.rect)
        inner = dark[top + 3:bottom - 3, left + 3:right - 3]
        rows = np.flatnonzero(inner.mean(axis=1) > 0.9) + top + 3.5  # pixel centres
        columns = np.flatnonzero(inner.mean(axis=0) > 0.9) + left + 3.5
        x0, x1 = chart._view(0.0, 10.0)
        want_row = top + (1.0 - v) / 2.0 * (bottom - top)
        want_column = left + (s - x0) / (x1 - x0) * (right - left)
        assert rows.size and np.abs(rows - want_row).max() <= 1.0
        assert columns.size and np.abs(columns - want_column).max() <= 1.0


@pytest.mark.parametrize("style", ["-", "--", ":"])
def test_a_line_style_covers_the_share_of_its_length_matplotlib_covers(tmp_path, style):
    """A long horizontal line in each style, drawn by simbench.chart and by matplotlib on a panel of the same
    size: the share of its length that is dark is the same within 0.06 (solid all of it, '--' 3.7 of every 5.3
    line widths, ':' 1 of 2.65, each widened alike by antialiasing)."""

    def share(path, rect):
        dark = np.asarray(Image.open(path).convert("L")) < 160
        left, top, right, bottom = (round(c) for c in rect)
        middle = round((top + bottom) / 2)
        return dark[middle - 3:middle + 4, left + 40:right - 40].any(axis=0).mean()

    fig, axes = time_panels(1, WIDTH, HEIGHT)
    panel = axes[0, 0]
    panel.set_ylim(0.0, 1.0)
    panel.plot([0.0, 1.0], [0.5, 0.5], style, color="k", lw=2.0)
    fig.save(tmp_path / "chart.png")
    mpl = MplFigure(figsize=(WIDTH, HEIGHT), dpi=chart.DPI)
    FigureCanvasAgg(mpl)
    left, top, right, bottom = (v / chart.DPI for v in panel.rect)
    ax = mpl.add_axes((left / WIDTH, 1 - bottom / HEIGHT, (right - left) / WIDTH, (bottom - top) / HEIGHT))
    ax.set_ylim(0.0, 1.0)
    ax.plot([0.0, 1.0], [0.5, 0.5], style, color="k", lw=2.0)
    mpl.savefig(tmp_path / "mpl.png", dpi=chart.DPI)
    ours, theirs = share(tmp_path / "chart.png", panel.rect), share(tmp_path / "mpl.png", panel.rect)
    assert abs(ours - theirs) < 0.06, (ours, theirs)


def test_time_line_keeps_every_peak_of_a_long_series(tmp_path):
    """A series far longer than the panel is wide, drawn through its envelope: a one-sample spike still reaches
    its height on the picture."""
    t = np.linspace(0.0, 100.0, 200_001)
    y = np.zeros_like(t)
    y[123_457] = 1.0
    fig, axes = time_panels(1, WIDTH, HEIGHT)
    panel = axes[0, 0]
    time_line(panel, t, y, color="k", lw=1.0)
    fig.save(tmp_path / "spike.png")
    dark = _dark(Image.open(tmp_path / "spike.png"))
    left, top, right, bottom = (round(c) for c in panel.rect)
    y0, y1 = chart._view(0.0, 1.0)
    peak_row = top + (y1 - 1.0) / (y1 - y0) * (bottom - top)
    column = left + (t[123_457] - chart._view(0.0, 100.0)[0]) / np.ptp(chart._view(0.0, 100.0)) * (right - left)
    near = dark[round(peak_row) - 1:round(peak_row) + 2, round(column) - 2:round(column) + 3]
    assert near.any()


def test_gaps_and_infinite_values_are_left_out_of_the_limits_and_the_line(tmp_path):
    """NaN and infinite samples are not drawn and do not widen the limits (matplotlib's behaviour); a series with
    nothing finite, a lone sample and a panel with only a horizontal line still make a picture."""
    t = np.linspace(0.0, 10.0, 1001)
    y = np.sin(t)
    y[100:200] = np.nan
    y[500] = np.inf
    y[600] = -np.inf
    fig, axes = time_panels(3, WIDTH, 2 * HEIGHT)
    first, second, third = axes[:, 0]
    time_line(first, t, y, color="k")
    time_line(first, t, np.full_like(t, np.nan), color="tab:red", label="nothing")
    second.plot([5.0], [2.0], color="k")
    third.axhline(0.5, color="k")
    fig.save(tmp_path / "gaps.png")
    assert np.allclose(first._ylimits(), chart._view(-1.0, 1.0), atol=1e-6)
    assert np.allclose(chart._view(*first.data_x()), chart._view(0.0, 10.0))
    picture = np.asarray(Image.open(tmp_path / "gaps.png").convert("L"))
    left, top, right, bottom = (round(c) for c in first.rect)
    x0, x1 = chart._view(0.0, 10.0)
    gap = [round(left + (s - x0) / (x1 - x0) * (right - left)) for s in (1.2, 1.8)]
    assert (picture[top + 2:bottom - 2, gap[0]:gap[1]] > 200).all()  # nothing drawn across the gap but the grid
