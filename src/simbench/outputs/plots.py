"""Plots of a run (joints, the tool's deviation, singularity measures, the path) in degrees and millimetres, for
reading; matplotlib Figures made without pyplot (no global state), saved in the run's plot format.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from simbench.analysis import Analysis
from simbench.api.panels import figure, plot_text, time_panels
from simbench.api.trajectory import JointTrajectory
from simbench.physics.sim import Recording
from simbench.robots import REVOLUTE, Robot

if TYPE_CHECKING:
    from matplotlib.figure import Figure

_LABEL_SIZE = 7  # pt: an event's name in a panel
_LABEL_ROWS = 3  # rows of event names at a panel's top
MIN_SPAN = 1e-4  # an axis's least span, of its values' size (plain_ticks)


def _display(kind: str) -> tuple[float, str]:
    return (180.0 / np.pi, "deg") if kind == REVOLUTE else (1e3, "mm")


def _shade(ax, events: list[dict], kinds: set[str] | None, color: str, joint: str | None = None) -> None:
    """Shade the spans of the events of these kinds (all if None), only those of `joint` where given."""
    for e in events:
        if joint is not None and e["detail"].get("joint", joint) != joint:
            continue
        if kinds is None or e["kind"] in kinds:
            ax.axvspan(e["t_start"], max(e["t_end"], e["t_start"] + 1e-3), color=color, alpha=0.25, lw=0)


def plain_ticks(fig: Figure) -> None:
    """Tick labels as the values themselves on every axis of the figure (a 3-D one's z too): no offset such as
    `1e-6+1.335e-1`, which matplotlib adds to a nearly constant series and which reads as a value. A linear axis
    spanning under MIN_SPAN of its values' size is widened to that span about its middle, so that its labels (six
    significant digits) fit beside the panel: a variation that small is drawn as the near-flat line it is."""
    from matplotlib.ticker import ScalarFormatter

    for ax in fig.axes:
        for axis in filter(None, (ax.xaxis, ax.yaxis, getattr(ax, "zaxis", None))):
            formatter = axis.get_major_formatter()
            if not isinstance(formatter, ScalarFormatter):
                continue
            formatter.set_useOffset(False)
            lo, hi = sorted(axis.get_view_interval())
            least = MIN_SPAN * max(abs(lo), abs(hi))
            if axis.get_scale() == "linear" and hi - lo < least:
                middle = (lo + hi) / 2
                getattr(ax, f"set_{axis.axis_name}lim")(middle - least / 2, middle + least / 2)


def save(fig: Figure, folder: Path, stem: str, plot_format: str = "png") -> str:
    """Write the figure as `folder/<stem>.<plot_format>`, its ticks plain (plain_ticks); the file's name."""
    name = f"{stem}.{plot_format}"
    plain_ticks(fig)
    fig.savefig(folder / name, format=plot_format)
    return name


def _joint_panels(robot: Robot, t: np.ndarray, planned: np.ndarray, simulated: np.ndarray, labels: tuple[str, str],
                  per_second: bool, title: str, decorate) -> Figure:
    """One panel a joint: planned (dashed) against simulated; decorate(ax, j, scale) adds limits and shading."""
    fig, axes = time_panels(robot.dof, 8, 1.8 * robot.dof + 0.6)
    for j, ax in enumerate(axes[:, 0]):
        scale, unit = _display(robot.kinds[j])
        ax.plot(t, planned[:, j] * scale, "--", color="tab:blue", lw=1.4, label=labels[0])
        ax.plot(t, simulated[:, j] * scale, color="tab:orange", lw=1.0, label=labels[1])
        decorate(ax, j, scale)
        ax.set_ylabel(f"{plot_text(robot.joints[j])} ({unit}{'/s' if per_second else ''})")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="best", fontsize=8)
    axes[0, 0].set_title(title, y=1.0)  # y given: no search for a place above the ticks
    axes[-1, 0].set_xlabel("time (s)")
    return fig


def plot_joints(robot: Robot, traj: JointTrajectory, rec: Recording, result: Analysis) -> Figure:
    """Each joint's reference against the simulated value; jumps and limit breaks shaded."""

    def decorate(ax, j, scale):
        _shade(ax, result.limit_events, {"reference_jump", "joint_limit", "velocity_limit"}, "tab:red",
               robot.joints[j])

    return _joint_panels(robot, traj.t, traj.q_ref, rec.q, ("reference", "simulated"), False,
                         "Joint reference and simulated joint values (red: jumps and limit breaks)", decorate)


def plot_joint_speeds(robot: Robot, traj: JointTrajectory, rec: Recording, result: Analysis) -> Figure:
    """Each joint's planned and simulated speed against its speed limit; singular spans shaded orange."""

    def decorate(ax, j, scale):
        for sign in (-1, 1):
            ax.axhline(sign * robot.qd_max[j] * scale, color="k", ls=":", lw=0.8)
        _shade(ax, result.singularity_events, None, "tab:orange")
        _shade(ax, result.limit_events, {"velocity_limit"}, "tab:red", robot.joints[j])

    return _joint_panels(robot, traj.t, traj.qd_ref, rec.qd, ("planned", "simulated"), True,
                         "Joint speeds (dotted: speed limits; orange: near a singularity; red: over the limit)",
                         decorate)


