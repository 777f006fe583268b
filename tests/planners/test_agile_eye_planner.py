"""Paper 003's planner: the smoothness of the bent path, and the avoidance of the obstacle and the singularity
checked with the exact forward kinematics."""

from decimal import Decimal, localcontext

import numpy as np
import pytest

from simbench.maths.timing import TimeLaw
from simbench.planners import avoidance_4567 as method
from simbench.planners.avoidance_4567.estimators import Estimator
from simbench.planners.avoidance_4567.path import plain_plan
from simbench.planners.avoidance_4567.windows import WindowFit
from simbench.robots import agile_eye as E


@pytest.mark.parametrize("order", range(4))
def test_bump_and_its_first_three_derivatives_vanish_at_both_ends(order):
    """Near each end the k-th derivative of b must shrink as eps^(4 - k) (a fourth-order zero): ten times closer,
    10^(4 - k) times smaller (within the next term's share at eps = 0.01; a zero of another order is 10 times
    off)."""
    small, big = (np.abs(method.bump(np.array([eps, 1 - eps]), order)) for eps in (1e-3, 1e-2))
    np.testing.assert_allclose(small / big, 10.0 ** -(4 - order), rtol=0.15)
    assert method.bump(np.array([0.5]))[0] == pytest.approx(1.0)
    assert np.all(method.bump(np.array([-0.1, 1.1]), order) == 0.0)


def smooth_plan():
    law = TimeLaw("4567", 4.0)
    windows = (method.Window(0.7, 1.0, np.array([0.6, -0.8, 0.0]), 0.3),
               method.Window(2.2, 1.0, np.array([0.0, 0.6, 0.8]), 0.2))
    return method.Plan(np.array([0.1, -0.2, 0.3]), np.array([1.2, 0.4, -0.9]), law, windows)


@pytest.mark.parametrize("order", range(4))
def test_planned_path_is_continuous_in_position_velocity_acceleration_and_jerk(order):
    plan = smooth_plan()
    for edge in (0.7, 1.7, 2.2, 3.2):  # the windows' ends
        # Across a continuous function the step shrinks with the gap; across a jump it would not.
        steps = [np.abs(np.subtract(*plan.theta(np.array([edge + eps, edge - eps]), order))).max()
                 for eps in (1e-4, 1e-6)]
        assert steps[1] < 0.05 * steps[0] + 1e-9
    ends = plan.theta(np.array([0.0, 4.0]), order)
    if order:
        assert np.abs(ends).max() < 1e-9  # at rest, no acceleration and no jerk at both ends


def test_derivatives_are_those_of_the_path():
    plan = smooth_plan()
    t = np.linspace(0.0, 4.0, 40001)
    for order in range(1, 4):
        fd = np.gradient(plan.theta(t, order - 1), t, axis=0)
        assert np.abs(fd - plan.theta(t, order))[5:-5].max() < 1e-3 * max(1.0, np.abs(fd).max())


def test_avoidance_scenario_plain_path_violates_and_optimised_path_clears(evaluated):
    scenario, ev = evaluated("agile_eye", "avoidance")
    info = ev.trajectory.info
    need = info["margins"]
    plain = info["plain_path"]["clearance"]
    assert plain["obstacle1"] < 0  # the plain 4-5-6-7 path runs through the obstacle
    assert plain["type2"] < np.deg2rad(5)  # and within 5 deg of a type 2 singular curve
    # The optimised path keeps every margin, by the exact FK of the planned joints, recomputed here.
    theta = ev.trajectory.q_ref
    rot = E.fk_track(theta, scenario.task.start.matrix())
    clear = method.clearances(scenario.task, theta, rot)
    for name, margin in need.items():
        assert clear[name].min() >= margin - 1e-9, name
    assert E.kci(theta, rot).mean() >= 0.30  # the paper's 0.30-0.42
    assert np.rad2deg(E.rotation_angle(rot[-1:], scenario.task.goal.matrix()[None]))[0] < 1e-4
    for window in info["windows"]:
        assert window["feasible"]
        assert {"alpha", "beta", "gamma", "L"} <= set(window)
        assert window["alpha"] ** 2 + window["beta"] ** 2 + window["gamma"] ** 2 == pytest.approx(1.0, abs=1e-6)
    assert any(w["estimator"] == "network" for w in info["windows"])


def test_through_singularity_plan_reports_the_crossing(evaluated):
    _, ev = evaluated("agile_eye", "through_singularity")
    assert ev.trajectory.info["singular_crossings"]
    assert any("may change assembly mode" in w for w in ev.trajectory.warnings)
    assert {v["kind"] for v in ev.trajectory.violations} == {"clearance_margin", "singular_crossing", "goal_missed"}
    assert ev.verdict.as_expected


# Project issue 14: the planner's fast forms and analytic derivatives, each against what it stands for.

