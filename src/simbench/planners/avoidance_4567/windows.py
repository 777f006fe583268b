"""Steps 3-4 of the method: a window per violation, its bump found by SLSQP with analytic gradients."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from simbench.maths.timing import TimeLaw
from simbench.planners import learnt_fk
from simbench.planners.avoidance_4567.estimators import Estimator
from simbench.planners.avoidance_4567.path import Plan, Window, bump, plain_plan
from simbench.planners.avoidance_4567.task import Task, centers, clearances, margins, obstacle_names
from simbench.robots import agile_eye

_COARSE = 201  # samples of the whole path on which violations are found
_WINDOW_SAMPLES = 101  # samples of a window on which SLSQP judges a candidate
_SAFETY = np.deg2rad(0.1)  # kept above each margin on the window's samples, so the dense path keeps the margin
_STEP = 1e-3  # rad: finite-difference step of the clearance gradient that seeds SLSQP
_MAX_AMPLITUDE = np.pi / 4
ANALYTIC_GRADIENTS = True  # SLSQP gets the analytic gradients of WindowFit (off: its finite differences)


def _score(plan: Plan, t: np.ndarray, estimate: Estimator, anchor: np.ndarray,
           task: Task) -> tuple[float, dict[str, float]]:
    """Mean KCI and the worst clearance minus margin of each constraint, for a candidate plan over times t."""
    theta = plan.theta(t)
    rot = estimate(theta, anchor)
    need = margins(task)
    clear = clearances(task, theta, rot)
    slack = {name: float(c.min() - need[name]) for name, c in clear.items()}
    kci = clear["kci"] if "kci" in clear else agile_eye.kci(theta, rot)
    return float(kci.mean()), slack


def _seeds(plan: Plan, t_worst: float, name: str, task: Task, estimate: Estimator,
           anchor: np.ndarray) -> list[np.ndarray]:
    """Starting directions for SLSQP: the violated clearance's gradient in the joints at its worst instant
    (orientation `anchor`), and the two joint axes nearest it."""
    theta = plan.theta(np.array([t_worst]))[0]
    probes = theta + np.vstack([np.zeros(3), _STEP * np.eye(3)])
    clear = clearances(task, probes, np.stack([estimate(p[None], anchor)[0] for p in probes]))[name]
    grad = (clear[1:] - clear[0]) / _STEP
    direction = grad / max(np.linalg.norm(grad), 1e-12)
    axes = np.argsort(-np.abs(direction))[:2]
    return [direction] + [np.sign(direction[a]) * np.eye(3)[a] for a in axes]


@dataclass(frozen=True)
class _Violation:
    """The constraint furthest below its margin, the time of its worst sample and the orientation there."""

    name: str
    t_worst: float
    rot: np.ndarray


@dataclass
class _Evaluation:
    """A candidate window's path on its samples: joints, estimate (and network layers), clearances, KCI terms, mean
    KCI, each clearance's worst less its margin; the gradients once asked."""

    theta: np.ndarray
    rot: np.ndarray
    layers: list | None
    clear: dict[str, np.ndarray]
    kci: agile_eye.KciTerms
    mean_kci: float
    slack: dict[str, float]
    gradients: tuple[np.ndarray, dict[str, np.ndarray]] | None = None


