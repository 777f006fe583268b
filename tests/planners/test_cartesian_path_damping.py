"""cartesian_path's default method, dls_adaptive, and its load-time reach check, on three arms nobody here modelled:
example-robot-data's UR5, xArm7 and Z1, read from their URDFs untouched and judged by MuJoCo's own kinematics of a
plain compile of each URDF (mj_kinematics, mj_jac), not simbench's:

  - on random lines starting near a rank loss (sigma_min_unit under 2 EPSILON; start uniform within the ranges,
    10 % of each width clear; 50-300 mm in a random direction) whose pinv plan keeps the path, the joint ranges and
    the speed limits, dls_adaptive's plan keeps the path too, within 0.1 mm, and its rates make the commanded twist
    exactly, J qd = x_d + K e: no damping where sigma_min_unit >= EPSILON, nor in a passage below it that pinv
    crosses within the speed limits. Before, every passage was damped: 10 of these 31 lines left the path by
    0.2-3.3 mm (and of bench_random_lines-style lines, 60 a arm at seed 7, 11 of the UR5's 41 such lines, 4 of the
    xArm7's 43 and 1 of the Z1's 33, by up to 3.35 mm);
  - a line's end, or an arc's farthest point, farther from the first joint's anchor than the chain's length (an
    upper bound on the reach, computed here from MuJoCo's anchors) is refused at load, in one line naming the field,
    the distance and the reach (exit 2); a path through points the arm reaches is not.
"""

import re
from importlib.metadata import distribution

import mujoco
import numpy as np
import pytest

from simbench.cli import main
from simbench.planners.path_methods import EPSILON
from simbench.planners.resolved_rates import CLIK_SHARE
from simbench.scenario import load_scenario

