"""Paper 003's planner on random Agile Eye tasks whose plain 4-5-6-7 joint path crosses a type 2 singular curve
(project issue 19): how many the avoidance windows bend to keep the margins, how many go on to the global
search in SO(3) and succeed, how many are refused (and the best clearance then found), and the planning time.

Tasks (fixed seed): start and goal orientations uniform in SO(3), each at least 15 deg from the singular curves
(the 10 deg margin and 5 more, so that no task is refused for its ends alone), kept only if the plain joint path
between their IK solutions (working mode 0, each joint the shorter way round, as the planner takes it) crosses
the type 2 surface, that is if det A along the exact FK of that path changes sign. Task k has k mod 4
obstacles, each a ball of orientations of radius 8-20 deg centred near the geodesic from start to goal (so that
it is in the way), kept at least 5 deg beyond its radius and the 1 deg margin from both ends. Margins: 10 deg
from the singular curves, 1 deg outside the obstacles; T = 4 s, the learnt-FK estimator, the default budget.

Every plan handed over is checked here, not by the planner's bookkeeping: the exact FK followed along the
plan's own q_ref from the start orientation (agile_eye.fk_track) gives the platform at every control sample;
from it the angle to the singular curves (agile_eye.axis_gaps), to each obstacle's centre, det A's sign, and
where the plan starts and ends.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402

import numpy as np  # noqa: E402
from scipy.spatial.transform import Rotation, Slerp  # noqa: E402

from simbench.core.errors import RunError  # noqa: E402
from simbench.core.plant import Plant  # noqa: E402
from simbench.maths.rotations import rotation_angle  # noqa: E402
from simbench.planners.random_tasks import orientation_doc as _quat  # noqa: E402
from simbench.planners.random_tasks import plain_path_crosses  # noqa: E402
from simbench.robots import agile_eye  # noqa: E402
from simbench.scenario import parse_scenario  # noqa: E402

TASKS = 40
SEED = 19
MARGIN = np.deg2rad(10.0)  # from the singular curves
CLEARANCE = np.deg2rad(1.0)  # outside the obstacles
ENDS = np.deg2rad(15.0)  # the ends' least angle to the singular curves
DURATION = 4.0


def tasks(n: int = TASKS, seed: int = SEED) -> list[dict]:
    """n task sections (orientations as quaternions, angles in radians) whose plain path crosses a type 2
    curve."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        ends = Rotation.random(2, random_state=rng).as_matrix()
        if agile_eye.axis_gaps(ends).min() < ENDS or not plain_path_crosses(*ends):
            continue
        geodesic = Slerp([0.0, 1.0], Rotation.from_matrix(ends))
        obstacles = []
        while len(obstacles) < len(out) % 4:
            radius = rng.uniform(np.deg2rad(8.0), np.deg2rad(20.0))
            nudge = Rotation.from_rotvec(rng.normal(size=3) * np.deg2rad(5.0))
            center = (nudge * geodesic([rng.uniform(0.2, 0.8)])).as_matrix()
            if rotation_angle(np.broadcast_to(center, (2, 3, 3)), ends).min() > radius + CLEARANCE + np.deg2rad(5):
                obstacles.append({"center": _quat(center[0]), "radius": float(radius)})
        out.append({"start": _quat(ends[0]), "goal": _quat(ends[1]), "obstacles": obstacles,
                     "singularity_clearance": float(MARGIN), "obstacle_clearance": float(CLEARANCE)})
    return out


def verify(task, q_ref: np.ndarray) -> dict:
    """The plan's clearances (rad) and end errors by the exact FK of its own joint samples."""
    start, goal = task.start.matrix(), task.goal.matrix()
    rot = agile_eye.fk_track(q_ref, start)
    det = np.linalg.det(agile_eye.jacobians(q_ref, rot)[0])
    obstacle = min([float((rotation_angle(np.broadcast_to(o.center.matrix(), rot.shape), rot) - o.radius).min())
                    for o in task.obstacles], default=np.inf)
    return {"type2": float(agile_eye.axis_gaps(rot).min()), "obstacle": obstacle,
            "det_a_sign_changes": int(np.sum(np.sign(det[1:]) * np.sign(det[:-1]) < 0)),
            "start_error": float(rotation_angle(rot[:1], start[None])[0]),
            "goal_error": float(rotation_angle(rot[-1:], goal[None])[0])}


