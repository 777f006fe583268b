"""cartesian_path's sns, priority and gradient methods (planners/path_methods) on random lines (fixed seeds) of the
generic PUMA 600 (its own MJCF, 6 joints) and example-robot-data's xArm7 (its URDF, 7 joints), judged by MuJoCo's own
kinematics of a plain compile of each file (test_path_methods.Mujoco, test_cartesian_path_damping.Kinematics) and
the commanded twist recomputed here from the line, the quintic law and the closed loop's gain:

  - sns: at every sample each joint within its speed limit (to 1e-9) and range; the tool's twist J qd the commanded
    x scaled by s in [0, 1] (|J qd - s x| under 1e-9 of |x|: not turned), s the plan's `plan_speed_scale`; where the
    pseudo-inverse's own rates (computed here, with the redundant arm's return to its start posture) keep every
    bound, sns's rates are those; on the xArm7 some samples keep the whole task (s = 1) only by saturating joints;
  - priority: with J1, J2 the point's and the orientation's rows, where J1 is far from its own singularity, the
    rates (the speed scale divided out) make J1 qd = x1 as pinv on the point's rows does, and the rest is the
    damped least-squares solution, recomputed here by least squares, of J2 N1 y = x2 - J2 J1+ x1 with the
    documented damping of J2 N1's least singular value (none: the orientation's error the least the point's null
    space allows); at a PUMA wrist within 1e-4 rad of its singularity the rule's rates stay within |J1+ x1| plus
    |x2 - J2 J1+ x1| / (2 lambda), where pinv's are a hundred times that and more, the point's twist made exactly;
    along paper 002's wrist line the tool stays on the line within the speed limits;
  - gradient: each sample's rates are pinv's plus GRADIENT_GAIN (I - J+ J) grad w, w = sqrt(det(Ju Ju^T)) and its
    gradient by central differences here; the null-space term moves the tool by nothing (J times it under 1e-9); on
    the lines both keep cleanly, w's mean along the plan is pinv's or more on the whole (not on every line: pinv
    returns to its start posture instead, which may end higher); where the tool holds still, w never falls; an arm
    with no joint to spare refuses it in one line naming task.method (exit 2); the bench writes it for the arms with
    one alone.
"""

import numpy as np
import pytest
import yaml

from simbench.cli import main
from simbench.core.errors import ScenarioError
from simbench.planners.path_methods import EPSILON, GRADIENT_GAIN, LAMBDA_MAX
from simbench.planners.resolved_rates import CLIK_SHARE, NULL_GAIN
from simbench.scenario import parse_scenario
from simbench.scenario.robot_mapping import load_robot
from simbench.scenario.schema import Units
from tests.planners.test_cartesian_path_damping import ARMS, Kinematics
from tests.planners.test_path_methods import SPEED, START, XML, Mujoco, _line_distance

DT, HOLD = 0.01, 0.3  # s: a coarse control step keeps dozens of plans quick
SLOW = 0.5  # rad/s: the xArm7's speed limits here (its URDF's 3.14 would seldom bind)


def _scenario(mapping: dict, start, by, method: str, duration: float = 1.0):
    """A line `by` (m) from the tool's point at `start` (rad), quintic over `duration`, by `method`."""
    doc = {"robot": mapping, "planner": "cartesian_path",
           "task": {"start": list(map(float, start)), "path": [{"line": {"by": list(map(float, by))}}],
                    "method": method},
           "timing": {"law": "quintic", "duration": duration, "hold": HOLD}}
    return parse_scenario(doc, f"{method} line")


def _plan(mapping: dict, start, by, method: str, duration: float = 1.0, dt: float = DT):
    """_scenario's robot and plan at control step dt."""
    scenario = _scenario(mapping, start, by, method, duration)
    return scenario, scenario.robot_def, scenario.planner_def.plan(scenario, scenario.robot_def, dt)