def plot_tool(traj: JointTrajectory, result: Analysis) -> Figure:
    """The tool's distance from the planned path and its lag along it."""
    fig, axes = time_panels(2, 8, 5)
    ax1, ax2 = axes[:, 0]
    ax1.plot(traj.t, result.series["path_deviation"] * 1e3, color="tab:red")
    ax1.axhline(1.0, color="k", ls=":", lw=0.8)
    ax1.set_ylabel("distance from path (mm)")
    ax1.set_title(f"Tool against the planned path: RMS {result.tracking['tool_rms'] * 1e3:.3f} mm, "
                  f"max {result.tracking['tool_max'] * 1e3:.3f} mm", y=1.0)
    ax2.plot(traj.t, result.series["path_lag"] * 1e3, color="tab:purple")
    ax2.set_ylabel("lag along path (mm)")
    ax2.set_xlabel("time (s)")
    for ax in (ax1, ax2):
        _shade(ax, result.limit_events, {"reference_jump"}, "tab:red")
        ax.grid(alpha=0.3)
    return fig


def plot_singularity(robot: Robot, rec: Recording, result: Analysis) -> Figure:
    """The robot's singularity measures over time, with the spans near a singular set shaded and named."""
    names = list(result.measures)
    fig, axes = time_panels(len(names), 8, 2.4 * len(names) + 0.6)
    for ax, name in zip(axes[:, 0], names):
        ax.plot(rec.t, result.series[name], color="tab:green")
        ax.set_ylabel(plot_text(name))
        ax.grid(alpha=0.3)
        _shade(ax, result.singularity_events, None, "tab:orange")
    firsts: dict[str, float] = {}
    for e in result.singularity_events:
        firsts.setdefault(e["kind"], e["t_start"])
    left_out = _event_labels(axes[0, 0], firsts)
    note = f"; {left_out} unlabelled, too close to another: report.json names each" if left_out else ""
    axes[0, 0].set_title(f"Singularity measures (orange: near a singular set{note})", y=1.0)
    axes[-1, 0].set_xlabel("time (s)")
    return fig


def _event_labels(ax, starts: dict[str, float]) -> int:
    """Name each kind of event at its start, `starts` {kind: t}, in the panel's top rows: each label in the first
    row where it overlaps no other (measured as drawn), flipped to the left of its time at the right edge; a
    label that fits no row is left out. Returns how many were left out."""
    renderer = _renderer(ax.figure)
    ax.get_xlim()  # the limits autoscaled now: the labels are measured where they will be drawn
    frame = ax.get_window_extent(renderer)
    placed: list = []  # the labels' boxes, display pixels
    left_out = 0
    for kind, t in sorted(starts.items(), key=lambda item: item[1]):
        label = ax.annotate(plot_text(kind), (t, 1.0), (0, 0), xycoords=("data", "axes fraction"),
                            textcoords="offset points", fontsize=_LABEL_SIZE, va="top",
                            bbox={"boxstyle": "square,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.8})
        for row in range(_LABEL_ROWS):
            y = -2 - row * _LABEL_SIZE * 1.6  # points below the panel's top
            label.xyann = (2, y)
            label.set_horizontalalignment("left")
            box = label.get_window_extent(renderer)
            if box.x1 > frame.x1:
                label.xyann = (-2, y)
                label.set_horizontalalignment("right")
                box = label.get_window_extent(renderer)
            if not any(box.overlaps(other) for other in placed):
                placed.append(box.padded(2))
                break
        else:
            label.remove()
            left_out += 1
    return left_out


def _renderer(fig: Figure):
    """A renderer that measures text as the saved figure draws it (Agg's, at the figure's resolution)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    return canvas.get_renderer()


def _equal_axes(ax, points: np.ndarray) -> None:
    """Equal scales on the three axes: a cube about the points' middle, as long as their largest extent (at least
    1 mm), in a cubic box. A flat arc looks flat, and a line's small sideways wobble as small as it is."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    middle, half = (lo + hi) / 2, max(float(np.max(hi - lo)), 1.0) / 2
    ax.set_xlim3d(middle[0] - half, middle[0] + half)
    ax.set_ylim3d(middle[1] - half, middle[1] + half)
    ax.set_zlim3d(middle[2] - half, middle[2] + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))


def plot_path(traj: JointTrajectory, rec: Recording) -> Figure:
    """The planned path and the simulated tool trace in 3-D on equal axes, with the method's waypoints."""
    fig = figure(6.5, 6)
    fig.subplots_adjust(left=0.02, right=0.95, bottom=0.04, top=0.98)
    ax = fig.add_subplot(projection="3d")
    ref, tool = traj.tool_ref * 1e3, rec.tool * 1e3
    ax.plot(*ref.T, "--", color="tab:blue", lw=2, label="planned")
    ax.plot(*tool.T, color="tab:red", lw=1, label="simulated tool")
    points = [ref, tool]
    if traj.waypoints:
        points.append(np.array([w["X"] for w in traj.waypoints]) * 1e3)
        ax.scatter(*points[-1].T, color="k", s=12, label="waypoints")
    _equal_axes(ax, np.vstack(points))
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    ax.legend(loc="upper left", fontsize=8)
    return fig


def draw_plots(robot: Robot, traj: JointTrajectory, rec: Recording, result: Analysis) -> dict[str, Figure]:
    """simbench's plots and the robot's own (its `plots` hook), by their file stems."""
    return {"joints": plot_joints(robot, traj, rec, result),
            "joint_speeds": plot_joint_speeds(robot, traj, rec, result),
            "tool_deviation": plot_tool(traj, result),
            "singularity": plot_singularity(robot, rec, result),
            "path": plot_path(traj, rec),
            **robot.plots(traj, rec, result)}


def write_plots(robot: Robot, traj: JointTrajectory, rec: Recording, result: Analysis, folder: Path,
                plot_format: str = "png") -> list[str]:
    """draw_plots' figures into folder, in `plot_format`; their file names."""
    folder.mkdir(parents=True, exist_ok=True)
    return [save(fig, folder, stem, plot_format) for stem, fig in draw_plots(robot, traj, rec, result).items()]