def task_scenario(k: int, section: dict, duration: float = DURATION):
    """Random task k (its `task:` section) as an avoidance_4567 scenario on the 4-5-6-7 law."""
    raw = {"robot": "agile_eye", "planner": "avoidance_4567", "task": section,
           "timing": {"law": "4567", "duration": duration, "hold": 0.0}}
    return parse_scenario(raw, f"task {k}")


def measure() -> dict:
    """Plan every task; outcome, planning time and the independent check of each."""
    robot = agile_eye.ROBOT
    dt = float(Plant.load(robot).model.opt.timestep)
    rows = []
    for k, section in enumerate(tasks()):
        sc = task_scenario(k, section)
        start = time.perf_counter()
        try:
            traj = sc.planner_def.plan(sc, robot, dt)
        except RunError as err:
            rows.append({"task": k, "obstacles": len(sc.task.obstacles), "outcome": "refused",
                         "seconds": time.perf_counter() - start, "reason": str(err)})
            continue
        seconds = time.perf_counter() - start
        check = verify(sc.task, traj.q_ref)
        kept = (check["type2"] >= MARGIN - 1e-9 and check["obstacle"] >= CLEARANCE - 1e-9
                and check["det_a_sign_changes"] == 0 and max(check["start_error"], check["goal_error"]) < 1e-6)
        outcome = "search" if traj.info["path"].startswith("global search") else "bent"
        rows.append({"task": k, "obstacles": len(sc.task.obstacles), "outcome": outcome, "seconds": seconds,
                     "kept": kept, "windows": len(traj.info["windows"]),
                     "search_seconds": (traj.info["search"] or {}).get("time", 0.0), **check})
    return {"rows": rows}


def markdown(r: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    rows = r["rows"]
    seconds = np.array([row["seconds"] for row in rows])
    accepted = [row for row in rows if row["outcome"] != "refused"]
    lines = [
        f"### Agile Eye: {len(rows)} random tasks whose plain path crosses a type 2 singular curve "
        f"(seed {SEED}, margins 10 deg / 1 deg)",
        "",
        "| outcome | tasks | least angle to the singular curves (deg) | least obstacle clearance (deg) | "
        "planning s, median | planning s, max |",
        "|---|---|---|---|---|---|",
    ]
    for outcome, label in (("bent", "bent by windows"), ("search", "global search in SO(3)"),
                           ("refused", "refused")):
        group = [row for row in rows if row["outcome"] == outcome]
        if not group:
            lines.append(f"| {label} | 0 | | | | |")
            continue
        times = np.array([row["seconds"] for row in group])
        if outcome == "refused":
            gap = obstacle = "see below"
        else:
            gap = f"{np.rad2deg(min(row['type2'] for row in group)):.2f}"
            clear = min(row["obstacle"] for row in group)
            obstacle = f"{np.rad2deg(clear):.2f}" if np.isfinite(clear) else "(no obstacle)"
        lines.append(f"| {label} | {len(group)} | {gap} | {obstacle} | {np.median(times):.2f} | {times.max():.2f} |")
    failed = [row["task"] for row in accepted if not row["kept"]]
    search = [row["search_seconds"] for row in rows if row["outcome"] == "search"]
    lines += [
        "",
        f"All tasks: planning time median {np.median(seconds):.2f} s, max {seconds.max():.2f} s"
        + (f"; the global search itself median {np.median(search):.3f} s, max {max(search):.3f} s." if search
           else "."),
        f"Plans handed over that break a margin, cross the type 2 surface (det A changes sign) or miss the start "
        f"or goal by 1e-6 rad, by the exact FK of their own q_ref: {len(failed)}"
        + (f" (tasks {failed})." if failed else "."),
    ]
    lines += [f"- task {row['task']} refused: {row['reason']}" for row in rows if row["outcome"] == "refused"]
    return "\n".join(lines)


if __name__ == "__main__":
    print(markdown(measure()))
