"""Plots of a run (PNG, matplotlib's Agg backend): joints, the tool's deviation, singularity measures, the path.

Plots are for reading, so angles are drawn in degrees and lengths in millimetres; the data files stay SI.

Drawn at the pace of the rest of a run: figures made on Agg canvases directly (no pyplot); margins, axis labels and
titles at fixed places in inches, where tight_layout and matplotlib's own placing would measure every tick label at
each draw; each time series drawn through its envelope at the figure's pixel columns (`_envelope`: what the line
looks like at that resolution, every peak kept); one figure cleared and drawn again for the plots with as many
panels, its ticks made once (`_Pages`); and PNGs written with light compression. The robots' own plots draw
through `time_panels`, `time_line` and `save_png`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from simbench.analysis import Analysis
from simbench.robots import REVOLUTE, Robot
from simbench.sim import Recording
from simbench.trajectory import JointTrajectory

_DPI = 110
_MARGINS = (1.0, 0.15, 0.36, 0.59)  # in: left (tick labels and y label), right, top (title), bottom (x label)
_GAP = 0.22  # in: between panels that share their time axis
_LABEL_X, _LABEL_Y = 0.72, 0.36  # in: the centre of a y label left of its panel, the top of the x label below it
_PNG = {"compress_level": 1}  # zlib's fastest: the files 10-20 % larger, written in half the time


def _display(kind: str) -> tuple[float, str]:
    return (180.0 / np.pi, "deg") if kind == REVOLUTE else (1e3, "mm")


def _shade(ax, events: list[dict], kinds: set[str] | None, color: str, joint: str | None = None) -> None:
    """Shade the spans of the events of these kinds (all if None), only those of `joint` where given."""
    for e in events:
        if joint is not None and e["detail"].get("joint", joint) != joint:
            continue
        if kinds is None or e["kind"] in kinds:
            ax.axvspan(e["t_start"], max(e["t_end"], e["t_start"] + 1e-3), color=color, alpha=0.25, lw=0)


def _figure(width: float, height: float) -> Figure:
    """A figure of this size (in) on its own Agg canvas."""
    fig = Figure(figsize=(width, height), dpi=_DPI)
    FigureCanvasAgg(fig)
    return fig


def _layout(fig, rows: int, width: float, height: float) -> None:
    """Size the figure and place its `rows` panels with the fixed margins."""
    fig.set_size_inches(width, height)
    left, right, top, bottom = _MARGINS
    panel = (height - top - bottom - (rows - 1) * _GAP) / rows
    fig.subplots_adjust(left=left / width, right=1 - right / width, top=1 - top / height, bottom=bottom / height,
                        hspace=_GAP / panel)


def _place_labels(axes, width: float, height: float) -> None:
    """Axis labels at fixed distances (in) from the panels, and titles just above them: matplotlib would otherwise
    measure every tick label of every panel at each draw to place them."""
    left, right, top, bottom = _MARGINS
    rows = len(axes)
    panel = (height - top - bottom - (rows - 1) * _GAP) / rows
    for ax in axes[:, 0]:
        ax.yaxis.set_label_coords(-_LABEL_X / (width - left - right), 0.5)
        ax.xaxis.set_label_coords(0.5, -_LABEL_Y / panel)
        ax.set_title(ax.get_title(), y=1.0)


def _panels(rows: int, width: float, height: float):
    """A figure of `rows` panels over one time axis, laid out with the fixed margins; (figure, axes (rows, 1))."""
    fig = _figure(width, height)
    _layout(fig, rows, width, height)
    axes = fig.subplots(rows, 1, sharex=True, squeeze=False)
    _place_labels(axes, width, height)
    return fig, axes


def time_panels(rows: int, width: float, height: float):
    """For a robot's own plots: a figure of `rows` panels over one time axis, laid out as simbench's; (figure,
    axes (rows, 1))."""
    return _panels(rows, width, height)


def time_line(ax, t: np.ndarray, y: np.ndarray, *args, **kwargs) -> None:
    """For a robot's own plots: ax.plot of y(t) as simbench draws it (through its envelope at the figure's
    resolution)."""
    _line(ax, t, y, *args, **kwargs)


def save_png(fig, path: Path) -> None:
    """For a robot's own plots: write the figure as simbench writes its plots."""
    fig.savefig(path, dpi=_DPI, pil_kwargs=_PNG)


def _columns(fig) -> int:
    """Pixel columns across the figure's time axes."""
    left, right, _, _ = _MARGINS
    return max(1, int((fig.get_figwidth() - left - right) * _DPI))