def _commanded(mj, robot, plan, k: int, start, by, r0, duration: float = 1.0) -> np.ndarray:
    """The commanded unit twist [v / L; w] at sample k: the line's velocity under the quintic law plus K = CLIK_SHARE
    / dt times the tool's error at the plan's q (the point's, and 1/2 sum n x n_d of the start's orientation)."""
    tau = min(plan.t[k] / duration, 1.0)
    s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    ds = (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / duration
    point, rotation = mj.pose(plan.q_ref[k])
    gain = CLIK_SHARE / DT
    velocity = np.asarray(by) * ds + gain * (start + s * np.asarray(by) - point)
    turn = gain * 0.5 * np.cross(rotation.T, r0.T).sum(axis=0)
    return np.concatenate([velocity / robot.reach, turn])


def _unit_of(jac: np.ndarray, reach: float) -> np.ndarray:
    """Ju = [Jp / L; Jr] of J = [Jp; Jr] (6, dof)."""
    return np.vstack([jac[:3] / reach, jac[3:]])


def _unit(robot, jac: np.ndarray) -> np.ndarray:
    return _unit_of(jac, robot.reach)


def _arm(mapping: dict):
    """The arm simbench derives from a robot mapping (SI)."""
    return load_robot(mapping, "arm", Units())


def _lines(mapping: dict, rng, count: int, length=(0.05, 0.2)):
    """`count` random lines the arm can reach (cartesian_path's check): starts uniform within the ranges (a tenth of
    each width clear), `length` m in a random direction."""
    robot = _arm(mapping)
    found = 0
    while found < count:
        start = robot.lower + (robot.upper - robot.lower) * rng.uniform(0.1, 0.9, robot.dof)
        direction = rng.normal(size=3)
        by = direction / np.linalg.norm(direction) * rng.uniform(*length)
        try:
            _scenario(mapping, start, by, "pinv")
        except ScenarioError:
            continue
        found += 1
        yield start, by


PUMA = {"model": str(XML), "tool": {"site": "tool"}, "speed_limits": np.deg2rad([30.0] * 6).tolist()}
XARM = {"model": str(ARMS["xarm7"][0]), "speed_limits": [SLOW] * 7}


def _puma(robot):
    return Mujoco(robot.joints)


def _xarm(robot):
    return Kinematics("xarm7", robot.joints, robot.arm.chain.tool.body)


# --- sns -----------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize(("mapping", "kinematics", "seed"), [(PUMA, _puma, 11), (XARM, _xarm, 12)],
                         ids=["puma600", "xarm7"])
def test_sns_keeps_every_bound_and_scales_the_commanded_twist_without_turning_it(mapping, kinematics, seed):
    rng = np.random.default_rng(seed)
    scaled = saturated_whole = equal_to_pinv = 0
    for start, by in _lines(mapping, rng, 8):
        _, robot, plan = _plan(mapping, start, by, "sns")
        mj = kinematics(robot)
        tool0, r0 = mj.pose(start)
        assert np.all(np.abs(plan.qd_ref) <= robot.qd_max * (1 + 1e-9))
        assert np.all((plan.q_ref >= robot.lower) & (plan.q_ref <= robot.upper))
        scale = plan.series["plan_speed_scale"]
        for k in range(len(plan.t)):
            q, qd = plan.q_ref[k], plan.qd_ref[k]
            ju, x = _unit(robot, mj.jacobian(q)), _commanded(mj, robot, plan, k, tool0, by, r0)
            assert 0.0 <= scale[k] <= 1.0
            assert np.linalg.norm(ju @ qd - scale[k] * x) <= 1e-9 * (1 + np.linalg.norm(x)), k
            pinv = np.linalg.pinv(ju, rcond=1e-12)
            rates = pinv @ x
            if robot.dof > 6:
                rates += (np.eye(robot.dof) - pinv @ ju) @ (NULL_GAIN * (start - q))
            after = q + DT * rates
            if np.all(np.abs(rates) < (1 - 1e-9) * robot.qd_max) and np.all(after <= robot.upper) and \
                    np.all(after >= robot.lower):
                np.testing.assert_allclose(qd, rates, rtol=0, atol=1e-9 * (1 + np.abs(rates).max()))
                equal_to_pinv += 1
            elif scale[k] == 1.0:
                saturated_whole += 1  # pinv's rates pass a bound, yet the whole task is made
            scaled += scale[k] < 1
    assert equal_to_pinv > 100 and scaled > 10  # measured: 423 and 625 (PUMA), 313 and 731 (xArm7)
    if mapping is XARM:
        assert saturated_whole > 0


# --- priority ------------------------------------------------------------------------------------------------------

