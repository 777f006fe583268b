"""A joint path judged by the exact FK of its samples (clearances, type 2 crossings, goal error), and the refusal
or the warnings a path that breaks its margins gets."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simbench.maths.rotations import rotation_angle
from simbench.planners.avoidance_4567.estimators import platform
from simbench.planners.avoidance_4567.task import Task, clearances, margins
from simbench.robots import agile_eye

ENDS = 1e-6  # rad: how near the exact FK of the last joint sample must come to the goal orientation
_ON_CURVE = 1e-6  # rad: a platform axis this near its base axis is on a singular curve


def summary(task: Task, theta: np.ndarray, rot: np.ndarray, kci: np.ndarray) -> dict:
    """KCI and clearances of a path, its exact orientations and KCI given."""
    clear = {name: float(c.min()) for name, c in clearances(task, theta, rot, kci).items()}
    gaps = agile_eye.axis_gaps(rot).min(axis=0)
    return {"kci": {"mean": float(kci.mean()), "min": float(kci.min())}, "clearance": clear,
            "singular_curves": {f"v{i + 1} = +-u{i + 1}": float(g) for i, g in enumerate(gaps)}}


@dataclass(frozen=True)
class Checked:
    """A joint path on the control grid with what the exact FK says of it, and whether it keeps every margin in
    one assembly mode and ends at the goal (`ok`)."""

    name: str
    theta: np.ndarray
    theta_dot: np.ndarray
    rot: np.ndarray
    exact: dict
    crossings: np.ndarray
    goal_error: float
    ok: bool


def _crossings(t: np.ndarray, rot: np.ndarray, undetermined: np.ndarray, det_a: np.ndarray) -> np.ndarray:
    """Times where a path passes the type 2 singular surface: det A changes sign, or the platform comes onto a
    singular curve (where either assembly mode may follow) or is undetermined."""
    on = (agile_eye.axis_gaps(rot).min(axis=1) < _ON_CURVE) | undetermined
    arrives = np.flatnonzero(on & ~np.concatenate([[False], on[:-1]]))
    flips = 1 + np.flatnonzero(np.sign(det_a[1:]) * np.sign(det_a[:-1]) < 0)
    return t[np.union1d(arrives, flips)]


def check_path(task: Task, name: str, t: np.ndarray, theta: np.ndarray, theta_dot: np.ndarray) -> Checked:
    """Judge a joint path by the exact FK of its samples (independent of how it was planned)."""
    rot, undetermined = platform(theta, task.start.matrix())
    terms = agile_eye.kci_terms(theta, rot)  # its rows a_i are A's (agile_eye.jacobians)
    exact = summary(task, theta, rot, terms.kci)
    crossings = _crossings(t, rot, undetermined, np.linalg.det(terms.a))
    goal_error = float(rotation_angle(rot[-1:], task.goal.matrix()[None])[0])
    keeps = not shortfalls(task, exact["clearance"])
    return Checked(name, theta, theta_dot, rot, exact, crossings, goal_error,
                    keeps and not crossings.size and goal_error < ENDS)


_MARGIN_FIELDS = {"type2": "task.singularity_clearance", "kci": "task.kci_min"}


def shortfalls(task: Task, clearance: dict[str, float]) -> list[str]:
    """Each margin not kept, in words: the clearance reached, the margin, and the field that sets it."""
    need = margins(task)
    out = []
    for name, c in clearance.items():
        if c < need[name] - 1e-9:
            field = _MARGIN_FIELDS.get(name, "task.obstacle_clearance")
            out.append(f"kci {c:.3f} (floor {need[name]:.3f}, {field})" if name == "kci" else
                       f"{name} clearance {np.rad2deg(c):.2f} deg (margin {np.rad2deg(need[name]):.2f} deg, {field})")
    return out


def refusal(task: Task, best: Checked, search: dict | None) -> str:
    """Why no path is handed over: the margins not kept, the best clearances found, and what was tried."""
    for end in ("start", "goal"):
        rot = getattr(task, end).matrix()[None]
        clear = {n: float(c[0]) for n, c in clearances(task, agile_eye.ik(rot, task.working_mode), rot).items()}
        if shortfalls(task, clear):
            return (f"the {end} orientation breaks a margin, so no path keeps them: "
                    f"{'; '.join(shortfalls(task, clear))}")
    if search is None:
        tried = "the global search was off (task.avoidance.enabled: false)"
    elif "waypoints" in search:
        tried = "the global search's path failed the exact check of its samples"
    else:
        tried = (f"the global search in SO(3) found none in {search['time']:.2f} s ({search['status']}; "
                 f"task.avoidance.time_budget {task.avoidance.time_budget:g} s)")
    return (f"no path found that keeps the margins: {tried}; the best path found ({best.name}) has "
            f"{'; '.join(v['message'] for v in _violations(task, best))}. Set "
            "task.accept_margin_violation: true to run it anyway")


def _violations(task: Task, chosen: Checked, t_end: float | None = None) -> list[dict]:
    """What a path that is not ok breaks, as verdict violations: margins, a singular crossing, the goal missed."""
    out = [{"kind": "clearance_margin", "message": f"{line} not kept"}
           for line in shortfalls(task, chosen.exact["clearance"])]
    if chosen.crossings.size:
        t_cross = float(chosen.crossings[0])
        out.append({"kind": "singular_crossing", "t": t_cross, "crossings": chosen.crossings.tolist(),
                    "message": f"the plan passes the type 2 singular surface at t = {t_cross:.3f} s: the platform "
                               "may change assembly mode there"})
    if chosen.goal_error >= ENDS:
        out.append({"kind": "goal_missed", "t": t_end, "error": chosen.goal_error,
                    "message": f"the planned platform ends {np.rad2deg(chosen.goal_error):.1f} deg from the goal "
                               "orientation"})
    return out


def accepted(task: Task, chosen: Checked, t_end: float) -> tuple[list[str], list[dict]]:
    """Warnings and violations of a path handed over although it breaks its margins (_violations)."""
    violations = _violations(task, chosen, t_end)
    return [f"{v['message']} (accepted: task.accept_margin_violation)" for v in violations], violations
