"""Paper 003's trajectory optimisation for the Agile Eye: a 4-5-6-7 joint path bent around obstacles and
type 2 singularities by smooth bumps whose parameters SLSQP finds.

  1. The start and goal orientations give the base angles by IK in the chosen working mode; each joint goes
     theta_j(t) = theta_j_init + (theta_j_final - theta_j_init) S(t / T) with S = 35 tau^4 - 84 tau^5
     + 70 tau^6 - 20 tau^7 (eqs. 8-10): zero velocity, acceleration and jerk at both ends.
  2. Along the path the platform orientation is estimated (by the learnt FK, as the paper does, or exactly),
     and so the clearance from every obstacle (a ball of orientations: geodesic angle to its centre minus its
     radius) and from the type 2 singular curves (the angle between some v_i and u_i); a floor on the KCI may
     be set too, since near the singular curves the platform magnifies joint errors by about 1 / KCI.
  3. Where a clearance falls below its margin, a bump is added over a window of T* seconds centred on the
     worst sample: theta_j += c_j L b((t - t0) / T*), b(tau) = 256 tau^4 (1 - tau)^4, whose value and first
     three derivatives vanish at both ends of the window (the role of S*(tau*) in eqs. 11-12, whose printed
     form is lost). (c_1, c_2, c_3) = (alpha, beta, gamma) is a unit direction and L the amplitude (rad);
     scipy's SLSQP chooses them to maximise the path's mean KCI less a small cost on L, subject to every
     clearance staying above its margin over the whole path (sections 6-7). SLSQP is given the gradients
     analytically (project issue 14): the KCI's and each clearance's partial derivatives in the base angles and
     in the platform's rotation (agile_eye.kci_partials, axis_gap_partials, _angle_partial), pulled back through
     the estimate's own derivative (the network's by reverse mode, the exact FK's A^-1 B) and the bump; the KCI
     is computed in closed form (agile_eye.kci_closed_form, within 1e-13 of agile_eye.kci).
  4. Repeat for the next violation, up to max_windows; then check the result with the exact FK.

Two additions of ours (project issue 19):
  5. Where the bent path still breaks a margin (a plain path across a type 2 curve is rarely saved by windows:
     they are too short to go round it), a global search in SO(3) (so3_search: RRT-Connect, shortcuts, corners
     rounded) finds an orientation path that keeps every margin; it is timed by the same 4-5-6-7 law over the
     scenario's duration, by its geodesic angle, and the joints follow it by IK in the task's working mode. No
     window or SLSQP start is begun once half of task.avoidance.time_budget is spent; the search gets the rest
     of the budget, and at least half of it (a slower machine may so stop with fewer windows). If no path
     keeps the margins, the planner refuses (RunError) naming the margins and the best clearances found, unless
     task.accept_margin_violation hands over the best path anyway, with warnings and, where its platform
     passes the type 2 singular surface or ends away from the goal (by the exact FK), the violations
     singular_crossing and goal_missed (simbench.verdict), so that such a run is never `ok` (a margin
     short of that, an obstacle's or the KCI's, stays a warning: the verdict has no kind for it).
     One assembly mode throughout: det A (with theta the IK of R in a fixed working mode) has one sign over all
     of SO(3) off the singular curves (IK is continuous there, det A vanishes only on the curves, and the curves
     do not cut SO(3) apart), so a path that keeps away from the curves keeps the start's assembly mode; the
     final plan is checked for it all the same (det A's sign along the exact FK of the sampled joints).
  6. The plan carries every joint of the closed chain, the passive ones included, assembled at the start
     orientation (JointTrajectory.initial): the robot's own assembly picks the FK solution nearest home, which
     for most start orientations is another assembly mode.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Annotated, Literal

import numpy as np
from pydantic import Field

from simbench.planners import learnt_fk
from simbench.api import Decoration, Planner
from simbench.errors import RunError
from simbench.robots import agile_eye
from simbench.rotations import matrix_to_quat, rotation_angle
from simbench.schema import NonNegativeAngle, Orientation, PositiveAngle, SimbenchModel, Weight, seconds
from simbench.timing import TimeLaw
from simbench.trajectory import JointTrajectory, control_grid

_COARSE = 201  # samples of the whole path on which violations are found
_WINDOW_SAMPLES = 101  # samples of a window on which SLSQP judges a candidate
_SAFETY = np.deg2rad(0.1)  # kept above each margin on the window's samples, so the dense path keeps the margin
_STEP = 1e-3  # rad: finite-difference step of the clearance gradient that seeds SLSQP
_MAX_AMPLITUDE = np.pi / 4
_SEARCH_STEP = np.deg2rad(0.5)  # rotation angle between the states the global search checks along a motion
_ENDS = 1e-6  # rad: how near the exact FK of the last joint sample must come to the goal orientation
_ON_CURVE = 1e-6  # rad: a platform axis this near its base axis is on a singular curve
_ANALYTIC_GRADIENTS = True  # SLSQP gets the analytic gradients of _WindowFit (off: its finite differences)


class Obstacle(SimbenchModel):
    """A region of orientations the platform must stay out of: all within `radius` of `center`."""

    name: str = ""
    center: Orientation
    radius: PositiveAngle


class Avoidance(SimbenchModel):
    """How the path is bent: window length T*, how many windows at most, which FK estimates clearances."""

    enabled: bool = True
    window: seconds(0.01, 3600.0) = 1.0
    max_windows: int = Field(4, ge=1, le=20)
    estimator: Literal["network", "exact"] = "network"
    deviation_weight: Weight = 0.1
    time_budget: seconds(0.0, 600.0, low_open=True) = Field(
        10.0, description="seconds of planning: windows for about half, the global search for the rest")


class Task(SimbenchModel):
    """`task:` of paper 003's planner."""

    start: Orientation
    goal: Orientation
    working_mode: int = Field(0, ge=0, le=7)
    obstacles: list[Obstacle] = []
    singularity_clearance: PositiveAngle = float(np.deg2rad(10.0))
    kci_min: Annotated[float, Field(ge=0, lt=1)] = 0.0
    obstacle_clearance: NonNegativeAngle = 0.0
    avoidance: Avoidance = Avoidance()
    accept_margin_violation: bool = Field(
        False, description="hand over the best path found, with warnings, when none keeps the margins (a "
                           "singular crossing included) instead of refusing to run")


