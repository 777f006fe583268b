"""Plots of a run (PNG, matplotlib's Agg backend): joints, the tool's deviation, singularity measures, the path.

Plots are for reading, so angles are drawn in degrees and lengths in millimetres; the data files stay SI.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from simbench.analysis import Analysis  # noqa: E402
from simbench.robots import REVOLUTE, Robot  # noqa: E402
from simbench.sim import Recording  # noqa: E402
from simbench.trajectory import JointTrajectory  # noqa: E402

_DPI = 110


def _display(kind: str) -> tuple[float, str]:
    return (180.0 / np.pi, "deg") if kind == REVOLUTE else (1e3, "mm")


def _shade(ax, events: list[dict], kinds: set[str] | None, color: str, joint: str | None = None) -> None:
    """Shade the spans of the events of these kinds (all if None), only those of `joint` where given."""
    for e in events:
        if joint is not None and e["detail"].get("joint", joint) != joint:
            continue
        if kinds is None or e["kind"] in kinds:
            ax.axvspan(e["t_start"], max(e["t_end"], e["t_start"] + 1e-3), color=color, alpha=0.25, lw=0)


def _save(fig, path: Path) -> None:
    fig.tight_layout()
    fig.savefig(path, dpi=_DPI)
    plt.close(fig)


def _joint_panels(robot: Robot, t: np.ndarray, planned: np.ndarray, simulated: np.ndarray, labels: tuple[str, str],
                  per_second: bool, title: str, path: Path, decorate) -> None:
    """One panel a joint: planned (dashed) against simulated, in degrees or millimetres; decorate(ax, j) adds
    each panel's limits and shading."""
    fig, axes = plt.subplots(robot.dof, 1, figsize=(8, 1.8 * robot.dof + 0.6), sharex=True, squeeze=False)
    for j, ax in enumerate(axes[:, 0]):
        scale, unit = _display(robot.kinds[j])
        ax.plot(t, planned[:, j] * scale, "--", color="tab:blue", lw=1.4, label=labels[0])
        ax.plot(t, simulated[:, j] * scale, color="tab:orange", lw=1.0, label=labels[1])
        decorate(ax, j, scale)
        ax.set_ylabel(f"{robot.joints[j]} ({unit}{'/s' if per_second else ''})")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="best", fontsize=8)
    axes[0, 0].set_title(title)
    axes[-1, 0].set_xlabel("time (s)")
    _save(fig, path)


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
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    ax1.plot(traj.t, result.series["path_deviation"] * 1e3, color="tab:red")
    ax1.axhline(1.0, color="k", ls=":", lw=0.8)
    ax1.set_ylabel("distance from path (mm)")
    ax1.set_title(f"Tool against the planned path: RMS {result.tracking['tool_rms'] * 1e3:.3f} mm, "
                  f"max {result.tracking['tool_max'] * 1e3:.3f} mm")
    ax2.plot(traj.t, result.series["path_lag"] * 1e3, color="tab:purple")
    ax2.set_ylabel("lag along path (mm)")
    ax2.set_xlabel("time (s)")
    for ax in (ax1, ax2):
        _shade(ax, result.limit_events, {"reference_jump"}, "tab:red")
        ax.grid(alpha=0.3)
    _save(fig, path)


def plot_singularity(robot: Robot, rec: Recording, result: Analysis, path: Path) -> None:
    """The robot's singularity measures over time, with the spans near a singular set shaded and named."""
    names = list(result.measures)
    fig, axes = plt.subplots(len(names), 1, figsize=(8, 2.4 * len(names) + 0.6), sharex=True, squeeze=False)
    for ax, name in zip(axes[:, 0], names):
        ax.plot(rec.t, result.series[name], color="tab:green")
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
        _shade(ax, result.singularity_events, None, "tab:orange")
    seen = set()
    for e in result.singularity_events:
        if e["kind"] not in seen:
            axes[0, 0].annotate(e["kind"], (e["t_start"], 1.0), xycoords=("data", "axes fraction"), fontsize=7,
                                rotation=90, va="top")
            seen.add(e["kind"])
    axes[0, 0].set_title("Singularity measures (orange: near a singular set)")
    axes[-1, 0].set_xlabel("time (s)")
    _save(fig, path)


def plot_path(traj: JointTrajectory, rec: Recording, path: Path) -> None:
    """The planned path and the simulated tool trace in 3-D, with the method's waypoints."""
    fig = plt.figure(figsize=(6.5, 6))
    ax = fig.add_subplot(projection="3d")
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
    _save(fig, path)


def write_plots(robot: Robot, traj: JointTrajectory, rec: Recording, result: Analysis, folder: Path) -> list[str]:
    """All plots into folder; returns their file names."""
    folder.mkdir(parents=True, exist_ok=True)
    plot_joints(robot, traj, rec, result, folder / "joints.png")
    plot_joint_speeds(robot, traj, rec, result, folder / "joint_speeds.png")
    plot_tool(traj, result, folder / "tool_deviation.png")
    plot_singularity(robot, rec, result, folder / "singularity.png")
    plot_path(traj, rec, folder / "path.png")
    return ["joints.png", "joint_speeds.png", "tool_deviation.png", "singularity.png", "path.png"]