def _envelope(t: np.ndarray, y: np.ndarray, columns: int) -> tuple[np.ndarray, np.ndarray]:
    """The samples of y(t) a line at `columns` pixels across shows: in each run of samples one column wide, the
    first, the least, the greatest and the last (in their order; M4 aggregation), so that every peak and every
    step survives, and either side of every gap (NaN). Series already that short are kept whole."""
    count = len(t)
    size = -(-count // columns)  # samples a column
    if size <= 4:
        return t, y
    whole = count // size * size
    gap = np.isnan(y)
    block = y[:whole].reshape(-1, size)
    blank = gap[:whole].reshape(-1, size)
    start = np.arange(0, whole, size)
    least = np.where(blank, np.inf, block).argmin(axis=1)
    greatest = np.where(blank, -np.inf, block).argmax(axis=1)
    keep = [start, start + size - 1, np.arange(whole, count), start + least, start + greatest]
    if gap.any():
        edge = np.flatnonzero(gap[1:] != gap[:-1])
        keep += [edge, edge + 1]
    keep = np.unique(np.concatenate(keep))
    return t[keep], y[keep]


def _line(ax, t: np.ndarray, y: np.ndarray, *args, **kwargs) -> None:
    """ax.plot of y(t) through its envelope at the figure's resolution."""
    ax.plot(*_envelope(t, y, _columns(ax.figure)), *args, **kwargs)


def _clear(axes) -> None:
    """Take off what a plot drew on these panels, leaving the panels, their layout and their ticks to draw the
    next plot of the same layout on."""
    for ax in axes[:, 0]:
        for artist in [*ax.lines, *ax.patches, *ax.texts, *ax.collections]:
            artist.remove()
        if ax.get_legend() is not None:
            ax.get_legend().remove()
        ax.set_title("")
        ax.set_xlabel("")
        ax.relim()
        ax.autoscale()


class _Pages:
    """The figures of one run's plots: a figure a number of panels, cleared, sized and drawn again for the next plot
    with as many (its panels and their ticks made once)."""

    def __init__(self):
        self._figures: dict[int, tuple] = {}

    def panels(self, rows: int, width: float, height: float):
        """A figure of `rows` panels over one time axis (`_panels`), blank; (figure, axes (rows, 1))."""
        if rows in self._figures:
            fig, axes = self._figures[rows]
            _clear(axes)
            _layout(fig, rows, width, height)
            _place_labels(axes, width, height)
        else:
            self._figures[rows] = _panels(rows, width, height)
        return self._figures[rows]

    @staticmethod
    def save(fig, path: Path) -> None:
        """Draw the figure into its PNG."""
        save_png(fig, path)


def _joint_panels(robot: Robot, t: np.ndarray, planned: np.ndarray, simulated: np.ndarray, labels: tuple[str, str],
                  per_second: bool, title: str, path: Path, decorate, pages: _Pages) -> None:
    """One panel a joint: planned (dashed) against simulated, in degrees or millimetres; decorate(ax, j) adds
    each panel's limits and shading."""
    fig, axes = pages.panels(robot.dof, 8, 1.8 * robot.dof + 0.6)
    for j, ax in enumerate(axes[:, 0]):
        scale, unit = _display(robot.kinds[j])
        _line(ax, t, planned[:, j] * scale, "--", color="tab:blue", lw=1.4, label=labels[0])
        _line(ax, t, simulated[:, j] * scale, color="tab:orange", lw=1.0, label=labels[1])
        decorate(ax, j, scale)
        ax.set_ylabel(f"{robot.joints[j]} ({unit}{'/s' if per_second else ''})")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="best", fontsize=8)
    axes[0, 0].set_title(title, y=1.0)
    axes[-1, 0].set_xlabel("time (s)")
    pages.save(fig, path)


def plot_joints(robot: Robot, traj: JointTrajectory, rec: Recording, result: Analysis, path: Path,
                pages: _Pages | None = None) -> None:
    """Each joint's reference against the simulated value; jumps and limit breaks shaded."""

    def decorate(ax, j, scale):
        _shade(ax, result.limit_events, {"reference_jump", "joint_limit", "velocity_limit"}, "tab:red",
               robot.joints[j])

    _joint_panels(robot, traj.t, traj.q_ref, rec.q, ("reference", "simulated"), False,
                  "Joint reference and simulated joint values (red: jumps and limit breaks)", path, decorate,
                  pages or _Pages())


def plot_joint_speeds(robot: Robot, traj: JointTrajectory, rec: Recording, result: Analysis, path: Path,
                      pages: _Pages | None = None) -> None:
    """Each joint's planned and simulated speed against its speed limit; singular spans shaded orange."""

    def decorate(ax, j, scale):
        for sign in (-1, 1):
            ax.axhline(sign * robot.qd_max[j] * scale, color="k", ls=":", lw=0.8)
        _shade(ax, result.singularity_events, None, "tab:orange")
        _shade(ax, result.limit_events, {"velocity_limit"}, "tab:red", robot.joints[j])

    _joint_panels(robot, traj.t, traj.qd_ref, rec.qd, ("planned", "simulated"), True,
                  "Joint speeds (dotted: speed limits; orange: near a singularity; red: over the limit)", path,
                  decorate, pages or _Pages())