ROBOTS = (distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data") / "robots")
ARMS = {  # name: (URDF, its robot mapping's other fields, joints inside the ranges (rad))
    "ur5": (ROBOTS / "ur_description" / "urdf" / "ur5_robot.urdf", "tool: {body: tool0}",
            [0.3, -1.0, 1.0, -1.0, 1.0, 0.3]),
    "xarm7": (ROBOTS / "xarm_description" / "urdf" / "xarm7.urdf", "", [0.3, 0.3, 0.3, 1.0, 0.3, 0.3, 0.3]),
    "z1": (ROBOTS / "z1_description" / "urdf" / "z1.urdf",
           "tool: {body: gripperStator}, joints: [joint1, joint2, joint3, joint4, joint5, joint6]",
           [0.3, 1.0, -1.0, 0.3, 0.3, 0.3]),
}
LINES, SEED, NEAR = 20, 7, 2 * EPSILON  # a arm
SPEED, HOLD, DT = 0.1, 0.3, 0.002  # m/s along the line (at least 1 s), s, s
KEPT = 1e-4  # m: the path kept


def _mapping(arm: str) -> str:
    urdf, fields, _ = ARMS[arm]
    return f"{{model: {urdf}{', ' + fields if fields else ''}}}"


def _write(folder, arm: str, start, path: list[str], name: str = "line") -> str:
    """A cartesian_path scenario (SI) on `arm`: joints `start`, path segments in YAML's flow style, quintic."""
    segments = "".join(f"\n    - {segment}" for segment in path)
    file = folder / f"{arm}-{name}.yaml"
    file.write_text(f"robot: {_mapping(arm)}\nplanner: cartesian_path\ntask:\n  start: {[float(v) for v in start]}\n"
                    f"  path:{segments}\ntiming: {{law: quintic, duration: 1.0, hold: {HOLD}}}\n")
    return str(file)


class Kinematics:
    """MuJoCo's own compile of the arm's URDF, its meshes left out and its fixed links kept as bodies: the tool body's
    point and orientation, J = [Jp; Jr] there, and the chain's anchors, at the joints `joints`."""

    def __init__(self, arm: str, joints, tool: str):
        text = re.sub(r"<(visual|collision)\b.*?</\1>", "", ARMS[arm][0].read_text(), flags=re.DOTALL)
        text = re.sub(r"(<robot\b[^>]*>)", r'\1<mujoco><compiler fusestatic="false"/></mujoco>', text, count=1)
        self.model = mujoco.MjModel.from_xml_string(text)
        self.data = mujoco.MjData(self.model)
        self.ids = [self.model.joint(name).id for name in joints]
        self.adr = [self.model.joint(name).qposadr[0] for name in joints]
        self.dofs = [self.model.joint(name).dofadr[0] for name in joints]
        self.body = self.model.body(tool).id

    def pose(self, q) -> tuple[np.ndarray, np.ndarray]:
        self.data.qpos[self.adr] = q
        mujoco.mj_kinematics(self.model, self.data)
        return self.data.xpos[self.body].copy(), self.data.xmat[self.body].reshape(3, 3).copy()

    def jacobian(self, q) -> np.ndarray:
        point, _ = self.pose(q)
        mujoco.mj_comPos(self.model, self.data)
        jacp, jacr = np.zeros((3, self.model.nv)), np.zeros((3, self.model.nv))
        mujoco.mj_jac(self.model, self.data, jacp, jacr, point, self.body)
        return np.vstack([jacp[:, self.dofs], jacr[:, self.dofs]])

    def chain_length(self) -> tuple[np.ndarray, float]:
        """The first joint's anchor and the polyline through the joints' anchors to the tool at qpos0: no joint
        values put the tool farther from that anchor (each link's span between its anchors is fixed)."""
        self.data.qpos[:] = self.model.qpos0
        mujoco.mj_kinematics(self.model, self.data)
        points = np.vstack([self.data.xanchor[self.ids], self.data.xpos[self.body]])
        return points[0].copy(), float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


@pytest.fixture(scope="module", params=list(ARMS))
def arm(request, tmp_path_factory):
    """(name, a loaded scenario on the arm, its Robot, MuJoCo's Kinematics of it)."""
    folder = tmp_path_factory.mktemp(request.param)
    base = load_scenario(_write(folder, request.param, ARMS[request.param][2], ["line: {end: [0.3, 0.2, 0.3]}"]))
    robot = base.robot_def
    return request.param, base, robot, Kinematics(request.param, robot.joints, robot.arm.chain.tool.body)


def _sigma_min_unit(robot, jac: np.ndarray) -> np.ndarray:
    """The least singular value of [Jp / L; Jr] (..., 6, dof), L the reach."""
    unit = np.array([1 / robot.reach] * 3 + [1.0] * 3)
    return np.linalg.svd(unit[:, None] * jac, compute_uv=False)[..., -1]


def _lines(robot, mj: Kinematics, n: int, seed: int):
    """n random lines starting near a rank loss (sigma_min_unit under NEAR there), where dls_adaptive's passages
    are: start joints, the tool's point there (MuJoCo's), the end point, the duration."""
    rng = np.random.default_rng(seed)
    low, high = robot.lower, robot.upper
    width = high - low
    lines = []
    while len(lines) < n:
        q = rng.uniform(low + 0.1 * width, high - 0.1 * width)
        if _sigma_min_unit(robot, mj.jacobian(q)) >= NEAR:
            continue
        start = mj.pose(q)[0]
        direction = rng.normal(size=3)
        length = rng.uniform(0.05, 0.3)
        end = start + length * direction / np.linalg.norm(direction)
        if min(start[2], end[2]) >= 0.05:  # both above the floor
            lines.append((q, start, end, max(1.0, length / SPEED)))
    return lines


def _plan(base, robot, q, end, duration: float, method: str, **fields):
    """The plan of one line by `method` (and the task's other `fields`), on the base scenario's arm, at control
    period DT."""
    task = type(base.task).model_validate({"start": [float(v) for v in q], "path": [{"line": {"end": list(end)}}],
                                           "method": method, **fields}, context={"robot": robot})
    scenario = base.model_copy(update={"task": task, "timing": base.timing.model_copy(update={"duration": duration})})
    return scenario.planner_def.plan(scenario, robot, DT)


def _segment_distance(points, a, b) -> np.ndarray:
    along = np.clip((points - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
    return np.linalg.norm(points - (a + along[:, None] * (b - a)), axis=1)


def _keeps(plan, mj: Kinematics, robot, a, b) -> bool:
    """The plan's tool (MuJoCo's, at q_ref) within KEPT of the line and of its end, q_ref inside MuJoCo's joint
    ranges, and its finite-difference speeds within the speed limits."""
    tool = np.array([mj.pose(q)[0] for q in plan.q_ref])
    ranges = mj.model.jnt_range[mj.ids]  # every joint of these arms has one
    speed = np.abs(np.diff(plan.q_ref, axis=0)) / np.diff(plan.t)[:, None]
    return bool(_segment_distance(tool, a, b).max() <= KEPT and np.linalg.norm(tool[-1] - b) <= KEPT
                and np.all((plan.q_ref >= ranges[:, 0]) & (plan.q_ref <= ranges[:, 1]))
                and np.all(speed <= robot.qd_max))


def _commanded(mj: Kinematics, plan, a, b, r0, duration: float) -> np.ndarray:
    """The commanded twists [v; w] (N, 6, SI): the line's under the quintic law plus K times the tool's error at
    q_ref (its point from the line's at s(t), and 1/2 sum n x n_d from the start's orientation)."""
    tau = np.clip(plan.t / duration, 0.0, 1.0)
    s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    ds = (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / duration
    gain = CLIK_SHARE / DT
    out = []
    for q, si, dsi in zip(plan.q_ref, s, ds):
        point, rotation = mj.pose(q)
        turn = 0.5 * np.cross(rotation.T, r0.T).sum(axis=0)
        out.append(np.concatenate([(b - a) * dsi + gain * (a + si * (b - a) - point), gain * turn]))
    return np.array(out)


def test_dls_adaptive_keeps_the_path_wherever_pinv_keeps_it_within_the_limits(arm):
    name, base, robot, mj = arm
    kept = near = 0
    for q, a, b, duration in _lines(robot, mj, LINES, SEED):
        if not _keeps(_plan(base, robot, q, b, duration, "pinv"), mj, robot, a, b):
            continue
        plan = _plan(base, robot, q, b, duration, "dls_adaptive", knot_step=0)  # every sample by the rule
        assert _keeps(plan, mj, robot, a, b), (name, np.rad2deg(q).round(3).tolist(), b.tolist())
        jac = np.array([mj.jacobian(row) for row in plan.q_ref])
        twist = _commanded(mj, plan, a, b, mj.pose(q)[1], duration)
        made = np.einsum("nij,nj->ni", jac, plan.qd_ref)
        np.testing.assert_allclose(made, twist, rtol=0, atol=1e-8 * (1 + np.abs(twist).max()))  # undamped
        kept, near = kept + 1, near + (_sigma_min_unit(robot, jac).min() < EPSILON)
    assert kept >= 3 and near >= 1  # measured: 15, 13 and 3 lines of 20 (UR5, xArm7, Z1), 8, 10 and 1 of them
    # through a passage below EPSILON


def test_knots_keep_the_path_as_the_samples_resolved_alone_do(arm):
    """resolved_rates.integrate's knots (the default knot_step): on random lines near a rank loss, by MuJoCo's own
    kinematics, the tool no farther from the line's point at each time than with every sample resolved alone (the
    worst sample, to 1 um; where alone it is on the point, within 1 um at the median), the same end, and the speeds
    within the limits."""
    name, base, robot, mj = arm
    for q, a, b, duration in _lines(robot, mj, LINES // 2, SEED + 1):
        alone = _plan(base, robot, q, b, duration, "dls_adaptive", knot_step=0)
        knots = _plan(base, robot, q, b, duration, "dls_adaptive")
        assert np.array_equal(alone.t, knots.t)
        tau = np.clip(knots.t / duration, 0.0, 1.0)
        asked = a + np.outer(10 * tau**3 - 15 * tau**4 + 6 * tau**5, b - a)  # the line's point at each time
        miss = {key: np.linalg.norm(np.array([mj.pose(row)[0] for row in plan.q_ref]) - asked, axis=1)
                for key, plan in (("alone", alone), ("knots", knots))}
        assert miss["knots"].max() <= miss["alone"].max() + 1e-6, (name, miss["knots"].max(), miss["alone"].max())
        undamped = miss["alone"] <= 1e-6  # the samples where resolved alone the tool is on the line's point
        assert np.median(miss["knots"][undamped]) <= 1e-6
        assert abs(miss["knots"][-1] - miss["alone"][-1]) <= 1e-6
        assert np.all(np.abs(knots.qd_ref) <= robot.qd_max)


def _refusal(path: str, capsys) -> str:
    assert main(["validate", path]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and path in err
    return err


def _figures(err: str) -> tuple[float, float]:
    """The distance and the reach (m) a refusal names."""
    far, reach = re.search(r"([\d.]+) mm from .* reach of ([\d.]+) mm", err).groups()
    return float(far) / 1e3, float(reach) / 1e3


@pytest.mark.parametrize("beyond", [0.12, 0.49])
def test_a_line_ending_beyond_the_reach_is_refused_at_load(arm, tmp_path, capsys, beyond):
    name, base, _, mj = arm
    anchor, length = mj.chain_length()
    q = np.array(base.task.start)
    out = mj.pose(q)[0] - anchor
    end = anchor + (length + beyond) * out / np.linalg.norm(out)
    err = _refusal(_write(tmp_path, name, q, [f"line: {{end: {end.tolist()}}}"]), capsys)
    assert "task.path[0].line.end" in err
    far, reach = _figures(err)
    assert far == pytest.approx(length + beyond, abs=1e-4) and reach == pytest.approx(length, abs=1e-4)


def test_an_arc_reaching_past_the_reach_between_its_ends_is_refused(arm, tmp_path, capsys):
    """A circle through the tool's point, its centre 0.4 reach outward: its ends lie within the reach, its point
    opposite the tool's 0.8 reach farther out."""
    name, base, _, mj = arm
    anchor, length = mj.chain_length()
    q = np.array(base.task.start)
    point = mj.pose(q)[0]
    out = (point - anchor) / np.linalg.norm(point - anchor)
    normal = np.cross(out, [0.0, 0.0, 1.0]) if abs(out[2]) < 0.9 else np.cross(out, [1.0, 0.0, 0.0])
    arc = {"center": (point + 0.4 * length * out).tolist(), "radius": 0.4 * length, "normal": normal.tolist(),
           "ref": (-out).tolist(), "start": 0.0, "end": 2 * np.pi - 0.2}
    ends = [point, np.array(arc["center"]) + 0.4 * length * (np.cos(0.2) * -out - np.sin(0.2) * np.cross(normal, -out)
                                                             / np.linalg.norm(normal))]
    assert all(np.linalg.norm(p - anchor) < length for p in ends)
    err = _refusal(_write(tmp_path, name, q, [f"arc: {arc}"]), capsys)
    assert "task.path[0].arc" in err
    far, reach = _figures(err)
    assert far == pytest.approx(np.linalg.norm(point - anchor) + 0.8 * length, abs=1e-4)
    assert reach == pytest.approx(length, abs=1e-4)


def test_a_path_through_points_the_arm_reaches_is_not_refused(arm, tmp_path):
    """An arc the first joint sweeps (the tool turned about its axis), then lines through the tool's points at
    random joint values anywhere in the ranges."""
    name, base, robot, mj = arm
    rng = np.random.default_rng(3)
    q = np.array(base.task.start)
    point = mj.pose(q)[0]
    axis, anchor = mj.data.xaxis[mj.ids[0]].copy(), mj.data.xanchor[mj.ids[0]].copy()
    centre = anchor + ((point - anchor) @ axis) * axis
    radius = np.linalg.norm(point - centre)
    sweep = 1.0  # rad, within joint 1's range from the start's 0.3 rad
    path = [(f"arc: {{center: {centre.tolist()}, radius: {radius}, normal: {axis.tolist()}, "
             f"ref: {((point - centre) / radius).tolist()}, start: 0.0, end: {sweep}}}")]
    at = mj.pose(np.concatenate([[q[0] + sweep], q[1:]]))[0]
    for _ in range(12):
        then = mj.pose(rng.uniform(robot.lower, robot.upper))[0]
        path.append(f"line: {{start: {at.tolist()}, end: {then.tolist()}}}")
        at = then
    scenario = load_scenario(_write(tmp_path, name, q, path, "reachable"))
    assert len(scenario.task.path) == 13
