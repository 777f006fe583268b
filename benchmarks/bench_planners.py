"""Path points solved per second by each planner, on one core.

Two measures: the vectorised kernels of papers 000 and 002 on 200,000 points a call (paper 002's also set
against Craig's analytic IK called point by point, the way the paper says IK would otherwise be used, in the
same run; target, issue 3: at least 1e6 points per second), and every planner's whole `plan` on a shipped
scenario, in control samples planned per second: everything the planner does for a run, paper 003's SLSQP
optimisation and paper 001's switch schedule included.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402

import numpy as np  # noqa: E402

from benchmarks.common import shipped  # noqa: E402
from simbench.core.plant import Plant  # noqa: E402
from simbench.maths.paths import Arc  # noqa: E402
from simbench.planners import decoupled_path, safe_straight_path  # noqa: E402
from simbench.robots import puma600  # noqa: E402

REPEATS = 5
PLANS = (("safe_straight_path", "spherical_arm/case1"), ("joint_move", "spherical_arm/case1_joint_move"),
         ("decoupled_path", "puma600/weld_seam"), ("avoidance_4567", "agile_eye/avoidance"),
         ("round_robin", "rsmg/three_turns"))


def _best(fn, repeats: int = REPEATS) -> tuple[float, object]:
    """Fastest of several wall times (the least disturbed by the machine's noise), after a warm-up call whose
    result is returned too."""
    result = fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times), result


def measure(n: int = 200_000, n_loop: int = 2_000) -> dict:
    """Points per second of each method."""
    s = np.linspace(0.0, 1.0, n)
    arc = Arc.from_plane([0.55, -0.1, -0.22], 0.12, [0.5, 0.0, 0.8660254], 0.0, 2 * np.pi)
    rot = np.diag([-1.0, 1.0, -1.0])
    flags = np.array([-1.0, 1.0, -1.0])

    def paper002():
        decoupled_path.solve(arc.point(s), np.broadcast_to(rot, (n, 3, 3)), flags)

    pts = arc.point(s[:n_loop])

    def craig_per_point():
        for p in pts:
            puma600.ik(p[None], rot, flags)

    deg = np.pi / 180
    line = safe_straight_path.build(np.array([120 * deg, 0.005, 120 * deg, 0.015]),
                                    np.array([120 * deg, 0.07, -60 * deg, 0.1]))

    def paper000():
        safe_straight_path.evaluate(line, s)

    (t002, _), (t_ik, _), (t000, _) = _best(paper002), _best(craig_per_point, 3), _best(paper000)
    return {"n": n, "paper002_points_per_s": n / t002, "ik_per_point_points_per_s": n_loop / t_ik,
            "paper000_points_per_s": n / t000, "plans": [_whole_plan(*case) for case in PLANS]}


def _whole_plan(planner: str, scenario: str) -> dict:
    """Control samples a planner's whole `plan` call turns out per second (best of 3)."""
    sc = shipped(scenario)
    dt = float(Plant.load(sc.robot_def, sc.sim.timestep).model.opt.timestep)
    seconds, traj = _best(lambda: sc.planner_def.plan(sc, sc.robot_def, dt), 3)
    return {"planner": planner, "scenario": scenario, "samples": traj.t.size, "seconds": seconds}


def markdown(r: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    ratio = r["paper002_points_per_s"] / r["ik_per_point_points_per_s"]
    return "\n".join([
        f"### Planners: path points solved per second, one core (best of {REPEATS}; {r['n']:,} points a call)",
        "",
        "| method | points/s |",
        "|---|---|",
        f"| paper 002, vectorised (PUMA 600 circle: path, wrist offset, q1..q6) | {r['paper002_points_per_s']:,.0f} |",
        f"| Craig's analytic IK, one point a call (same circle) | {r['ik_per_point_points_per_s']:,.0f} |",
        f"| paper 000, vectorised (spherical arm, Table 2 case 3 line) | {r['paper000_points_per_s']:,.0f} |",
        "",
        f"Paper 002 vectorised / per-point IK: {ratio:,.0f}x. Target: at least 1e6 points/s for paper 002.",
        "",
        "Whole plans (best of 3), control samples planned per second:",
        "",
        "| planner | scenario | samples | seconds | samples/s |",
        "|---|---|---|---|---|",
        *[f"| `{p['planner']}` | `{p['scenario']}` | {p['samples']:,} | {p['seconds']:.4f} | "
          f"{p['samples'] / p['seconds']:,.0f} |" for p in r["plans"]],
    ])


if __name__ == "__main__":
    print(markdown(measure()))