def bump(tau: np.ndarray, order: int = 0) -> np.ndarray:
    """b(tau) = 256 tau^4 (1 - tau)^4 on [0, 1], zero outside, or its derivative of the given order (in tau)."""
    coef = 256 * np.polynomial.polynomial.polypow([0.0, 1.0, -1.0], 4)  # 256 (tau - tau^2)^4
    inside = (tau > 0) & (tau < 1)
    return np.where(inside, np.polynomial.polynomial.polyval(tau, np.polynomial.polynomial.polyder(coef, order)), 0.0)


@dataclass(frozen=True)
class Window:
    """One bump: start time, length T*, direction (alpha, beta, gamma), amplitude L (rad)."""

    t0: float
    length: float
    direction: np.ndarray
    amplitude: float

    def offset(self, t: np.ndarray, order: int = 0) -> np.ndarray:
        """Its contribution (N, 3) to the joint angles, or their derivative of the given order in t."""
        tau = (t - self.t0) / self.length
        return (self.amplitude * bump(tau, order) / self.length**order)[:, None] * self.direction


@dataclass(frozen=True)
class Plan:
    """The base 4-5-6-7 path plus its windows."""

    theta_init: np.ndarray
    theta_final: np.ndarray
    law: TimeLaw
    windows: tuple[Window, ...] = ()

    def theta(self, t: np.ndarray, order: int = 0) -> np.ndarray:
        """Joint angles (N, 3) at times t, or their time derivative of the given order (up to 3)."""
        out = self.law(t, order=order)[order][:, None] * (self.theta_final - self.theta_init)
        if order == 0:
            out = out + self.theta_init
        for w in self.windows:
            out = out + w.offset(t, order)
        return out

    def with_window(self, window: Window) -> Plan:
        """This plan with one more window."""
        return replace(self, windows=self.windows + (window,))


def _obstacle_names(task: Task) -> list[str]:
    """Each obstacle's name in the clearances and margins: its own, or obstacle<k> counting from 1."""
    return [obstacle.name or f"obstacle{k + 1}" for k, obstacle in enumerate(task.obstacles)]


def _centers(task: Task) -> list[np.ndarray]:
    """Each obstacle's centre as a rotation matrix (3, 3), read-only (Orientation.matrix, computed once)."""
    return [_matrix(o.center.convention, tuple(o.center.value)) for o in task.obstacles]


@lru_cache(maxsize=256)
def _matrix(convention: str, value: tuple[float, ...]) -> np.ndarray:
    """Orientation.matrix of an orientation given by its fields, kept: scipy takes about 0.1 ms for one."""
    out = Orientation.model_construct(convention=convention, value=list(value)).matrix()  # already validated
    out.flags.writeable = False
    return out