def _random_poses(count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Base angles uniform on the torus and the FK solution nearest home (some near the singular curves)."""
    theta = np.random.default_rng(seed).uniform(-np.pi, np.pi, (count, 3))
    return theta, E.fk_nearest(theta, np.eye(3))


def _exact_kci(a: np.ndarray, b: np.ndarray) -> float:
    """sigma_min / sigma_max of K = B^-1 A for the rows a_i (3, 3) and b_i (3,) as given, in 60 digits: the
    extreme roots of det(lambda - K K^T), found by Newton's method from either side of all three (where it moves
    monotonically towards the nearest root)."""
    with localcontext() as ctx:
        ctx.prec = 60
        k = [[Decimal(float(a[i, j])) / Decimal(float(b[i])) for j in range(3)] for i in range(3)]
        g = [[sum(k[i][m] * k[j][m] for m in range(3)) for j in range(3)] for i in range(3)]
        trace = g[0][0] + g[1][1] + g[2][2]
        minors = sum(g[i][i] * g[j][j] - g[i][j] * g[i][j] for i, j in ((0, 1), (0, 2), (1, 2)))
        det = (g[0][0] * (g[1][1] * g[2][2] - g[1][2] ** 2) - g[0][1] * (g[0][1] * g[2][2] - g[1][2] * g[0][2])
               + g[0][2] * (g[0][1] * g[1][2] - g[1][1] * g[0][2]))

        def root(x: Decimal) -> Decimal:
            for _ in range(2000):
                step = ((x - trace) * x * x + minors * x - det) / ((3 * x - 2 * trace) * x + minors)
                x -= step
                if abs(step) <= abs(x) * Decimal("1e-45"):
                    break
            return x

        return float((root(Decimal(0)) / root(trace)).sqrt())


def test_kci_is_exact_to_rounding_near_the_singular_curves_and_away():
    """kci against the exact sigma_min / sigma_max of its own rows (60 digits, `_exact_kci`): within 1e-15 on
    random poses and on poses turned 1e-7 to 0.1 rad off a singular curve (KCI down to about 1e-8), where the
    eigenvalues of K K^T lose the small singular value."""
    theta, rot = _random_poses(150, 14)
    on = E.axis_rotation(np.array([[0.0, 1.0, 0.0]]), np.array([-np.pi / 2]))
    rng = np.random.default_rng(34)
    axes = rng.normal(size=(150, 3))
    near = E.axis_rotation(axes / np.linalg.norm(axes, axis=1, keepdims=True), 10.0 ** rng.uniform(-7, -1, 150))
    near = near @ on @ E.axis_rotation(np.array([[1.0, 0.0, 0.0]]), np.array([0.7]))
    theta, rot = np.concatenate([theta, E.ik(near)]), np.concatenate([rot, near])
    terms = E.kci_terms(theta, rot)
    assert terms.ok.all() and terms.kci.min() < 1e-6
    exact = np.array([_exact_kci(a, b) for a, b in zip(terms.a, terms.b)])
    np.testing.assert_allclose(E.kci(theta, rot), exact, rtol=0, atol=1e-15)
    # on a singular curve (v1 = u1 = z: a quarter turn about -y, then any turn about the new v1) it is 0
    on_curve = on @ E.axis_rotation(np.array([[1.0, 0.0, 0.0]]), np.array([0.7]))
    assert E.axis_gaps(on_curve)[0, 0] < 1e-7
    assert E.kci(E.ik(on_curve), on_curve)[0] == pytest.approx(0.0, abs=1e-12)


def _track_by_sample(theta: np.ndarray, start: np.ndarray) -> np.ndarray:
    """The continuous assembly mode sample by sample, as its definition reads: of the 8 FK solutions, the nearest
    (largest trace of R^T R') to `start`, then to the one before."""
    sols = E.fk_all(theta)
    score = np.nan_to_num(np.einsum("kab,ab->k", sols[0], start), nan=-np.inf)
    rots = [sols[0, np.argmax(score)]]
    for k in range(1, len(sols)):
        rots.append(sols[k, np.argmax(np.nan_to_num(np.einsum("kab,ab->k", sols[k], rots[-1]), nan=-np.inf))])
    return np.stack(rots)


def test_fk_track_follows_the_nearest_solution_sample_by_sample():
    """The same arrays as the sample-by-sample definition, on smooth paths and on paths whose samples jump (the
    followed solution changing often)."""
    rng = np.random.default_rng(14)
    for step in (1e-3, 1e-2, 0.3, 2.0):
        theta = np.cumsum(rng.normal(scale=step, size=(1500, 3)), axis=0)
        start = E.fk_all(theta[:1])[0, rng.integers(8)]
        assert np.array_equal(E.fk_track(theta, start), _track_by_sample(theta, start), equal_nan=True)


def _fd_along_fk(fn, theta, rot, h=1e-6):
    """Central differences in each base angle of fn(theta, rot), the platform following the exact FK."""
    out = []
    for j in range(3):
        d = np.zeros(3)
        d[j] = h
        plus, minus = E.fk_nearest(theta + d, rot), E.fk_nearest(theta - d, rot)
        out.append((fn(theta + d, plus) - fn(theta - d, minus)) / (2 * h))
    return np.stack(out, axis=-1)


def test_kci_and_axis_gap_gradients_match_finite_differences():
    """Along the exact FK (rates A^-1 B), and in a turn of the platform alone (as a learnt FK's estimate turns,
    off the closure constraints)."""
    theta, rot = _random_poses(400, 15)
    keep = E.kci(theta, rot) > 0.02  # away from the singular curves, where the KCI is not differentiable
    theta, rot = theta[keep], rot[keep]
    rates = E.platform_rates(theta, rot)
    kci, d_theta, d_omega = E.kci_partials(theta, rot)
    np.testing.assert_allclose(kci, E.kci(theta, rot), atol=1e-12)
    fd = _fd_along_fk(E.kci, theta, rot)
    np.testing.assert_allclose(d_theta + np.einsum("nc,ncj->nj", d_omega, rates), fd, rtol=1e-5, atol=1e-6)
    gaps, d_gaps = E.axis_gap_partials(rot)
    np.testing.assert_array_equal(gaps, E.axis_gaps(rot))
    fd = _fd_along_fk(lambda t, r: E.axis_gaps(r), theta, rot)
    np.testing.assert_allclose(np.einsum("nic,ncj->nij", d_gaps, rates), fd, rtol=1e-5, atol=1e-6)
    # the platform turned off the FK (w_i . v_i != 0), the base held
    axes = np.random.default_rng(16).normal(size=(len(rot), 3))
    rot = E.axis_rotation(axes / np.linalg.norm(axes, axis=1, keepdims=True), np.full(len(rot), 0.1)) @ rot
    _, d_theta, d_omega = E.kci_partials(theta, rot)
    h = 1e-6
    for c in range(3):
        axis = np.zeros((len(rot), 3))
        axis[:, c] = 1.0
        turned = [E.axis_rotation(axis, np.full(len(rot), s * h)) @ rot for s in (1, -1)]
        fd = (E.kci(theta, turned[0]) - E.kci(theta, turned[1])) / (2 * h)
        np.testing.assert_allclose(d_omega[:, c], fd, rtol=1e-5, atol=1e-6)
        d = np.zeros(3)
        d[c] = h
        fd = (E.kci(theta + d, rot) - E.kci(theta - d, rot)) / (2 * h)
        np.testing.assert_allclose(d_theta[:, c], fd, rtol=1e-5, atol=1e-6)


def test_learnt_fk_reverse_mode_matches_finite_differences():
    """rates_vjp: torque . (angular velocity of the network's estimate per unit rate of theta_j)."""
    from simbench.planners import learnt_fk

    net = learnt_fk.load()
    rng = np.random.default_rng(17)
    rot = learnt_fk.sample_workspace(300, rng)
    for mode in (0, 6):
        theta = E.ik(rot, mode)
        estimate, layers = net.forward(theta, mode)
        assert np.array_equal(estimate, net(theta, mode))
        torque = rng.normal(size=(len(theta), 3))
        pulled = net.rates_vjp(theta, mode, torque, layers)
        h = 1e-6
        for j in range(3):
            d = np.zeros(3)
            d[j] = h
            turn = (net(theta + d, mode) - net(theta - d, mode)) / (2 * h) @ estimate.transpose(0, 2, 1)
            omega = np.stack([turn[:, 2, 1], turn[:, 0, 2], turn[:, 1, 0]], axis=-1)
            np.testing.assert_allclose(pulled[:, j], np.einsum("nc,nc->n", torque, omega), rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("estimator", ["network", "exact"])
def test_window_gradients_match_finite_differences(estimator):
    """SLSQP's analytic gradients (objective and each constraint's worst clearance) against central differences
    in x = (alpha, beta, gamma, L), at random x on the shipped scenario's first window; where the worst sample
    changes within the step (a kink of the minimum) the constraint is skipped."""
    import simbench
    from tests.conftest import scenario_file

    task = simbench.load_scenario(scenario_file("agile_eye", "avoidance")).task
    law = TimeLaw("4567", 4.0)
    plan = plain_plan(task, law)
    t0 = 0.5
    exact = Estimator("exact", task.working_mode)
    anchor = exact(plan.theta(np.linspace(0.0, t0, 26)), task.start.matrix())[-1]
    fit = WindowFit(plan, t0, task, Estimator(estimator, task.working_mode), anchor)
    rng = np.random.default_rng(18)
    h = 1e-6
    checked = 0
    for _ in range(12):
        x = np.array([*rng.normal(size=3), rng.uniform(0.05, 0.4)])
        objective, constraint = fit._gradients(x)
        for i in range(4):
            d = np.zeros(4)
            d[i] = h
            plus, minus = fit.evaluate(x + d), fit.evaluate(x - d)
            fd = (fit.objective(x + d) - fit.objective(x - d)) / (2 * h)
            assert objective[i] == pytest.approx(fd, rel=1e-4, abs=1e-7)
            for name, c in fit.evaluate(x).clear.items():
                if not np.argmin(plus.clear[name]) == np.argmin(minus.clear[name]) == np.argmin(c):
                    continue
                fd = (plus.slack[name] - minus.slack[name]) / (2 * h)
                assert constraint[name][i] == pytest.approx(fd, rel=1e-4, abs=1e-7), name
                checked += 1
    assert checked > 100
