"""A run's timeseries.npz as timeseries.csv (`simbench export RUN_FOLDER`, `simbench run --timeseries csv`): one
row a sample, one column a component of each per-sample array, named by its joint or axis with its unit in the
header (`q_shoulder_pan_joint [rad]`), every number as repr writes it (a float read back is the npz's, to the bit).

The file is written beside timeseries.npz through simbench's atomic writing and listed in the folder's marker first
(so `--force` still replaces the folder); a timeseries.csv simbench did not write there is never replaced.
"""

from __future__ import annotations

import json
import os
import zipfile
from dataclasses import dataclass
from itertools import chain
from pathlib import Path

import numpy as np

from simbench import api
from simbench.core import destination
from simbench.core.atomic import staged_file
from simbench.core.errors import RunError, ScenarioError
from simbench.outputs import csv_cells
from simbench.outputs.plot_formats import TIMESERIES_FORMATS

CSV = "timeseries.csv"
BLOCK = 4096  # rows converted to Python numbers at a time: a long run's file is written without holding it all
# The arrays with one column a joint: their unit by the joint's kind (where the kinds are unknown, either).
_BY_KIND = {"position": {api.REVOLUTE: "rad", api.PRISMATIC: "m", None: "rad or m"},
            "speed": {api.REVOLUTE: "rad/s", api.PRISMATIC: "m/s", None: "rad/s or m/s"},
            "force": {api.REVOLUTE: "N m", api.PRISMATIC: "N", None: "N m or N"}}
_JOINT_ARRAYS = {"q_ref": "position", "q": "position", "joint_error": "position", "base_angles": "position",
                 "qd_ref": "speed", "qd": "speed", "actuator_force": "force"}
# The arrays with one column an axis or a quaternion's term (w x y z).
_AXES = {**dict.fromkeys(("tool_ref", "tool"), "xyz"),
         **dict.fromkeys(("tool_orientation_ref", "platform_quat_ref", "platform_quat", "rotor_quat_ref",
                          "rotor_quat"), "wxyz")}
# The unit of every other array simbench writes (docs/guide/outputs.md): 1 a pure number; SI a mix of units, as
# qpos (rad, m and a quaternion's numbers) or a Jacobian's singular values (m and rad per joint unit) are.
UNITS = {"t": "s", "s": "1", "qpos": "SI", "ctrl": "SI", "tool_ref": "m", "tool": "m", "path_deviation": "m",
         "path_lag": "m", "tool_error": "m", "tool_orientation_ref": "1", "tool_orientation_error": "rad",
         "plan_damping": "1", "plan_speed_scale": "1", "plan_tool_error": "m", "plan_orientation_error": "rad",
         "sigma_min": "SI", "manipulability": "SI", "inverse_condition": "1", "sigma_min_unit": "1",
         "condition": "1", "shoulder_gap": "m", "elbow_gap": "rad", "wrist_gap": "rad", "axis_distance": "m",
         "platform_quat_ref": "1", "platform_quat": "1", "orientation_error": "rad", "kci": "1", "singular_gap": "rad",
         "det_a": "1", "closure_error": "m", "gamma": "rad", "engaged": "1", "engaged_ref": "1", "rotor_quat_ref": "1",
         "rotor_quat": "1", "rotor_error": "rad", "type_a": "SI", "type_b_gap": "rad"}
_ROBOT_UNITS = {"puma600": {"manipulability": "1"}}  # its Jacobian's linear rows divided by a length
UNKNOWN = "?"  # a series of a robot or planner of your own, whose unit simbench cannot know


@dataclass(frozen=True)
class Export:
    """A written export: the file, its header's columns, its rows, and the arrays left out (not one row a sample)."""

    path: Path
    columns: tuple[str, ...]
    rows: int
    left_out: tuple[str, ...]


def export(folder: str | os.PathLike, fmt: str = "csv", kinds: tuple[str, ...] | None = None) -> Export:
    """Write the run folder's timeseries.npz as timeseries.csv beside it.

    Args:
        folder: A run's output folder (report.json and timeseries.npz).
        fmt: `"csv"`, the only format.
        kinds: The joints' kinds (api.REVOLUTE or PRISMATIC), for their units; None: a shipped robot's by the
            report's name, an arm derived from its model by the scenario file the report names, else unknown.

    Returns:
        What was written.

    Raises:
        ScenarioError: Not a run folder, an unreadable timeseries or report, or a timeseries.csv in the way that
            simbench did not write.
    """
    if fmt not in TIMESERIES_FORMATS:
        raise ScenarioError("simbench.outputs.export", "fmt",
                            f"expected one of {', '.join(TIMESERIES_FORMATS)}, got {fmt!r}")
    folder = destination.followed(Path(folder))
    _check_folder(folder)
    path = folder / CSV
    with destination.locked(folder):  # no run --force replaces the folder meanwhile
        arrays, report = _read(folder)
        joints = tuple(str(name) for name in arrays.pop("joints"))
        found = kinds if kinds is not None else _kinds(report, joints)
        known = found if found is not None and len(found) == len(joints) else (None,) * len(joints)
        name = report.get("robot")
        shipped = _ROBOT_UNITS.get(name, {}) if isinstance(name, str) and "derived_arm" not in report else {}
        columns, blocks, left_out = _columns(arrays, joints, known, shipped)
        _check_target(folder, path)
        with staged_file(path) as tmp, open(tmp, "w", encoding="utf-8", newline="") as f:
            f.write(csv_cells.row(csv_cells.safe(c) for c in columns))
            for lo in range(0, len(arrays["t"]), BLOCK):
                parts = [b[lo:lo + BLOCK].tolist() for b in blocks]  # Python floats and ints: repr is exact
                f.writelines(",".join(map(repr, chain.from_iterable(p[i] for p in parts))) + "\n"
                             for i in range(len(parts[0])))
    return Export(path=path, columns=tuple(columns), rows=len(arrays["t"]), left_out=tuple(left_out))