def clearances(task: Task, theta: np.ndarray, rot: np.ndarray,
               kci: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Clearance (rad) of each obstacle and of the singular curves along orientations (N, 3, 3), positive
    outside, negative inside; and the KCI (agile_eye.kci_closed_form, or `kci` if given) where the task sets a
    floor on it."""
    out = {}
    if task.kci_min > 0:
        out["kci"] = agile_eye.kci_closed_form(theta, rot) if kci is None else kci
    for name, obstacle, center in zip(_obstacle_names(task), task.obstacles, _centers(task)):
        out[name] = rotation_angle(np.broadcast_to(center, rot.shape), rot) - obstacle.radius
    out["type2"] = agile_eye.axis_gaps(rot).min(axis=1)
    return out


def margins(task: Task) -> dict[str, float]:
    """The clearance each constraint must keep."""
    out = dict.fromkeys(_obstacle_names(task), task.obstacle_clearance)
    out["type2"] = task.singularity_clearance
    if task.kci_min > 0:
        out["kci"] = task.kci_min
    return out


class _Estimator:
    """Platform orientations along a stretch of joint path: the learnt FK of the working mode, or the exact FK
    followed continuously from the orientation `anchor` at the stretch's first sample."""

    def __init__(self, kind: str, mode: int):
        self.kind, self.mode = kind, mode
        self.network = learnt_fk.load() if kind == "network" else None

    def __call__(self, theta: np.ndarray, anchor: np.ndarray) -> np.ndarray:
        if self.network is not None:
            return self.network(theta, self.mode)
        return _platform(theta, anchor)[0]

    def estimate(self, theta: np.ndarray, anchor: np.ndarray) -> tuple[np.ndarray, list | None]:
        """The orientations, as calling this gives them, and what `pull` reuses (the network's layers)."""
        if self.network is not None:
            return self.network.forward(theta, self.mode)
        return self(theta, anchor), None

    def pull(self, theta: np.ndarray, rot: np.ndarray, layers: list | None, torque: np.ndarray) -> np.ndarray:
        """The gradient in the base angles (N, 3) of quantities whose derivatives in the platform's rotation are
        `torque` (N, 3), each at its own sample: torque^T (d omega / d theta) of the estimate, the network's own
        derivative (reverse mode) or the exact FK's (A^-1 B, zero where A is singular)."""
        if self.network is not None:
            return self.network.rates_vjp(theta, self.mode, torque, layers, rot)
        rates = np.nan_to_num(agile_eye.platform_rates(theta, rot), nan=0.0, posinf=0.0, neginf=0.0)
        return np.einsum("nc,ncj->nj", torque, rates)


def _score(plan: Plan, t: np.ndarray, estimate: _Estimator, anchor: np.ndarray,
           task: Task) -> tuple[float, dict[str, float]]:
    """Mean KCI and the worst clearance minus margin of each constraint, for a candidate plan over times t."""
    theta = plan.theta(t)
    rot = estimate(theta, anchor)
    need = margins(task)
    clear = clearances(task, theta, rot)
    slack = {name: float(c.min() - need[name]) for name, c in clear.items()}
    kci = clear["kci"] if "kci" in clear else agile_eye.kci_closed_form(theta, rot)
    return float(kci.mean()), slack


def _seeds(plan: Plan, t_worst: float, name: str, task: Task, estimate: _Estimator,
           anchor: np.ndarray) -> list[np.ndarray]:
    """Starting directions for SLSQP: the gradient of the violated clearance in the joint angles at its worst
    instant (where the window peaks; `anchor` is the orientation there), and the two joint axes nearest it."""
    theta = plan.theta(np.array([t_worst]))[0]
    probes = theta + np.vstack([np.zeros(3), _STEP * np.eye(3)])
    clear = clearances(task, probes, np.stack([estimate(p[None], anchor)[0] for p in probes]))[name]
    grad = (clear[1:] - clear[0]) / _STEP
    direction = grad / max(np.linalg.norm(grad), 1e-12)
    axes = np.argsort(-np.abs(direction))[:2]
    return [direction] + [np.sign(direction[a]) * np.eye(3)[a] for a in axes]


@dataclass(frozen=True)
class _Violation:
    """The constraint whose clearance falls furthest below its margin along a plan, the time of its worst sample
    and the platform orientation there (exact FK)."""

    name: str
    t_worst: float
    rot: np.ndarray


@dataclass
class _Evaluation:
    """A candidate window's path on the window's samples: joint angles, estimated orientations (and the network's
    layers), clearances (N,) by name, the KCI with its terms, mean KCI and each clearance's worst minus its
    margin; the gradients once asked."""

    theta: np.ndarray
    rot: np.ndarray
    layers: list | None
    clear: dict[str, np.ndarray]
    kci: agile_eye.KciTerms
    mean_kci: float
    slack: dict[str, float]
    gradients: tuple[np.ndarray, dict[str, np.ndarray]] | None = None


def _angle_partial(center: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """Derivative (N, 3) of the geodesic angle between `center` (3, 3) and orientations rot (N, 3, 3) in the
    platform's rotation: cos = (tr(C^T R) - 1) / 2 and dR = [omega]x R give d cos = omega . m / 2, m the axial
    vector of R C^T less its transpose."""
    m = rot @ center.T
    cos = (np.einsum("ij,nij->n", center, rot) - 1) / 2
    axial = np.stack([m[:, 1, 2] - m[:, 2, 1], m[:, 2, 0] - m[:, 0, 2], m[:, 0, 1] - m[:, 1, 0]], axis=-1)
    return -0.5 * axial / np.sqrt(np.maximum(1.0 - np.clip(cos, -1.0, 1.0) ** 2, 1e-300))[:, None]


class _WindowFit:
    """SLSQP's problem for a new window at t0 (x = alpha, beta, gamma, L): the plan with it, judged on the
    window's own samples, since a window changes the path only within itself (`anchor`: the orientation at t0,
    where the exact FK starts following the mode). The plan without the window is evaluated once on those
    samples; each x's path, estimate and clearances are cached, as the objective and every constraint ask for the
    same x, and so are their gradients (analytic: the chain x -> theta -> estimated orientation -> clearance or
    KCI, _gradients), asked for at the points already evaluated."""

    def __init__(self, plan: Plan, t0: float, task: Task, estimate: _Estimator, anchor: np.ndarray):
        self.plan, self.t0, self.task, self.estimate, self.anchor = plan, t0, task, estimate, anchor
        self.length = task.avoidance.window
        self.t = np.linspace(t0, t0 + self.length, _WINDOW_SAMPLES)
        self.share = self.length / plan.law.duration  # the window's part of the path's mean KCI
        self.base = plan.theta(self.t)  # the plan without the new window: plan.with_window(w).theta(t) - offset
        self.bump = bump((self.t - t0) / self.length)
        self.need = margins(task)
        self.centers = dict(zip(_obstacle_names(task), _centers(task)))
        self.cache: dict[bytes, _Evaluation] = {}

    def window(self, x: np.ndarray) -> Window:
        """The window x stands for, its direction made a unit vector."""
        return Window(self.t0, self.length, x[:3] / max(np.linalg.norm(x[:3]), 1e-12), float(x[3]))

    def evaluate(self, x: np.ndarray) -> _Evaluation:
        """The path with the window x on the window's samples (as _score judges plan.with_window(window(x)))."""
        key = x.tobytes()
        if key not in self.cache:
            window = self.window(x)  # its offset, as Window.offset gives it, from the bump kept
            theta = self.base + (window.amplitude * self.bump)[:, None] * window.direction
            rot, layers = self.estimate.estimate(theta, self.anchor)
            kci = agile_eye.kci_terms(theta, rot)
            clear = clearances(self.task, theta, rot, kci.kci)
            self.cache[key] = _Evaluation(theta, rot, layers, clear, kci, float(kci.kci.mean()),
                                          {name: float(c.min() - self.need[name]) for name, c in clear.items()})
        return self.cache[key]

    def score(self, x: np.ndarray) -> tuple[float, dict[str, float]]:
        """_score of the plan with the window x."""
        e = self.evaluate(x)
        return e.mean_kci, e.slack

    def objective(self, x: np.ndarray) -> float:
        """What SLSQP minimises: -(the window's share of the path's mean KCI) + w L^2."""
        return -self.share * self.score(x)[0] + self.task.avoidance.deviation_weight * x[3] ** 2

    def _gradients(self, x: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Gradients in x (4,) of the objective and of each constraint's worst clearance (at its worst sample).
        Each quantity's partial derivatives in theta (platform held) and in the platform's rotation are pulled
        back to theta through the estimate's own derivative (_Estimator.pull), then to x: theta = base +
        L b(tau) n, n = d / |d| (d = x[:3]), so d theta / d d = L b (I - n n^T) / |d| and d theta / dL = b n."""
        e = self.evaluate(x)
        if e.gradients is None:
            norm = max(np.linalg.norm(x[:3]), 1e-12)
            n, amplitude = x[:3] / norm, float(x[3])
            _, d_theta, d_omega = agile_eye.kci_partials(e.theta, e.rot, e.kci)
            rows, direct, torque = [np.arange(len(self.t))], [d_theta], [d_omega]
            for name, c in e.clear.items():  # each constraint at its worst sample
                k = int(np.argmin(c))
                rows.append(np.array([k]))
                if name == "kci":
                    direct.append(d_theta[k:k + 1])
                    torque.append(d_omega[k:k + 1])
                    continue
                direct.append(np.zeros((1, 3)))
                if name == "type2":
                    gaps, d_gaps = agile_eye.axis_gap_partials(e.rot[k:k + 1])
                    torque.append(d_gaps[:, int(np.argmin(gaps[0]))])
                else:
                    torque.append(_angle_partial(self.centers[name], e.rot[k:k + 1]))
            index = np.concatenate(rows)
            layers = None if e.layers is None else [layer[index] for layer in e.layers]
            g_theta = np.concatenate(direct) + self.estimate.pull(e.theta[index], e.rot[index], layers,
                                                                  np.concatenate(torque))
            b = self.bump[index]
            g_x = np.concatenate([amplitude * b[:, None] * (g_theta @ ((np.eye(3) - np.outer(n, n)) / norm)),
                                  (b * (g_theta @ n))[:, None]], axis=1)
            samples = len(self.t)
            objective = -self.share * g_x[:samples].mean(axis=0)
            objective[3] += 2 * self.task.avoidance.deviation_weight * amplitude
            e.gradients = (objective, dict(zip(e.clear, g_x[samples:])))
        return e.gradients

    def objective_gradient(self, x: np.ndarray) -> np.ndarray:
        """The objective's gradient (4,)."""
        return self._gradients(x)[0]

    def constraints(self) -> list[dict]:
        """(alpha, beta, gamma) a unit vector, and every clearance _SAFETY above its margin, with their
        gradients (finite differences by SLSQP where _ANALYTIC_GRADIENTS is off)."""
        unit = {"type": "eq", "fun": lambda x: x[:3] @ x[:3] - 1.0}
        keep = [{"type": "ineq", "fun": lambda x, n=name: self.score(x)[1][n] - _SAFETY} for name in self.need]
        if _ANALYTIC_GRADIENTS:
            unit["jac"] = lambda x: np.array([2 * x[0], 2 * x[1], 2 * x[2], 0.0])
            for con, name in zip(keep, self.need):
                con["jac"] = lambda x, n=name: self._gradients(x)[1][n]
        return [unit] + keep


def _optimise_window(plan: Plan, t0: float, worst: _Violation, task: Task, estimate: _Estimator,
                     anchor: np.ndarray, deadline: float) -> tuple[Window, bool]:
    """(alpha, beta, gamma, L) of a new window at t0 by SLSQP (_WindowFit): maximise the path's mean KCI - w L^2,
    every clearance kept. Each seed direction (_seeds, at the violation's worst instant) is tried (no further one
    once the clock passes `deadline`); the best feasible result wins (else the one that misses least). Returns
    the window and whether it is feasible."""
    from scipy.optimize import minimize  # imported when planned, not when registered (47 MB, 0.4 s)

    fit = _WindowFit(plan, t0, task, estimate, anchor)
    constraints = fit.constraints()
    best = None
    for seed in _seeds(plan, worst.t_worst, worst.name, task, estimate, worst.rot):
        if best is not None and time.perf_counter() > deadline:
            break
        result = minimize(fit.objective, np.array([*seed, 0.2]), method="SLSQP",
                          jac=fit.objective_gradient if _ANALYTIC_GRADIENTS else None,
                          bounds=[(-1, 1)] * 3 + [(0, _MAX_AMPLITUDE)], constraints=constraints,
                          options={"maxiter": 40, "ftol": 1e-6})
        slack = min(fit.score(result.x)[1].values()) - _SAFETY
        # Feasible candidates rank by their objective, the others by how far they miss.
        rank = (True, -result.fun) if slack >= -1e-6 else (False, slack)
        if best is None or rank > best[0]:
            best = (rank, result.x)
    return fit.window(best[1]), best[0][0]


def _plain_plan(task: Task, law: TimeLaw) -> Plan:
    """The 4-5-6-7 joint path (eqs. 8-10) from the IK of the start to that of the goal in the working mode, each
    joint the shorter way round."""
    theta_init = agile_eye.ik(task.start.matrix(), task.working_mode)[0]
    theta_goal = agile_eye.ik(task.goal.matrix(), task.working_mode)[0]
    theta_final = theta_init + np.angle(np.exp(1j * (theta_goal - theta_init)))  # the shorter way round
    return Plan(theta_init, theta_final, law)


def _worst_violation(task: Task, plan: Plan, t: np.ndarray, exact: _Estimator) -> _Violation | None:
    """The plan's worst broken margin on the samples t, by the exact FK from the start; None if it keeps all."""
    theta = plan.theta(t)
    rot = exact(theta, task.start.matrix())
    need = margins(task)
    slack = {name: c - need[name] for name, c in clearances(task, theta, rot).items()}
    worst_name = min(slack, key=lambda n: slack[n].min())
    if slack[worst_name].min() >= 0:
        return None
    k = int(np.argmin(slack[worst_name]))
    return _Violation(worst_name, float(t[k]), rot[k])


def _bend(task: Task, plan: Plan, t: np.ndarray, worst: _Violation, estimate: _Estimator, exact: _Estimator,
          deadline: float) -> tuple[Plan, dict]:
    """The plan with one more window of T* centred on the worst sample (kept inside [0, T]), and what it did.
    It is optimised with `estimate` where the window's stretch lies in the network's training workspace, else
    with the exact FK, and again with the exact FK if the network's window fails the exact check."""
    length = task.avoidance.window
    t0 = float(np.clip(worst.t_worst - length / 2, 0.0, plan.law.duration - length))
    anchor = exact(plan.theta(np.append(t[t < t0], t0)), task.start.matrix())[-1]  # the orientation at t0
    span = np.linspace(t0, t0 + length, _WINDOW_SAMPLES)
    chosen, used = estimate, estimate.kind
    if chosen.kind == "network" and not learnt_fk.in_workspace(exact(plan.theta(span), anchor)).all():
        chosen, used = exact, "exact (the window leaves the network's training workspace)"
    window, feasible = _optimise_window(plan, t0, worst, task, chosen, anchor, deadline)
    if chosen.kind == "network" and min(_score(plan.with_window(window), span, exact, anchor, task)[1].values()) < 0:
        window, feasible = _optimise_window(plan, t0, worst, task, exact, anchor, deadline)
        used = "exact (the network's window failed the exact check)"
    return plan.with_window(window), {
        "avoiding": worst.name, "t_worst": worst.t_worst, "t0": t0, "length": length,
        "alpha": float(window.direction[0]), "beta": float(window.direction[1]),
        "gamma": float(window.direction[2]), "L": window.amplitude, "estimator": used, "feasible": feasible}


def optimise(task: Task, law: TimeLaw, deadline: float = np.inf) -> tuple[Plan, list[dict]]:
    """The plain path, then one window per violation until none is left, max_windows is reached or the clock
    (time.perf_counter) passes `deadline`.

    Violations are found with the exact FK. Each window is optimised with the chosen estimator: the network
    where the window's stretch of path lies in its training workspace (elsewhere its estimates mean nothing),
    then checked with the exact FK and optimised again with it where the check fails. Returns the plan and what
    each window did, estimator included.
    """
    plan = _plain_plan(task, law)
    if not task.avoidance.enabled:
        return plan, []
    t = np.linspace(0.0, law.duration, _COARSE)
    exact = _Estimator("exact", task.working_mode)
    estimate = _Estimator(task.avoidance.estimator, task.working_mode)
    steps = []
    for _ in range(task.avoidance.max_windows):
        worst = None if time.perf_counter() > deadline else _worst_violation(task, plan, t, exact)
        if worst is None:
            break
        plan, step = _bend(task, plan, t, worst, estimate, exact, deadline)
        steps.append(step)
    return plan, steps


def _summary(task: Task, theta: np.ndarray, rot: np.ndarray, kci: np.ndarray | None = None) -> dict:
    """KCI and clearances of a path, exact orientations given (and its KCI, if at hand)."""
    kci = agile_eye.kci_closed_form(theta, rot) if kci is None else kci
    clear = {name: float(c.min()) for name, c in clearances(task, theta, rot, kci).items()}
    gaps = agile_eye.axis_gaps(rot).min(axis=0)
    return {"kci": {"mean": float(kci.mean()), "min": float(kci.min())}, "clearance": clear,
            "singular_curves": {f"v{i + 1} = +-u{i + 1}": float(g) for i, g in enumerate(gaps)}}


def slack(task: Task, rot: np.ndarray, pad: float = 0.0) -> np.ndarray:
    """The worst clearance less its margin (N,) at orientations (N, 3, 3), the angular margins raised by `pad`:
    >= 0 where every margin is kept. The joints are the IK in the task's working mode."""
    theta = agile_eye.ik(rot, task.working_mode)
    need = margins(task)
    return np.min([c - need[name] - (0.0 if name == "kci" else pad)
                   for name, c in clearances(task, theta, rot).items()], axis=0)


@dataclass(frozen=True)
class _Checked:
    """A joint path on the control grid with what the exact FK says of it: the platform followed from the start
    orientation, the summary, where it meets or crosses the type 2 singular surface, how far it ends from the
    goal, and whether it keeps every margin in one assembly mode and ends at the goal."""

    name: str
    theta: np.ndarray
    theta_dot: np.ndarray
    rot: np.ndarray
    exact: dict
    crossings: np.ndarray
    goal_error: float
    ok: bool


def _platform(theta: np.ndarray, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The exact FK followed along a joint path from the start orientation (N, 3, 3), and where it is
    undetermined (N,): base angles at which the platform can turn with the base locked (the FK's roots
    degenerate, on the type 2 singular surface). There the orientation before is held."""
    rot = agile_eye.fk_track(theta, start)
    undetermined = ~np.isfinite(rot).all(axis=(1, 2))
    for k in np.flatnonzero(undetermined):
        rot[k] = rot[k - 1] if k else start
    return rot, undetermined


def _crossings(t: np.ndarray, theta: np.ndarray, rot: np.ndarray, undetermined: np.ndarray,
               det_a: np.ndarray | None = None) -> np.ndarray:
    """Times where a path passes the type 2 singular surface: det A changes sign between two samples, or the
    platform comes onto a singular curve (some v_i = +-u_i within _ON_CURVE; there the FK followed may go on in
    either assembly mode, det A's sign then telling nothing) or where its orientation is undetermined. `det_a`:
    det A along the path, if at hand."""
    det_a = np.linalg.det(agile_eye.jacobians(theta, rot)[0]) if det_a is None else det_a
    on = (agile_eye.axis_gaps(rot).min(axis=1) < _ON_CURVE) | undetermined
    arrives = np.flatnonzero(on & ~np.concatenate([[False], on[:-1]]))
    flips = 1 + np.flatnonzero(np.sign(det_a[1:]) * np.sign(det_a[:-1]) < 0)
    return t[np.union1d(arrives, flips)]


def _check(task: Task, name: str, t: np.ndarray, theta: np.ndarray, theta_dot: np.ndarray) -> _Checked:
    """Judge a joint path by the exact FK of its samples (independent of how it was planned)."""
    rot, undetermined = _platform(theta, task.start.matrix())
    terms = agile_eye.kci_terms(theta, rot)  # its rows a_i are A's (agile_eye.jacobians)
    exact = _summary(task, theta, rot, terms.kci)
    crossings = _crossings(t, theta, rot, undetermined, np.linalg.det(terms.a))
    goal_error = float(rotation_angle(rot[-1:], task.goal.matrix()[None])[0])
    keeps = not _shortfalls(task, exact["clearance"])
    return _Checked(name, theta, theta_dot, rot, exact, crossings, goal_error,
                    keeps and not crossings.size and goal_error < _ENDS)


def _search(task: Task, law: TimeLaw, t: np.ndarray, deadline: float) -> tuple[_Checked | None, dict]:
    """The global search's path timed on the control grid and checked, or None; and what the search did.
    The orientation path R(sigma) is timed as sigma = length S(t / T), S the 4-5-6-7 law (eq. 8), so the
    platform is at rest with no acceleration or jerk at both ends; the joints are its IK in the working mode."""
    from simbench.planners import so3_search  # OMPL, imported when a search is planned

    start, goal = task.start.matrix(), task.goal.matrix()
    clock = time.perf_counter()

    def padded(rot):  # margins padded so that whole motions keep them (so3_search's docstring)
        return slack(task, rot, _SEARCH_STEP / 2)

    waypoints, status = so3_search.search(padded, start, goal, max(deadline - clock, 1e-3), _SEARCH_STEP)
    info = {"status": status, "time": time.perf_counter() - clock}
    if waypoints is None:
        return None, info
    path = so3_search.smooth(waypoints, padded, _SEARCH_STEP)
    rot = path(path.length * law(t, order=0)[0])
    theta = np.unwrap(agile_eye.ik(rot, task.working_mode), axis=0)  # continuous, from IK(start) in (-pi, pi]
    info.update({"waypoints": len(waypoints), "length": path.length, "blends": path.blends.tolist(),
                 "time": time.perf_counter() - clock})
    return _check(task, "global search in SO(3)", t, theta, np.gradient(theta, t, axis=0)), info


_MARGIN_FIELDS = {"type2": "task.singularity_clearance", "kci": "task.kci_min"}


def _shortfalls(task: Task, clearance: dict[str, float]) -> list[str]:
    """Each margin not kept: the clearance reached, the margin, and the field that sets it. The KCI is a
    number (1 / cond(A^-1 B)), the clearances angles (in degrees here)."""
    need = margins(task)
    out = []
    for name, c in clearance.items():
        if c < need[name] - 1e-9:
            field = _MARGIN_FIELDS.get(name, "task.obstacle_clearance")
            out.append(f"kci {c:.3f} (floor {need[name]:.3f}, {field})" if name == "kci" else
                       f"{name} clearance {np.rad2deg(c):.2f} deg (margin {np.rad2deg(need[name]):.2f} deg, {field})")
    return out


def _refusal(task: Task, best: _Checked, search: dict | None) -> str:
    """Why no path is handed over: the margins not kept, the best clearances found, and what was tried."""
    for end in ("start", "goal"):
        rot = getattr(task, end).matrix()[None]
        clear = {n: float(c[0]) for n, c in clearances(task, agile_eye.ik(rot, task.working_mode), rot).items()}
        if _shortfalls(task, clear):
            return (f"the {end} orientation breaks a margin, so no path keeps them: "
                    f"{'; '.join(_shortfalls(task, clear))}")
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


def _choose(task: Task, law: TimeLaw, t: np.ndarray) -> tuple[_Checked, _Checked, list[dict], dict | None]:
    """The path to hand over: the plain one if it keeps the margins, else the one bent by windows, else the
    global search's; each judged by the exact FK on the control grid. Windows get half of the time budget, the
    search the rest (at least half). Returns the chosen path (not ok if none is), the plain path, the windows
    and what the search did (None if it did not run). RunError if none keeps the margins and the task does not
    accept that."""
    clock = time.perf_counter()
    budget = task.avoidance.time_budget
    bent, steps = optimise(task, law, deadline=clock + budget / 2)
    plain_plan = Plan(bent.theta_init, bent.theta_final, law)
    plain = _check(task, "plain 4-5-6-7 joint path", t, plain_plan.theta(t), plain_plan.theta(t, order=1))
    chosen = plain if not steps else _check(task, "4-5-6-7 joint path bent by windows", t, bent.theta(t),
                                            bent.theta(t, order=1))
    search = None
    if not chosen.ok and task.avoidance.enabled:
        found, search = _search(task, law, t, max(clock + budget, time.perf_counter() + budget / 2))
        if found is not None and found.ok:
            chosen = found
    if not chosen.ok and not task.accept_margin_violation:
        raise RunError(_refusal(task, chosen, search))
    return chosen, plain, steps, search


def _violations(task: Task, chosen: _Checked, t_end: float | None = None) -> list[dict]:
    """What a path that is not ok breaks, as verdict violations: each margin not kept, a singular crossing where
    it passes the type 2 surface, the goal missed where its platform ends away from the goal (at `t_end`)."""
    out = [{"kind": "clearance_margin", "message": f"{line} not kept"}
           for line in _shortfalls(task, chosen.exact["clearance"])]
    if chosen.crossings.size:
        t_cross = float(chosen.crossings[0])
        out.append({"kind": "singular_crossing", "t": t_cross, "crossings": chosen.crossings.tolist(),
                    "message": f"the plan passes the type 2 singular surface at t = {t_cross:.3f} s: the platform "
                               "may change assembly mode there"})
    if chosen.goal_error >= _ENDS:
        out.append({"kind": "goal_missed", "t": t_end, "error": chosen.goal_error,
                    "message": f"the planned platform ends {np.rad2deg(chosen.goal_error):.1f} deg from the goal "
                               "orientation"})
    return out


def _accepted(task: Task, chosen: _Checked, t_end: float) -> tuple[list[str], list[dict]]:
    """Warnings and violations of a path handed over although it breaks its margins (_violations)."""
    violations = _violations(task, chosen, t_end)
    return [f"{v['message']} (accepted: task.accept_margin_violation)" for v in violations], violations


def _info(task: Task, chosen: _Checked, plain: _Checked, steps: list[dict], search: dict | None,
          planning_time: float) -> dict:
    """The plan's info: the path chosen, its windows and search, and what the exact FK says of it and of the
    plain path; with the network, the clearances it estimates along the chosen path too."""
    theta = chosen.theta
    info = {
        "method": "paper 003: 4-5-6-7 joint path with smooth avoidance windows found by SLSQP; where they fail, "
                  "a global search in SO(3) (RRT-Connect) timed by the same law",
        "path": chosen.name + ("" if chosen.ok else " (margins not kept: accepted by task.accept_margin_violation)"),
        "planning_time": planning_time,
        "working_mode": task.working_mode,
        "theta_init": theta[0].tolist(),
        "theta_final": theta[-1].tolist(),
        "estimator": task.avoidance.estimator if task.avoidance.enabled else None,
        "windows": steps,
        "search": search,
        "margins": margins(task),
        "goal_error": chosen.goal_error,
        "singular_crossings": chosen.crossings.tolist(),
        **chosen.exact,
        "plain_path": {**plain.exact, "singular_crossings": plain.crossings.tolist(),
                       "goal_error": plain.goal_error},
    }
    if task.avoidance.enabled and task.avoidance.estimator == "network":
        estimated = clearances(task, theta, learnt_fk.load()(theta, task.working_mode))
        info["clearance_estimated"] = {name: float(c.min()) for name, c in estimated.items()}
    return info


def plan(scenario, robot, dt: float) -> JointTrajectory:
    """Plan, bend and time the path, searching SO(3) where bending fails; the exact FK gives the platform
    orientations the report checks. RunError if no path keeps the margins (unless the task accepts that)."""
    task = scenario.task
    law = scenario.timing.law_fn()
    clock = time.perf_counter()
    t = control_grid(law.duration, scenario.timing.hold, dt)
    chosen, plain, steps, search = _choose(task, law, t)
    theta, rot = chosen.theta, chosen.rot
    warnings, violations = _accepted(task, chosen, float(t[-1]))
    info = _info(task, chosen, plain, steps, search, time.perf_counter() - clock)
    quat = matrix_to_quat(rot)
    aim = rot @ agile_eye.LINE_OF_SIGHT * agile_eye.AIM
    waypoints = tuple({"s": s, "X": aim[k].tolist(), "q": theta[k].tolist(), "quat": quat[k].tolist()}
                      for s, k in ((0.0, 0), (1.0, -1)))
    return JointTrajectory(t=t, s=law(t, order=0)[0], q_ref=theta, qd_ref=chosen.theta_dot, tool_ref=aim,
                           waypoints=waypoints, info=info, warnings=tuple(warnings), violations=tuple(violations),
                           series={"platform_quat_ref": quat}, initial=start_assembly(theta[0], task.start.matrix()))


def start_assembly(theta: np.ndarray, start: np.ndarray) -> dict[str, list[float]]:
    """JointTrajectory.initial: every joint of the closed chain, the passive ones included, at base angles theta
    (3,) and the start orientation (3, 3). The robot's own assembly takes the FK solution nearest home, for
    most start orientations another assembly mode than the plan's, which the physics would then keep."""
    return {joint: [value] for joint, value in agile_eye.assemble(theta, start).items()}


def check(scenario, robot) -> tuple[str, str] | None:
    """T* must fit in T, and the start and goal must not lie on a singular curve (their IK is undefined there)."""
    task = scenario.task
    if task.avoidance.window > scenario.timing.duration:
        return ("task.avoidance.window", f"T* = {task.avoidance.window:g} s is longer than the motion "
                                         f"(timing.duration = {scenario.timing.duration:g} s)")
    for field in ("start", "goal"):
        gap = agile_eye.axis_gaps(getattr(task, field).matrix()).min()
        if gap < 1e-6:
            return f"task.{field}", "lies on a singular curve (some v_i = +-u_i): its base angles are undefined"
    return None


def decorations(scenario) -> list[Decoration]:
    """The obstacles as the cones of lines of sight they contain, for the video."""
    out = []
    for obstacle in scenario.task.obstacles:
        x, y, z = (float(v) for v in obstacle.center.matrix() @ agile_eye.LINE_OF_SIGHT)
        out.append(Decoration("cone", (x, y, z), obstacle.radius, agile_eye.AIM, (0.6, 0.25, 0.95, 0.35)))
    return out



class Avoidance4567(Planner):
    """Paper 003: 4-5-6-7 orientation path bent around obstacles and singularities (SLSQP)."""

    name = "avoidance_4567"
    description = "paper 003: 4-5-6-7 orientation path bent around obstacles and singularities (SLSQP)"
    task = Task
    robots = ("agile_eye",)

    def plan(self, scenario, robot, dt: float) -> JointTrajectory:
        return plan(scenario, robot, dt)

    def check(self, scenario, robot) -> tuple[str, str] | None:
        return check(scenario, robot)

    def decorations(self, scenario) -> list[Decoration]:
        return decorations(scenario)


PLANNER = Avoidance4567()