def _angle_partial(center: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """Derivative (N, 3) in the platform's rotation of the geodesic angle between `center` and rot (N, 3, 3):
    d cos = omega . m / 2, m the axial vector of R C^T less its transpose."""
    m = rot @ center.T
    cos = (np.einsum("ij,nij->n", center, rot) - 1) / 2
    axial = np.stack([m[:, 1, 2] - m[:, 2, 1], m[:, 2, 0] - m[:, 0, 2], m[:, 0, 1] - m[:, 1, 0]], axis=-1)
    return -0.5 * axial / np.sqrt(np.maximum(1.0 - np.clip(cos, -1.0, 1.0) ** 2, 1e-300))[:, None]


class WindowFit:
    """SLSQP's problem for a new window at t0 (x = alpha, beta, gamma, L), judged on the window's own samples (a
    window changes nothing outside it; `anchor`: the orientation at t0). Each x's evaluation and gradients are
    cached, as the objective and every constraint ask for the same x."""

    def __init__(self, plan: Plan, t0: float, task: Task, estimate: Estimator, anchor: np.ndarray):
        self.plan, self.t0, self.task, self.estimate, self.anchor = plan, t0, task, estimate, anchor
        self.length = task.avoidance.window
        self.t = np.linspace(t0, t0 + self.length, _WINDOW_SAMPLES)
        self.share = self.length / plan.law.duration  # the window's part of the path's mean KCI
        self.base = plan.theta(self.t)  # the plan without the new window: plan.with_window(w).theta(t) - offset
        self.bump = bump((self.t - t0) / self.length)
        self.need = margins(task)
        self.centers = dict(zip(obstacle_names(task), centers(task)))
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
        """Gradients in x (4,) of the objective and of each constraint at its worst sample: partials in theta and
        the platform's rotation pulled back through the estimate (Estimator.pull), then through
        theta = base + L b n, n = d / |d|: d theta / d d = L b (I - n n^T) / |d|, d theta / dL = b n."""
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
        """(alpha, beta, gamma) a unit vector, and every clearance _SAFETY above its margin."""
        unit = {"type": "eq", "fun": lambda x: x[:3] @ x[:3] - 1.0}
        keep = [{"type": "ineq", "fun": lambda x, n=name: self.score(x)[1][n] - _SAFETY} for name in self.need]
        if ANALYTIC_GRADIENTS:
            unit["jac"] = lambda x: np.array([2 * x[0], 2 * x[1], 2 * x[2], 0.0])
            for con, name in zip(keep, self.need):
                con["jac"] = lambda x, n=name: self._gradients(x)[1][n]
        return [unit] + keep


def _optimise_window(plan: Plan, t0: float, worst: _Violation, task: Task, estimate: Estimator,
                     anchor: np.ndarray, deadline: float) -> tuple[Window, bool]:
    """A new window at t0 by SLSQP from each seed (none new past `deadline`): the best feasible one (else the one
    that misses least), and whether it is feasible."""
    from scipy.optimize import minimize  # imported when planned, not when registered

    fit = WindowFit(plan, t0, task, estimate, anchor)
    constraints = fit.constraints()
    best = None
    for seed in _seeds(plan, worst.t_worst, worst.name, task, estimate, worst.rot):
        if best is not None and time.perf_counter() > deadline:
            break
        result = minimize(fit.objective, np.array([*seed, 0.2]), method="SLSQP",
                          jac=fit.objective_gradient if ANALYTIC_GRADIENTS else None,
                          bounds=[(-1, 1)] * 3 + [(0, _MAX_AMPLITUDE)], constraints=constraints,
                          options={"maxiter": 40, "ftol": 1e-6})
        slack = min(fit.score(result.x)[1].values()) - _SAFETY
        # Feasible candidates rank by their objective, the others by how far they miss.
        rank = (True, -result.fun) if slack >= -1e-6 else (False, slack)
        if best is None or rank > best[0]:
            best = (rank, result.x)
    return fit.window(best[1]), best[0][0]


def _worst_violation(task: Task, plan: Plan, t: np.ndarray, exact: Estimator) -> _Violation | None:
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


def _bend(task: Task, plan: Plan, t: np.ndarray, worst: _Violation, estimate: Estimator, exact: Estimator,
          deadline: float) -> tuple[Plan, dict]:
    """The plan with one more window centred on the worst sample, and what it did: optimised with `estimate`
    inside the network's training workspace, else (or if it fails the exact check) with the exact FK."""
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
    """The plain path, then one window per violation (found by the exact FK) until none is left, max_windows is
    reached or time.perf_counter passes `deadline`; the plan and what each window did."""
    plan = plain_plan(task, law)
    if not task.avoidance.enabled:
        return plan, []
    t = np.linspace(0.0, law.duration, _COARSE)
    exact = Estimator("exact", task.working_mode)
    estimate = Estimator(task.avoidance.estimator, task.working_mode)
    steps = []
    for _ in range(task.avoidance.max_windows):
        worst = None if time.perf_counter() > deadline else _worst_violation(task, plan, t, exact)
        if worst is None:
            break
        plan, step = _bend(task, plan, t, worst, estimate, exact, deadline)
        steps.append(step)
    return plan, steps