def _check_folder(folder: Path) -> None:
    """ScenarioError unless `folder` is a folder holding timeseries.npz and report.json."""
    with destination.refused(folder):
        if not folder.is_dir():
            raise ScenarioError(str(folder), None, "not a folder: expected a run's output folder (report.json and "
                                                   "timeseries.npz)")
        missing = [name for name in ("timeseries.npz", "report.json") if not (folder / name).is_file()]
    if missing:
        raise ScenarioError(str(folder), None, f"not a run's output folder: it has no {' or '.join(missing)} (a "
                                               "run whose plan was refused writes none)")


def _read(folder: Path) -> tuple[dict[str, np.ndarray], dict]:
    """The arrays of the folder's timeseries.npz and its report.json; ScenarioError if either is not simbench's."""
    npz = folder / "timeseries.npz"
    try:
        with np.load(npz, allow_pickle=False) as z:
            arrays = {name: z[name] for name in z.files}
    except (ValueError, EOFError, zipfile.BadZipFile, zipfile.LargeZipFile) as err:
        raise ScenarioError(str(npz), None, f"not a timeseries simbench wrote (NumPy cannot read it: {err})") from None
    for name in ("t", "joints"):
        if name not in arrays:
            raise ScenarioError(str(npz), name, "missing: not a timeseries simbench wrote")
    if arrays["joints"].ndim != 1 or arrays["t"].ndim != 1 or arrays["t"].dtype.kind not in "fiu":
        raise ScenarioError(str(npz), None, f"not a timeseries simbench wrote: t of {arrays['t'].dtype} "
                                            f"{arrays['t'].shape}, joints of shape {arrays['joints'].shape}")
    try:
        report = json.loads((folder / "report.json").read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as err:
        raise ScenarioError(str(folder / "report.json"), None, f"not JSON simbench wrote: {err}") from None
    if not isinstance(report, dict):
        raise ScenarioError(str(folder / "report.json"), None, "expected a JSON object, as simbench writes it")
    return arrays, report


def _kinds(report: dict, joints: tuple[str, ...]) -> tuple[str, ...] | None:
    """The joints' kinds as the run's robot has them: a shipped robot's (by the report's name), or the robot of the
    scenario file the report names; None where neither is there with the joints the timeseries names."""
    from simbench.api import registry

    name = report.get("robot")
    if "derived_arm" not in report and isinstance(name, str) and name in registry.robots():
        robot = registry.robots()[name]
        if tuple(robot.joints) == joints:
            return tuple(robot.kinds)
    scenario = report.get("scenario")
    source = scenario.get("file") if isinstance(scenario, dict) else None
    if isinstance(source, str) and Path(source).is_file():
        from simbench.scenario import load_scenario

        try:
            robot = load_scenario(source).robot_def
        except (ScenarioError, RunError, OSError):  # changed since, or gone: the units stay unknown
            return None
        if tuple(robot.joints) == joints:
            return tuple(robot.kinds)
    return None


def _columns(arrays: dict[str, np.ndarray], joints: tuple[str, ...], kinds: tuple[str | None, ...],
             robot_units: dict[str, str]) -> tuple[list[str], list[np.ndarray], list[str]]:
    """The header's columns, the arrays they come from as (N, columns) blocks in the same order (booleans as 0 and
    1), and the arrays left out: those not one row a sample, and text."""
    rows = len(arrays["t"])
    columns, blocks, left_out = [], [], []
    for name, value in arrays.items():
        if value.ndim == 0 or value.shape[0] != rows or value.dtype.kind not in "fiub":
            left_out.append(name)
            continue
        columns += [f"{label} [{unit}]" for label, unit in _components(name, value.shape[1:], joints, kinds,
                                                                        robot_units)]
        blocks.append(value.reshape(rows, -1).astype(np.int64) if value.dtype.kind == "b" else value.reshape(rows, -1))
    return columns, blocks, left_out


def _components(name: str, shape: tuple[int, ...], joints: tuple[str, ...], kinds: tuple[str | None, ...],
                robot_units: dict[str, str]) -> list[tuple[str, str]]:
    """(label, unit) of each component of a per-sample array of trailing `shape`: by joint (its unit by its kind,
    None unknown), axis or quaternion term where it has one of each, else by index."""
    unit = robot_units.get(name, UNITS.get(name, UNKNOWN))
    if shape == ():
        return [(name, unit)]
    if name in _JOINT_ARRAYS and shape == (len(joints),):
        units = _BY_KIND[_JOINT_ARRAYS[name]]
        return [(f"{name}_{joint}", units.get(kind, units[None])) for joint, kind in zip(joints, kinds)]
    if name in _AXES and shape == (len(_AXES[name]),):
        return [(f"{name}_{axis}", unit) for axis in _AXES[name]]
    return [(f"{name}_{'_'.join(map(str, index))}", unit) for index in np.ndindex(*shape)]


def _check_target(folder: Path, path: Path) -> None:
    """ScenarioError if `path` is there and simbench did not write it (no marker lists it, or it is not a plain
    file); else, where it is not there yet, list it in the folder's marker before it is written."""
    with destination.refused(path):
        there = path.exists() or path.is_symlink()
        if not there:
            destination.mark_more(folder, [CSV])
            return
        if path.is_symlink() or not path.is_file() or path in destination.foreign(folder):
            raise ScenarioError(str(path), None, "is there and simbench did not write it: it is never replaced; "
                                                 "move it out of the way")
