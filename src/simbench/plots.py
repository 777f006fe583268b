"""Plots of a run (PNG): joints, the tool's deviation, singularity measures, the path.

Plots are for reading, so angles are drawn in degrees and lengths in millimetres; the data files stay SI.

Drawn at the pace of the rest of a run (issue 14) by `simbench.chart`, a light raster renderer that takes its
limits, ticks, labels, dash patterns, colours and font from matplotlib; margins, axis labels and titles at fixed
places in inches; and each time series drawn through its envelope at the figure's pixel columns (`_envelope`:
what the line looks like at that resolution, every peak kept). The robots' own plots draw through
`time_panels`, `time_line` and `save_png`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from simbench.analysis import Analysis
from simbench.chart import DPI, Figure, Panel
from simbench.robots import REVOLUTE, Robot
from simbench.sim import Recording
from simbench.trajectory import JointTrajectory

_MARGINS = (1.0, 0.15, 0.36, 0.59)  # in: left (tick labels and y label), right, top (title), bottom (x label)
_GAP = 0.22  # in: between panels that share their time axis
_COLUMN_GAP = 1.05  # in: between columns of panels (the next column's tick labels and y label)
_LABEL_X, _LABEL_Y = 0.72, 0.36  # in: the centre of a y label left of its panel, the top of the x label below it


def _display(kind: str) -> tuple[float, str]:
    return (180.0 / np.pi, "deg") if kind == REVOLUTE else (1e3, "mm")


def _shade(ax: Panel, events: list[dict], kinds: set[str] | None, color: str, joint: str | None = None) -> None:
    """Shade the spans of the events of these kinds (all if None), only those of `joint` where given."""
    for e in events:
        if joint is not None and e["detail"].get("joint", joint) != joint:
            continue
        if kinds is None or e["kind"] in kinds:
            ax.axvspan(e["t_start"], max(e["t_end"], e["t_start"] + 1e-3), color=color, alpha=0.25, lw=0)


def time_panels(rows: int, width: float, height: float, cols: int = 1, gap: float = _GAP,
                top: float = _MARGINS[2]) -> tuple[Figure, np.ndarray]:
    """A figure of `rows` x `cols` panels over one time axis, `width` x `height` inches, laid out with simbench's
    fixed margins (`top` inches over the first row, `gap` between rows; the x tick labels on the lowest row
    only); (figure, panels as an array (rows, cols)). The panels take matplotlib's Axes calls
    (`simbench.chart.Panel`)."""
    fig = Figure(width, height)
    left, right, _, bottom = _MARGINS
    panel = (height - top - bottom - (rows - 1) * gap) / rows
    column = (width - left - right - (cols - 1) * _COLUMN_GAP) / cols
    axes = np.empty((rows, cols), dtype=object)
    for i in range(rows):
        for j in range(cols):
            x0, y0 = left + j * (column + _COLUMN_GAP), top + i * (panel + gap)
            ax = fig.panel(tuple(v * DPI for v in (x0, y0, x0 + column, y0 + panel)))
            ax.xticklabels = i == rows - 1
            ax.ylabel_x, ax.xlabel_y = _LABEL_X * DPI, _LABEL_Y * DPI
            axes[i, j] = ax
    return fig, axes


def time_line(ax: Panel, t: np.ndarray, y: np.ndarray, *args, **kwargs) -> None:
    """ax.plot of y(t) through its envelope at the figure's resolution (`_envelope`): for a robot's own plots as
    for simbench's."""
    ax.plot(*_envelope(t, y, max(1, round(ax.rect[2] - ax.rect[0]))), *args, **kwargs)


def save_png(fig: Figure, path: Path) -> None:
    """Write the figure as simbench writes its plots."""
    fig.save(path)


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


def _joint_panels(robot: Robot, t: np.ndarray, planned: np.ndarray, simulated: np.ndarray, labels: tuple[str, str],
                  per_second: bool, title: str, path: Path, decorate) -> None:
    """One panel a joint: planned (dashed) against simulated, in degrees or millimetres; decorate(ax, j) adds
    each panel's limits and shading."""
    fig, axes = time_panels(robot.dof, 8, 1.8 * robot.dof + 0.6)
    for j, ax in enumerate(axes[:, 0]):
        scale, unit = _display(robot.kinds[j])
        time_line(ax, t, planned[:, j] * scale, "--", color="tab:blue", lw=1.4, label=labels[0])
        time_line(ax, t, simulated[:, j] * scale, color="tab:orange", lw=1.0, label=labels[1])
        decorate(ax, j, scale)
        ax.set_ylabel(f"{robot.joints[j]} ({unit}{'/s' if per_second else ''})")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="best", fontsize=8)
    axes[0, 0].set_title(title, y=1.0)
    axes[-1, 0].set_xlabel("time (s)")
    save_png(fig, path)


