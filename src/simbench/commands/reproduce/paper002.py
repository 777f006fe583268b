"""Paper 002's joint time histories of a line and a circle for the PUMA 600, and its equations checked by number.

The paper prints its method, no table: q3 from the wrist centre's distance (eqs. 9-19), q1 and q2 after, lines
(eqs. 23-27) and circles (eqs. 28-37). simbench's planner runs it on scenarios/puma600/line.yaml and circle.yaml.
Each equation is checked against an independent truth (Craig's modified DH chain, the quadratic's algebra, the
cubic's end conditions, orthogonality); where one is wrong as printed (docs/papers/002-puma600.md, Errata) a
number shows it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from simbench.commands.pipeline import check_plan
from simbench.commands.reproduce._common import (ERROR, TYPO, Difference, PaperSummary, figure, finish, fmt, save,
                                                 write_table)
from simbench.core.resources import scenarios_dir
from simbench.robots import puma600
from simbench.robots.puma600 import A2, A3, D3, D4, JOINTS, QD_MAX
from simbench.scenario import load_scenario

TITLE = "joint time histories of a line and a circle, PUMA 600"
_SAMPLE = np.deg2rad([30.0, -60.0, -45.0, 0.0, 0.0, 0.0])  # the configuration where single values are shown
_SEED = 2  # of the random configurations the printed forward kinematics is checked on

# The paper's symbols for eq. 9 (eqs. 8-9: f1 = -C3 a4 + S3 b4 + a3), with eq. 1's numbers: its a3 is Craig's
# a2, its a4 Craig's a3, its b4 Craig's d4 (metres).
_P_A3, _P_A4, _P_B4 = 0.432, 0.02, 0.432


def printed_wrist(q: np.ndarray) -> np.ndarray:
    """The wrist centre (N, 3) by eq. 1 exactly as printed (Py's d3 term with a minus sign)."""
    c1, s1, c2, s2, c3, s3 = (f(q[:, i]) for i in (0, 1, 2) for f in (np.cos, np.sin))
    g = 0.02 * c3 - 0.432 * s3 + 0.432
    h = 0.02 * s3 + 0.432 * c3
    px = c1 * c2 * g - c1 * s2 * h - 0.149 * s1
    py = s1 * c2 * g - s1 * s2 * h - 0.149 * c1
    pz = -0.02 * s2 * c3 + 0.432 * s3 * s2 - 0.432 * s2 - c2 * h
    return np.stack([px, py, pz], axis=-1)


def dh_wrist(q: np.ndarray) -> np.ndarray:
    """The wrist centre (N, 3) by Craig's modified DH chain: the origin of frame 4."""
    return puma600.link_frames(q)[0][:, 3]


def printed_eq9(q3: np.ndarray) -> np.ndarray:
    """|P|^2 by eq. 9 as printed: 2 a3 a4 cos q3 + 2 a3 b4 sin q3 + (a4^2 + a3^2 + b4^2)."""
    return 2 * _P_A3 * _P_A4 * np.cos(q3) + 2 * _P_A3 * _P_B4 * np.sin(q3) + (_P_A4**2 + _P_A3**2 + _P_B4**2)


# Eq. 12's A, B, C for the corrected eq. 9: |P|^2 = C + A cos q3 + B sin q3 (docs/papers/002-puma600.md, Errata).
_A, _B, _C = 2 * A2 * A3, -2 * A2 * D4, A2**2 + A3**2 + D4**2 + D3**2


def quadratic_roots(k: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. 14, v^2 (C - A - K) + 2 B v + (A + C - K) = 0 with v = tan(q3/2): its quarter discriminant and both
    roots as q3 (eq. 19), NaN where there are none."""
    a, c = _C - _A - k, _A + _C - k
    disc = _B**2 - a * c
    with np.errstate(invalid="ignore"):
        root = np.sqrt(disc)
        return disc, 2 * np.arctan((-_B + root) / a), 2 * np.arctan((-_B - root) / a)


def printed_rotation(alpha: float, theta: float) -> np.ndarray:
    """Eq. 32's rotation matrix as printed (its last row: sin a sin t, sin a sin t, cos a)."""
    ca, sa, ct, st = np.cos(alpha), np.sin(alpha), np.cos(theta), np.sin(theta)
    return np.array([[ct, -st, 0.0], [ca * st, ca * ct, -sa], [sa * st, sa * st, ca]])


def printed_circle(center: np.ndarray, radius: float, alpha: float, theta: float, u: np.ndarray) -> np.ndarray:
    """Eq. 36: the circle's points (N, 3) for parameter values u."""
    ca, sa, ct, st = np.cos(alpha), np.sin(alpha), np.cos(theta), np.sin(theta)
    cu, su = np.cos(u), np.sin(u)
    return center + radius * np.stack([ct * cu - st * su, st * cu * ca + ct * su * ca,
                                       cu * sa * st + ct * su * sa], axis=-1)


def _plan(name: str):
    scenario = load_scenario(scenarios_dir() / "puma600" / f"{name}.yaml")
    traj, verdict = check_plan(scenario)
    return scenario, traj, verdict


def _checks(plans: dict) -> tuple[list[list[str]], list[Difference], int]:
    """Every equation checked: table rows, the differences, how many reproduced."""
    rows, diffs, reproduced = [], [], 0

    def ok(eq: str, claim: str, number: str) -> None:
        nonlocal reproduced
        reproduced += 1
        rows.append([eq, claim, "reproduced", number])

    def bad(kind: str, eq: str, claim: str, printed: str, ours: str, number: str) -> None:
        rows.append([eq, claim, kind, number])
        diffs.append(Difference(kind, eq, printed, ours, number))

    rng = np.random.default_rng(_SEED)
    q = rng.uniform(-np.pi, np.pi, (1000, 6))
    dh, pr = dh_wrist(q), printed_wrist(q)
    # eq. 1
    err_xz = float(np.abs(pr[:, [0, 2]] - dh[:, [0, 2]]).max())
    ok("eq. 1, Px and Pz", "the wrist centre of the PUMA 600", f"printed Px, Pz against Craig's modified DH chain "
       f"(a2 = 0.432, a3 = 0.02, d3 = 0.149, d4 = 0.432 m) at 1000 random configurations: {err_xz:.1e} m at most")
    err_y = float(np.abs(pr[:, 1] - dh[:, 1]).max())
    fixed = pr[:, 1] + 2 * 0.149 * np.cos(q[:, 0])
    spread = printed_wrist(np.array([[0.0, *_SAMPLE[1:]], [np.pi / 4, *_SAMPLE[1:]]]))
    bad(TYPO, "eq. 1, Py", "the wrist centre of the PUMA 600", "... - 0.149 cos q1", "... + 0.149 cos q1",
        f"printed Py is off the DH chain's by up to {err_y:.3f} m (2 d3 |cos q1|); with + 0.149 cos q1, "
        f"{np.abs(fixed - dh[:, 1]).max():.1e} m. As printed |P| would depend on q1, against the method: |P|^2 = "
        f"{np.sum(spread[0] ** 2):.4f} at q1 = 0 and {np.sum(spread[1] ** 2):.4f} m^2 at q1 = 45 deg (q2, q3 the same)")
    # eq. 9
    q3s = np.linspace(-np.pi, np.pi, 3601)
    true_k = np.sum(dh_wrist(np.column_stack([np.zeros((q3s.size, 2)), q3s, np.zeros((q3s.size, 3))])) ** 2, axis=1)
    k0 = float(np.sum(dh_wrist(_SAMPLE[None]) ** 2))
    p0 = float(printed_eq9(_SAMPLE[2:3])[0])
    sign_fixed = printed_eq9(q3s) - 4 * _P_A3 * _P_B4 * np.sin(q3s)
    bad(ERROR, "eq. 9", "|P|^2 = 2 a3 a4 cos q3 + 2 a3 b4 sin q3 + a4^2 + a3^2 + b4^2",
        "+ 2 a3 b4 sin q3, no d3^2", "- 2 a2 d4 sin q3 + d3^2",
        f"at q3 = -45 deg the printed eq. 9 gives {p0:.4f} m^2, the DH chain {k0:.4f} m^2; over all q3 it is off by "
        f"up to {np.abs(printed_eq9(q3s) - true_k).max():.4f} m^2; with the sine's sign fixed it still misses "
        f"d3^2 = {np.abs(sign_fixed - true_k).max():.4f} m^2 everywhere")
    # eqs. 12-14 with the corrected coefficients
    q3r = rng.uniform(-np.pi, np.pi, 1000)
    kr = np.sum(dh_wrist(np.column_stack([np.zeros((1000, 2)), q3r, np.zeros((1000, 3))])) ** 2, axis=1)
    _, r1, r2 = quadratic_roots(kr)
    wrap = lambda d: np.abs(np.angle(np.exp(1j * d)))  # noqa: E731
    err_q3 = float(np.minimum(wrap(r1 - q3r), wrap(r2 - q3r)).max())
    ok("eqs. 12-14, 19", "q3 from the wrist centre's distance: a quadratic in v = tan(q3/2)",
       f"with the corrected eq. 9, one root of eq. 14 gives back q3 at 1000 random values to {err_q3:.1e} rad")
    # eq. 15
    reach = np.sqrt(_C + np.hypot(_A, _B))
    k_far = (reach + 0.1) ** 2
    disc_far = float(quadratic_roots(np.array([k_far]))[0][0])
    printed_delta = (2 * _P_A3 * _P_B4) ** 2 + (2 * _P_A3 * _P_A4 + (_P_A4**2 + _P_A3**2 + _P_B4**2) - k_far) ** 2
    bad(ERROR, "eq. 15", "two real roots for any A, B, C, K: any line or circle can be followed",
        "Delta = B^2 + (A + C - K)^2 > 0", "B^2 - (C - A - K)(A + C - K), >= 0 only within reach",
        f"0.1 m beyond the wrist's reach ({reach:.4f} m) the true discriminant is {disc_far:.4f} (no real root: "
        f"the point cannot be reached) while the printed Delta is {printed_delta:.4f} > 0")
    # eq. 16
    a, c = _C - _A - k0, _A + _C - k0
    bad(ERROR, "eq. 16", "the product of the roots v1 v2 = -1", "-1", "(A + C - K) / (C - A - K)",
        f"at the configuration q2 = -60, q3 = -45 deg (K = {k0:.4f} m^2) the roots' product is {c / a:.4f}")
    # eqs. 20-21, along the line
    _, traj, _ = plans["line"]
    k_line = np.sum(dh_wrist(traj.q_ref) ** 2, axis=1)
    _, l1, l2 = quadratic_roots(k_line)
    gap = np.rad2deg(np.angle(np.exp(1j * (l1 - l2))))
    bad(ERROR, "eqs. 20-21", "the two solutions differ by a constant, so either may be taken", "q3' = q3 + pi",
        "the elbow-up and elbow-down q3 differ by a varying angle",
        f"along scenarios/puma600/line.yaml the two roots' q3 differ by {np.abs(gap).min():.2f} to "
        f"{np.abs(gap).max():.2f} deg: they are the elbow's two sides, not one history shifted")
    # eqs. 24-25
    bad(ERROR, "eqs. 24-25", "u(0) = 0, u(1) = 1, zero end velocities", "u(t') = 2 t'^3 - 3 t'^2",
        "u(t') = 3 t'^2 - 2 t'^3",
        f"the printed cubic gives u(1) = {2 - 3:.0f} and u(0.5) = {2 * 0.125 - 3 * 0.25:.2f}: "
        "the line would be run backwards from M1; 3 t'^2 - 2 t'^3 gives u(1) = 1")
    # eq. 32
    alpha, theta = np.deg2rad(30.0), np.deg2rad(40.0)
    r = printed_rotation(alpha, theta)
    r_fixed = r.copy()
    r_fixed[2, 1] = np.sin(alpha) * np.cos(theta)
    bad(TYPO, "eq. 32", "the rotation matrix of the circle's plane", "last row: sin a sin t, sin a sin t, cos a",
        "sin a sin t, sin a cos t, cos a",
        f"at alpha = 30, theta = 40 deg the printed matrix has |R^T R - I| = {np.abs(r.T @ r - np.eye(3)).max():.3f} "
        f"and det {np.linalg.det(r):.3f}; with sin a cos t it is a rotation "
        f"({np.abs(r_fixed.T @ r_fixed - np.eye(3)).max():.0e}), "
        "and eq. 33 already uses sin a cos t")
    # eq. 36 and the normals it can give
    u = np.linspace(0.0, 2 * np.pi, 721)
    center = np.array([0.55, -0.1, -0.22])
    pts = printed_circle(center, 0.12, alpha, theta, u)
    normal = r_fixed[:, 2]
    plane = float(np.abs((pts - center) @ normal).max())
    radius = float(np.abs(np.linalg.norm(pts - center, axis=1) - 0.12).max())
    ok("eqs. 33-36", "the circle of centre O1 and radius R in the plane of normal O1Z2",
       f"eq. 36's points lie on the circle to {radius:.1e} m and in the plane of normal R e_z to {plane:.1e} m")
    circle_normal = np.array(plans["circle"][0].task.path[0].arc.normal)
    bad(ERROR, "eqs. 31-36", "a circle of any centre, radius and normal n = [nx, ny, nz]", "alpha and theta",
        "a plane normal in any direction",
        f"the plane's normal R e_z = (0, -sin a, cos a) has nx = 0 for every alpha, theta (theta only turns the "
        f"start point within the plane): circle.yaml's normal ({circle_normal[0]:.3f}, {circle_normal[1]:.3f}, "
        f"{circle_normal[2]:.3f}) cannot be given; simbench takes the normal itself")
    # the time histories (eq. 22): their forward kinematics on the path
    for name in ("line", "circle"):
        _, traj, verdict = plans[name]
        err = float(np.linalg.norm(puma600.fk(traj.q_ref) - traj.tool_ref, axis=1).max())
        ok(f"eq. 22, the {name}", f"time histories q1(t) ... q6(t) that put the tool on the {name}",
           f"the forward kinematics of the {traj.t.size} samples is within {err:.1e} m of the path "
           f"(plan status {verdict.status})")
    return rows, diffs, reproduced


def _histories(folder: Path, plans: dict) -> tuple[list[str], list[list[str]]]:
    """{line,circle}_joints.csv (every 10 ms) and .png; rows of joints.md (each joint's span and peak speed)."""
    files, summary_rows = [], []
    for name, (scenario, traj, verdict) in plans.items():
        q, qd = np.rad2deg(traj.q_ref), np.rad2deg(traj.qd_ref)
        step = max(1, int(round(0.01 / (traj.t[1] - traj.t[0]))))
        rows = [[f"{t:.3f}", *(f"{v:.4f}" for v in qk)] for t, qk in zip(traj.t[::step], q[::step])]
        header = ("t (s)",) + tuple(f"{j} (deg)" for j in JOINTS)
        with open(folder / f"{name}_joints.csv", "w") as f:
            f.write(",".join(header) + "\n" + "\n".join(",".join(r) for r in rows) + "\n")
        files.append(f"{name}_joints.csv")
        for j, joint in enumerate(JOINTS):
            summary_rows.append([name, joint, fmt(q[:, j].min(), 2), fmt(q[:, j].max(), 2),
                                 fmt(np.abs(qd[:, j]).max(), 1), fmt(np.rad2deg(QD_MAX[j]), 0)])
        fig, axes = figure(2, 1, sharex=True)
        for j, joint in enumerate(JOINTS):
            axes[0 if j < 3 else 1].plot(traj.t, q[:, j], label=joint)
        for ax, what in zip(axes, ("arm joints q1-q3", "wrist joints q4-q6")):
            ax.set_ylabel(f"{what} (deg)")
            ax.grid(alpha=0.3)
            ax.legend(loc="best", fontsize=8)
            ax.axvspan(scenario.timing.duration, traj.t[-1], color="0.9", lw=0)
        axes[1].set_xlabel("time (s)  (shaded: the hold after the path)")
        config = traj.info["configuration"]["chosen"]
        fig.suptitle(f"Paper 002's method on scenarios/puma600/{name}.yaml ({config}): joint time histories")
        files.append(save(fig, folder / f"{name}_joints.png"))
    return files, summary_rows


def _equations_figure(folder: Path) -> str:
    """Eq. 9 as printed against the DH chain's |P|^2, and the printed cubic of eq. 24 against 3t^2 - 2t^3."""
    q3 = np.linspace(-np.pi, np.pi, 721)
    truth = np.sum(dh_wrist(np.column_stack([np.zeros((q3.size, 2)), q3, np.zeros((q3.size, 3))])) ** 2, axis=1)
    fig, (ax1, ax2) = figure(1, 2)
    ax1.plot(np.rad2deg(q3), truth, label="|P|^2 of the DH chain (corrected eq. 9)")
    ax1.plot(np.rad2deg(q3), printed_eq9(q3), "--", label="eq. 9 as printed")
    ax1.set_xlabel("q3 (deg)")
    ax1.set_ylabel("|P|^2 (m^2)")
    ax1.legend(fontsize=8)
    ax1.grid(alpha=0.3)
    t = np.linspace(0.0, 1.0, 201)
    ax2.plot(t, 3 * t**2 - 2 * t**3, label="3 t^2 - 2 t^3 (u(0) = 0, u(1) = 1)")
    ax2.plot(t, 2 * t**3 - 3 * t**2, "--", label="eq. 24 as printed: 2 t^3 - 3 t^2")
    ax2.set_xlabel("t' = t / tm")
    ax2.set_ylabel("u")
    ax2.legend(fontsize=8)
    ax2.grid(alpha=0.3)
    fig.suptitle("Paper 002: eq. 9 and eq. 24 as printed, against the truth")
    return save(fig, folder / "equations.png")


def reproduce(folder: Path) -> PaperSummary:
    """Write paper 002's time histories, equation checks and figures into `folder`; its part of the summary."""
    plans = {name: _plan(name) for name in ("line", "circle")}
    rows, diffs, reproduced = _checks(plans)
    files = write_table(folder, "equations", ("equation", "what the paper says", "status", "shown by"), rows,
                        "Paper 002: each equation checked by a number")
    hist_files, joint_rows = _histories(folder, plans)
    files += hist_files
    files += write_table(folder, "joints", ("path", "joint", "min (deg)", "max (deg)", "peak speed (deg/s)",
                                            "speed limit (deg/s)"), joint_rows,
                         "Paper 002's method on the line and the circle: each joint's span and peak speed",
                         notes=["line.yaml: a 0.54 m straight seam at 0.25 m/s, torch vertical; circle.yaml: a full "
                                "circle of radius 120 mm in a plane tilted 30 deg, torch normal to it (trapezoidal "
                                "law). The histories themselves: line_joints.csv, circle_joints.csv (every 10 ms)."])
    files.append(_equations_figure(folder))
    worst = max(float(np.linalg.norm(puma600.fk(t.q_ref) - t.tool_ref, axis=1).max()) for _, t, _ in plans.values())
    headline = (f"line and circle: joint time histories of all six joints (figures line_joints.png, "
                f"circle_joints.png), the tool on the path to {worst:.1e} m",
                f"equations: {reproduced} reproduced, {sum(d.kind == TYPO for d in diffs)} typos (eq. 1's Py, eq. "
                f"32), {sum(d.kind == ERROR for d in diffs)} errors (eqs. 9, 15, 16, 20-21, 24-25, 31-36)")
    part = PaperSummary("002", TITLE, len(rows), reproduced, tuple(diffs), headline,
                        facts={"tool_on_path_max": worst})
    return finish(folder, part, files, "Paper 002: every difference, classified", notes=[
        "The paper's symbols for eq. 9 read with eq. 1's numbers: its a3 = 0.432 m (Craig's a2), a4 = 0.02 m "
        "(Craig's a3), b4 = 0.432 m (Craig's d4); d3 = 0.149 m is missing from it.",
        "simbench solves q3 from the corrected eq. 9 (paper 002's errata in simbench's docs), keeps the "
        "elbow's side the configuration names, and times lines and circles by the scenario's law (not the "
        "printed cubic)."])