def _priority_expected(ju: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, float]:
    """J1+ x1 plus the damped least-squares y of J2 N1 y = x2 - J2 J1+ x1 (np.linalg.lstsq of [J2 N1; lambda I]),
    lambda by dls_adaptive's rule from J2 N1's least singular value; and J1's least singular value."""
    j1, j2 = ju[:3], ju[3:]
    j1_plus = np.linalg.pinv(j1)
    n1 = np.eye(ju.shape[1]) - j1_plus @ j1
    first = j1_plus @ x[:3]
    projected = j2 @ n1
    sigma = np.linalg.svd(projected, compute_uv=False)[-1]
    lam = np.sqrt(LAMBDA_MAX**2 * (1 - (sigma / EPSILON) ** 2)) if sigma < EPSILON else 0.0
    stacked = np.vstack([projected, lam * np.eye(ju.shape[1])])
    second = np.linalg.lstsq(stacked, np.concatenate([x[3:] - j2 @ first, np.zeros(ju.shape[1])]), rcond=None)[0]
    return first + second, float(np.linalg.svd(j1, compute_uv=False)[-1])


def test_priority_keeps_the_point_exactly_and_the_orientation_by_least_squares_in_what_it_leaves():
    rng = np.random.default_rng(21)
    checked = damped = 0
    for start, by in _lines(PUMA, rng, 8):
        _, robot, plan = _plan(PUMA, start, by, "priority")
        mj = Mujoco(robot.joints)
        tool0, r0 = mj.pose(start)
        assert np.all(np.abs(plan.qd_ref) <= robot.qd_max)
        scale = plan.series["plan_speed_scale"]
        for k in range(len(plan.t)):
            if plan.info["range_held_from"] is not None and plan.t[k] >= plan.info["range_held_from"]:
                break
            ju, x = _unit(robot, mj.jacobian(plan.q_ref[k])), _commanded(mj, robot, plan, k, tool0, by, r0)
            expected, sigma_1 = _priority_expected(ju, x)
            if sigma_1 < EPSILON:  # J1 damped near its own singularity
                continue
            rates = plan.qd_ref[k] / scale[k]
            point = np.linalg.pinv(ju[:3]) @ x[:3]
            np.testing.assert_allclose(ju[:3] @ rates, ju[:3] @ point, rtol=0, atol=1e-9 * (1 + np.abs(x).max()))
            np.testing.assert_allclose(rates, expected, rtol=0, atol=1e-8 * (1 + np.abs(expected).max()))
            checked += 1
            damped += plan.series["plan_damping"][k] > 0
    assert checked > 800 and damped > 0  # measured: 1048 and 174


def test_priority_on_a_planar_arm_makes_the_whole_twist_as_pinv_does():
    """The planar 3R (simbench-planar3r's MJCF), its orientation held: the point's z row and the orientation's x and
    y rows never move, so J1 has rank 2 and J2 N1 rank 1 everywhere; priority damps neither for that (before, it
    damped both at LAMBDA_MAX and turned the tool), and on random lines in its plane far from its stretched elbow
    J qd is the commanded twist at every sample, as pinv's."""
    import mujoco

    from simbench.commands.bench.robots import SHIPPED

    mapping = SHIPPED["planar3r"]().mapping
    rng = np.random.default_rng(23)
    robot = _arm(mapping)
    mj = Mujoco(robot.joints, mujoco.MjModel.from_xml_path(mapping["model"]))
    for _ in range(4):
        start = np.array([rng.uniform(-1, 1), rng.uniform(0.8, 1.8), rng.uniform(-1, 1)])
        angle = rng.uniform(0, 2 * np.pi)
        by = 0.05 * np.array([np.cos(angle), np.sin(angle), 0.0])
        _, robot, plan = _plan(mapping, start, by, "priority")
        tool0, r0 = mj.pose(start)
        assert not plan.violations and plan.series["plan_damping"].max() == 0
        for k in range(len(plan.t)):
            x = _commanded(mj, robot, plan, k, tool0, by, r0)
            made = _unit(robot, mj.jacobian(plan.q_ref[k])) @ plan.qd_ref[k] / plan.series["plan_speed_scale"][k]
            np.testing.assert_allclose(made, x, rtol=0, atol=1e-9 * (1 + np.abs(x).max()))