def plot_tool(traj: JointTrajectory, result: Analysis, path: Path, pages: _Pages | None = None) -> None:
    """The tool's distance from the planned path and its lag along it."""
    pages = pages or _Pages()
    fig, axes = pages.panels(2, 8, 5)
    ax1, ax2 = axes[:, 0]
    _line(ax1, traj.t, result.series["path_deviation"] * 1e3, color="tab:red")
    ax1.axhline(1.0, color="k", ls=":", lw=0.8)
    ax1.set_ylabel("distance from path (mm)")
    ax1.set_title(f"Tool against the planned path: RMS {result.tracking['tool_rms'] * 1e3:.3f} mm, "
                  f"max {result.tracking['tool_max'] * 1e3:.3f} mm", y=1.0)
    _line(ax2, traj.t, result.series["path_lag"] * 1e3, color="tab:purple")
    ax2.set_ylabel("lag along path (mm)")
    ax2.set_xlabel("time (s)")
    for ax in (ax1, ax2):
        _shade(ax, result.limit_events, {"reference_jump"}, "tab:red")
        ax.grid(alpha=0.3)
    pages.save(fig, path)


def plot_singularity(robot: Robot, rec: Recording, result: Analysis, path: Path,
                     pages: _Pages | None = None) -> None:
    """The robot's singularity measures over time, with the spans near a singular set shaded and named."""
    pages = pages or _Pages()
    names = list(result.measures)
    fig, axes = pages.panels(len(names), 8, 2.4 * len(names) + 0.6)
    for ax, name in zip(axes[:, 0], names):
        _line(ax, rec.t, result.series[name], color="tab:green")
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
        _shade(ax, result.singularity_events, None, "tab:orange")
    seen = set()
    for e in result.singularity_events:
        if e["kind"] not in seen:
            axes[0, 0].annotate(e["kind"], (e["t_start"], 1.0), xycoords=("data", "axes fraction"), fontsize=7,
                                rotation=90, va="top")
            seen.add(e["kind"])
    axes[0, 0].set_title("Singularity measures (orange: near a singular set)", y=1.0)
    axes[-1, 0].set_xlabel("time (s)")
    pages.save(fig, path)


def plot_path(traj: JointTrajectory, rec: Recording, path: Path) -> None:
    """The planned path and the simulated tool trace in 3-D, with the method's waypoints."""
    fig = _figure(6.5, 6)
    fig.subplots_adjust(left=0.15 / 6.5, right=1 - 0.3 / 6.5, top=1 - 0.15 / 6, bottom=0.2 / 6)
    ax = fig.add_subplot(projection="3d")
    ref, tool = _trace(traj.tool_ref * 1e3), _trace(rec.tool * 1e3)
    ax.plot(*ref.T, "--", color="tab:blue", lw=2, label="planned")
    ax.plot(*tool.T, color="tab:red", lw=1, label="simulated tool")
    if traj.waypoints:
        wp = np.array([w["X"] for w in traj.waypoints]) * 1e3
        ax.scatter(*wp.T, color="k", s=12, label="waypoints")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    ax.legend(loc="upper left", fontsize=8)
    save_png(fig, path)


def _trace(points: np.ndarray) -> np.ndarray:
    """A 3-D polyline with the vertices it does not need at the figure's resolution left out: each axis scaled to
    its own extent (as the 3-D box draws it), Ramer-Douglas-Peucker within 1e-3 of that (simbench.render.simplify),
    and each axis' least and greatest kept (the same limits)."""
    from simbench.render import simplify

    if len(points) < 3:
        return points
    extent = np.ptp(points, axis=0)
    keep = simplify(points / np.where(extent > 0, extent, 1.0), 1e-3)
    return points[np.union1d(keep, np.concatenate([points.argmin(axis=0), points.argmax(axis=0)]))]


def write_plots(robot: Robot, traj: JointTrajectory, rec: Recording, result: Analysis, folder: Path) -> list[str]:
    """All plots into folder; returns their file names."""
    folder.mkdir(parents=True, exist_ok=True)
    pages = _Pages()
    plot_joints(robot, traj, rec, result, folder / "joints.png", pages)
    plot_joint_speeds(robot, traj, rec, result, folder / "joint_speeds.png", pages)
    plot_tool(traj, result, folder / "tool_deviation.png", pages)
    plot_singularity(robot, rec, result, folder / "singularity.png", pages)
    plot_path(traj, rec, folder / "path.png")
    return ["joints.png", "joint_speeds.png", "tool_deviation.png", "singularity.png", "path.png"]