def plot_joints(robot: Robot, traj: JointTrajectory, rec: Recording, result: Analysis, path: Path) -> None:
    """Each joint's reference against the simulated value; jumps and limit breaks shaded."""

    def decorate(ax, j, scale):
        _shade(ax, result.limit_events, {"reference_jump", "joint_limit", "velocity_limit"}, "tab:red",
               robot.joints[j])

    _joint_panels(robot, traj.t, traj.q_ref, rec.q, ("reference", "simulated"), False,
                  "Joint reference and simulated joint values (red: jumps and limit breaks)", path, decorate)


def plot_joint_speeds(robot: Robot, traj: JointTrajectory, rec: Recording, result: Analysis, path: Path) -> None:
    """Each joint's planned and simulated speed against its speed limit; singular spans shaded orange."""

    def decorate(ax, j, scale):
        for sign in (-1, 1):
            ax.axhline(sign * robot.qd_max[j] * scale, color="k", ls=":", lw=0.8)
        _shade(ax, result.singularity_events, None, "tab:orange")
        _shade(ax, result.limit_events, {"velocity_limit"}, "tab:red", robot.joints[j])

    _joint_panels(robot, traj.t, traj.qd_ref, rec.qd, ("planned", "simulated"), True,
                  "Joint speeds (dotted: speed limits; orange: near a singularity; red: over the limit)", path,
                  decorate)


def plot_tool(traj: JointTrajectory, result: Analysis, path: Path) -> None:
    """The tool's distance from the planned path and its lag along it."""
    fig, axes = time_panels(2, 8, 5)
    ax1, ax2 = axes[:, 0]
    time_line(ax1, traj.t, result.series["path_deviation"] * 1e3, color="tab:red")
    ax1.axhline(1.0, color="k", ls=":", lw=0.8)
    ax1.set_ylabel("distance from path (mm)")
    ax1.set_title(f"Tool against the planned path: RMS {result.tracking['tool_rms'] * 1e3:.3f} mm, "
                  f"max {result.tracking['tool_max'] * 1e3:.3f} mm", y=1.0)
    time_line(ax2, traj.t, result.series["path_lag"] * 1e3, color="tab:purple")
    ax2.set_ylabel("lag along path (mm)")
    ax2.set_xlabel("time (s)")
    for ax in (ax1, ax2):
        _shade(ax, result.limit_events, {"reference_jump"}, "tab:red")
        ax.grid(alpha=0.3)
    save_png(fig, path)


def plot_singularity(robot: Robot, rec: Recording, result: Analysis, path: Path) -> None:
    """The robot's singularity measures over time, with the spans near a singular set shaded and named."""
    names = list(result.measures)
    fig, axes = time_panels(len(names), 8, 2.4 * len(names) + 0.6)
    for ax, name in zip(axes[:, 0], names):
        time_line(ax, rec.t, result.series[name], color="tab:green")
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
    save_png(fig, path)


def plot_path(traj: JointTrajectory, rec: Recording, path: Path) -> None:
    """The planned path and the simulated tool trace in 3-D, with the method's waypoints."""
    fig = Figure(6.5, 6)
    ax = fig.box3d((0.15 * DPI, 0.15 * DPI, (6.5 - 0.3) * DPI, (6 - 0.2) * DPI))
    ref, tool = traj.tool_ref * 1e3, rec.tool * 1e3
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


def write_plots(robot: Robot, traj: JointTrajectory, rec: Recording, result: Analysis, folder: Path) -> list[str]:
    """All plots into folder; returns their file names."""
    folder.mkdir(parents=True, exist_ok=True)
    plot_joints(robot, traj, rec, result, folder / "joints.png")
    plot_joint_speeds(robot, traj, rec, result, folder / "joint_speeds.png")
    plot_tool(traj, result, folder / "tool_deviation.png")
    plot_singularity(robot, rec, result, folder / "singularity.png")
    plot_path(traj, rec, folder / "path.png")
    return ["joints.png", "joint_speeds.png", "tool_deviation.png", "singularity.png", "path.png"]