def test_priority_at_a_wrist_singularity_keeps_the_point_with_bounded_rates():
    """The PUMA's rule at random joints with q5 within 1e-4 rad of 0 (the wrist's axes 4 and 6 in line; J1 far from
    its own singularity) and random twists: J1 qd = x1 exactly, |qd| within |J1+ x1| + |x2 - J2 J1+ x1| / (2 lambda),
    lambda by the documented rule, where pinv's rates are a hundred times that and more (the median)."""
    from simbench.planners.path_methods import priority_rates

    mj = Mujoco(["q1", "q2", "q3", "q4", "q5", "q6"])
    rng = np.random.default_rng(22)
    reach, ratios = 0.9, []
    while len(ratios) < 24:
        q = rng.uniform(-2.0, 2.0, 6)
        q[4] = rng.choice([-1, 1]) * 10 ** rng.uniform(-6, -4)
        ju = _unit_of(mj.jacobian(q), reach)
        if np.linalg.svd(ju[:3], compute_uv=False)[-1] < EPSILON:
            continue
        x = rng.normal(size=6)
        rates = priority_rates(ju, x)[0]
        np.testing.assert_allclose(ju[:3] @ rates, x[:3], rtol=0, atol=1e-9 * np.abs(x).max())
        first = np.linalg.pinv(ju[:3]) @ x[:3]
        projected = ju[3:] @ (np.eye(6) - np.linalg.pinv(ju[:3]) @ ju[:3])
        sigma = np.linalg.svd(projected, compute_uv=False)[-1]
        lam = LAMBDA_MAX * np.sqrt(1 - (sigma / EPSILON) ** 2)
        bound = np.linalg.norm(first) + np.linalg.norm(x[3:] - ju[3:] @ first) / (2 * lam)
        assert sigma < 1e-3 and np.linalg.norm(rates) <= bound * (1 + 1e-9)
        ratios.append(np.linalg.norm(np.linalg.pinv(ju, rcond=1e-12) @ x) / bound)
    assert np.median(ratios) > 100


def test_priority_crosses_paper_002s_wrist_line_on_the_line_within_the_speed_limits():
    start = np.deg2rad(START)
    mapping = {"model": str(XML), "tool": {"site": "tool"}, "speed_limits": np.deg2rad(SPEED).tolist()}
    mj = Mujoco(["q1", "q2", "q3", "q4", "q5", "q6"])
    tool0, _ = mj.pose(start)
    _, robot, plan = _plan(mapping, start, np.array([0.780, -0.149, -0.200]) - tool0, "priority", duration=2.0,
                           dt=0.002)
    tool = np.array([mj.pose(q)[0] for q in plan.q_ref])
    assert _line_distance(tool, tool0, np.array([0.780, -0.149, -0.200])).max() < 1e-4  # measured: 0.024 mm
    assert np.linalg.norm(tool[-1] - [0.780, -0.149, -0.200]) < 1e-5
    assert np.all(np.abs(plan.qd_ref) <= robot.qd_max) and plan.series["plan_speed_scale"].min() < 1


# --- gradient ------------------------------------------------------------------------------------------------------

def _w(robot, mj, q) -> float:
    return float(np.prod(np.linalg.svd(_unit(robot, mj.jacobian(q)), compute_uv=False)))


def _grad_w(robot, mj, q, step: float = 1e-5) -> np.ndarray:
    return np.array([(_w(robot, mj, q + step * e) - _w(robot, mj, q - step * e)) / (2 * step)
                     for e in np.eye(len(q))])


XARM_OWN = {"model": str(ARMS["xarm7"][0])}  # its URDF's speed limits


def test_gradient_is_pinv_plus_manipulabilitys_gradient_in_the_null_space_and_moves_the_tool_by_nothing():
    """At random samples of random lines: qd - J+ x is GRADIENT_GAIN (I - J+ J) grad w, grad w by central
    differences of MuJoCo's Jacobian here, and J times it is nothing. On the lines both keep cleanly, w's mean along
    the plan against pinv's (which returns to its start posture instead): measured 1.0003 to 1.17 times on these 9
    of 10 (seed 32); its next 6 lines have two at 0.985 and 0.988, pinv's posture return ending higher there, so
    asserted: their mean at least 1, two thirds at least 1."""
    rng = np.random.default_rng(32)
    robot = _arm(XARM_OWN)
    mj = _xarm(robot)
    ratios, checked = [], 0
    for start, by in _lines(XARM_OWN, rng, 10):
        _, _, plan = _plan(XARM_OWN, start, by, "gradient")
        assert plan.info["gradient_gain"] == GRADIENT_GAIN
        tool0, r0 = mj.pose(start)
        for k in rng.choice(len(plan.t), 6, replace=False):
            if plan.info["range_held_from"] is not None and plan.t[k] >= plan.info["range_held_from"]:
                continue
            q, qd = plan.q_ref[k], plan.qd_ref[k]
            ju, x = _unit(robot, mj.jacobian(q)), _commanded(mj, robot, plan, k, tool0, by, r0)
            pseudo = np.linalg.pinv(ju, rcond=1e-12)
            null_term = qd - pseudo @ x
            expected = GRADIENT_GAIN * (np.eye(7) - pseudo @ ju) @ _grad_w(robot, mj, q)
            np.testing.assert_allclose(null_term, expected, rtol=0, atol=1e-6 * (1 + np.abs(expected).max()))
            assert np.linalg.norm(ju @ null_term) <= 1e-9 * (1 + np.linalg.norm(null_term))
            checked += 1
        _, _, pinv = _plan(XARM_OWN, start, by, "pinv")
        if not any(p.violations or p.info["range_held_from"] is not None for p in (plan, pinv)):
            ratios.append(np.mean([_w(robot, mj, q) for q in plan.q_ref]) / np.mean([_w(robot, mj, q)
                                                                                     for q in pinv.q_ref]))
    assert checked > 40 and len(ratios) >= 8  # measured: 57 and 9
    assert np.mean(ratios) >= 1 and np.mean(np.array(ratios) >= 1) >= 2 / 3


def test_gradient_with_the_tool_still_climbs_manipulability_at_every_sample():
    """Where the task leaves the joints free to move (a 1 um line over 0.3 s, then 1 s still), w never falls by
    more than 1e-10 a sample (gradient ascent in the self-motion), rises overall, and the tool stays put."""
    rng = np.random.default_rng(33)
    robot = _arm(XARM_OWN)
    mj = _xarm(robot)
    for start, _ in _lines(XARM_OWN, rng, 6):
        by = rng.normal(size=3)
        by *= 1e-6 / np.linalg.norm(by)
        scenario = _scenario(XARM_OWN, start, by, "gradient", duration=0.3)
        scenario = scenario.model_copy(update={"timing": scenario.timing.model_copy(update={"hold": 1.0})})
        plan = scenario.planner_def.plan(scenario, scenario.robot_def, DT)
        w = np.array([_w(robot, mj, q) for q in plan.q_ref])
        assert np.diff(w).min() >= -1e-10 and w[-1] > w[0]
        tool = np.array([mj.pose(q)[0] for q in plan.q_ref])
        assert np.linalg.norm(tool - tool[0], axis=1).max() < 2e-6
        assert np.abs(plan.q_ref[-1] - start).max() > 1e-3  # the joints moved


def test_gradient_on_an_arm_with_no_joint_to_spare_is_a_one_line_error(tmp_path, capsys):
    path = tmp_path / "puma.yaml"
    path.write_text(yaml.safe_dump({"robot": PUMA, "planner": "cartesian_path",
                                    "task": {"start": list(START), "path": [{"line": {"by": [50.0, 0, 0]}}],
                                             "method": "gradient"},
                                    "units": {"angle": "deg", "length": "mm"},
                                    "timing": {"law": "quintic", "duration": 1.0}}))
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "task.method" in err and str(path) in err and "6" in err


def test_the_bench_writes_gradient_for_redundant_arms_alone_and_sns_and_priority_for_every_arm():
    """gradient where the arm has more joints than its tasks' rows (the Panda's 7 for 6; the spherical arm's 4 for
    the tool's point's 3), none on the PUMA and the planar 3R; sns and priority for every arm, each a valid scenario;
    none of the three in a suite's default methods (they run where named)."""
    from simbench.commands.bench.methods import METHODS, installed
    from simbench.commands.bench.robots import SHIPPED
    from simbench.commands.bench.tasks import Task

    assert not {"sns", "gradient", "priority"} & set(installed())

    for name, redundant in (("puma600", False), ("panda", True), ("spherical_arm", True), ("planar3r", False)):
        robot = SHIPPED[name]()
        arm = robot.model_arm()
        start = tuple(float(v) for v in np.clip(0.3, arm.lower, arm.upper))
        point = arm.fk(np.array([start]))[0]
        end = point * (1 - 0.02 / np.linalg.norm(point))  # 2 cm towards the world's origin
        task = Task(name, 0, "far", "line", start, start, {"line": {"end": end.tolist()}},
                    (1.0, 0.0, 0.0, 0.0), start, 1.0, 0.02, 1.0)
        assert (METHODS["gradient"].document(task, robot) is not None) == redundant
        for method in ("sns", "priority") + (("gradient",) if redundant else ()):
            doc = METHODS[method].document(task, robot)
            assert doc["task"]["method"] == method
            parse_scenario(doc, f"{name} {method}")
