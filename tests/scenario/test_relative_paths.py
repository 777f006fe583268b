"""cartesian_path's segments placed from where the path is (issue 46): a line `by` an offset in the world frame or
`by_tool` in the tool's frame at the start, an arc about a centre `center_by` / `center_by_tool` from where it
starts, bad combinations refused in one line, and the plan's warning at a corner between segments. On
example-robot-data's UR5 read from its URDF untouched, in millimetres and degrees; the truth is MuJoCo's own
kinematics of a plain compile of that URDF (test_cartesian_path_damping.Kinematics), not simbench's."""

import re

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

from simbench.cli import main
from simbench.scenario import load_scenario
from tests.planners.test_cartesian_path_damping import ARMS, Kinematics

START = [17.0, -57.0, 57.0, -57.0, 57.0, 17.0]  # deg: the UR5 well inside its ranges and reach
DT = 0.002  # s
NEAR = 0.5e-3  # m: the plan's (and the run's) tool within this of the truth


def _write(folder, path: list[str], name: str, duration: float = 2.0):
    """A cartesian_path scenario on the UR5 (deg, mm) from START along `path` (segments in YAML's flow style)."""
    segments = "".join(f"\n    - {segment}" for segment in path)
    file = folder / f"{name}.yaml"
    file.write_text(f"robot: {{model: {ARMS['ur5'][0]}, tool: {{body: tool0}}}}\nplanner: cartesian_path\n"
                    f"units: {{angle: deg, length: mm}}\ntask:\n  start: {START}\n  path:{segments}\n"
                    f"timing: {{law: quintic, duration: {duration}, hold: 0.3}}\n")
    return file


@pytest.fixture(scope="module")
def truth(tmp_path_factory):
    """MuJoCo's Kinematics of the UR5 and its tool's point and rotation at START."""
    robot = load_scenario(_write(tmp_path_factory.mktemp("ur5"), ["line: {by: [0, 10, 0]}"], "probe")).robot_def
    mj = Kinematics("ur5", robot.joints, "tool0")
    return (mj, *mj.pose(np.deg2rad(START)))


def _plan(file):
    scenario = load_scenario(file)
    return scenario.planner_def.plan(scenario, scenario.robot_def, DT)


@pytest.mark.parametrize("field", ["by", "by_tool"])
def test_a_line_by_an_offset_ends_at_the_start_s_tool_point_plus_the_offset(truth, tmp_path, field):
    """by: p0 + offset; by_tool: p0 + R0 offset (R0 turns 138 deg here: the two ends lie 144 mm apart). The plan's
    last joints put MuJoCo's tool there (measured: 1e-13 mm off), and the report's last waypoint is that point."""
    mj, p0, r0 = truth
    offset = np.array([60.0, -40.0, 30.0]) / 1e3
    end = p0 + (offset if field == "by" else r0 @ offset)
    plan = _plan(_write(tmp_path, [f"line: {{{field}: {(offset * 1e3).tolist()}}}"], field))
    assert np.linalg.norm(mj.pose(plan.q_ref[-1])[0] - end) < NEAR
    assert np.linalg.norm(np.array(plan.waypoints[-1]["X"]) - end) < 1e-6
    assert np.linalg.norm(np.array(plan.waypoints[0]["X"]) - p0) < 1e-6


def test_the_run_of_a_by_tool_line_ends_where_the_offset_says(truth, tmp_path):
    _, p0, r0 = truth
    offset = np.array([0.0, 50.0, -40.0]) / 1e3
    out = tmp_path / "out"
    assert main(["run", str(_write(tmp_path, [f"line: {{by_tool: {(offset * 1e3).tolist()}}}"], "run")),
                 "--out", str(out), "--no-video", "--quiet"]) == 0
    tool = np.load(out / "timeseries.npz")["tool"]
    assert np.linalg.norm(tool[-1] - (p0 + r0 @ offset)) < NEAR  # measured: 1.5e-6 mm


@pytest.mark.parametrize("case", ["center_by after a by line", "center_by_tool"])
def test_a_relative_arc_turns_about_its_centre_from_where_the_path_is(truth, tmp_path, case):
    """center_by: the centre 40 mm along -y from the end of a 40 mm line up, the arc about world x, 90 deg (it
    goes on along the line, +z); center_by_tool: the centre 30 mm along the tool's x at the start, the arc about
    the tool's z there, 120 deg. With radius, start and ref left out the arc starts where the path is and `end` is
    the angle swept: the plan's tool stays on the circle and ends at the start turned by that angle about the
    centre."""
    mj, p0, r0 = truth
    if case == "center_by_tool":
        path = ["arc: {center_by_tool: [30, 0, 0], normal: [0, 0, 1], end: 120}"]
        first, center, normal, sweep = p0, p0 + r0 @ [0.03, 0.0, 0.0], r0 @ [0.0, 0.0, 1.0], 120.0
    else:
        path = ["line: {by: [0, 0, 40]}", "arc: {center_by: [0, -40, 0], normal: [1, 0, 0], end: 90}"]
        first = p0 + [0.0, 0.0, 0.04]
        center, normal, sweep = first + [0.0, -0.04, 0.0], np.array([1.0, 0.0, 0.0]), 90.0
    end = center + Rotation.from_rotvec(np.deg2rad(sweep) * normal).apply(first - center)
    plan = _plan(_write(tmp_path, path, "arc", duration=3.0))
    assert np.allclose(plan.info["path"][-1]["arc"]["center"], center, atol=1e-6)
    tool = np.array([mj.pose(q)[0] for q in plan.q_ref[::10]])
    arc = tool[plan.s[::10] >= plan.waypoints[-2]["s"]]
    radius = np.linalg.norm(first - center)
    assert np.abs(np.linalg.norm(arc - center, axis=1) - radius).max() < NEAR
    assert np.abs((arc - center) @ normal).max() < NEAR
    assert np.linalg.norm(mj.pose(plan.q_ref[-1])[0] - end) < NEAR
    assert np.linalg.norm(np.array(plan.waypoints[-1]["X"]) - end) < 1e-6
    assert plan.warnings == ()  # no corner: the arc goes on along the line


@pytest.mark.parametrize("segment, field, says", [
    ("line: {end: [500, 0, 300], by: [0, 10, 0]}", "task.path[0].line",
     "exactly one of 'end', 'by' or 'by_tool', got 'end' and 'by'"),
    ("line: {by: [0, 10, 0], by_tool: [0, 0, 10]}", "task.path[0].line", "got 'by' and 'by_tool'"),
    ("line: {start: [500, 0, 300]}", "task.path[0].line", "got none"),
    ("line: {by: [0, 0, 0]}", "task.path[0].line", "a line needs a length"),
    ("line: {by: [0, 20000, 0]}", "task.path[0].line.by", "in [-10000, 10000] mm, got 20000 mm"),
    ("arc: {center: [500, 0, 300], center_by: [0, 10, 0], normal: [0, 0, 1], radius: 10, start: 0, end: 90}",
     "task.path[0].arc", "exactly one of 'center', 'center_by' or 'center_by_tool', got 'center' and 'center_by'"),
    ("arc: {center: [500, 0, 300], normal: [0, 0, 1], end: 90}", "task.path[0].arc", "needs its radius and start"),
    ("arc: {center_by: [0, 10, 30], normal: [0, 0, 1], end: 90}", "task.path[0].arc.center_by",
     "puts the arc's plane 30.000 mm from where it starts"),
    ("arc: {center_by_tool: [0, 0, 30], normal: [0, 0, 1], end: 90}", "task.path[0].arc.center_by_tool",
     "puts the arc's plane 30.000 mm from where it starts"),
])
def test_a_bad_segment_is_one_line_naming_its_field(tmp_path, capsys, segment, field, says):
    file = _write(tmp_path, [segment], "bad")
    assert main(["validate", "--no-plan", str(file)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and str(file) in err and f"{field}:" in err and says in err, err


def test_an_absolute_line_after_a_relative_segment_still_needs_its_start(tmp_path, capsys):
    file = _write(tmp_path, ["line: {by: [0, 10, 0]}", "line: {end: [500, 0, 300]}"], "later")
    assert main(["validate", "--no-plan", str(file)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "task.path[1].line.start: missing" in err and "'by'" in err


def _quintic_speed(length: float, s: float, duration: float) -> float:
    """The tool's speed (m/s) at path parameter s of a path `length` long under the quintic law."""
    tau = brentq(lambda x: 10 * x**3 - 15 * x**4 + 6 * x**5 - s, 0.0, 1.0)
    return length * 30 * tau**2 * (1 - tau) ** 2 / duration


@pytest.mark.parametrize("line, angle", [("[0, 100, 0]", 90.0), ("[-100, 0, 0]", None)])
def test_a_corner_between_segments_is_a_plan_warning_a_smooth_join_is_not(tmp_path, capsys, line, angle):
    """A quarter circle of 50 mm about z from the tool's point ends heading along -x (its tangent z x y there);
    then a 100 mm line along +y turns 90 deg: the warning names the corner, its angle, and the tool's velocity
    jump 2 v sin(45 deg), v the quintic law's speed where the line starts (s = 78.5 / 178.5 of the path). A line
    along -x goes on smoothly: no warning."""
    file = _write(tmp_path, ["arc: {center_by: [-50, 0, 0], normal: [0, 0, 1], end: 90}", f"line: {{by: {line}}}"],
                  "corner")
    main(["validate", str(file)])
    warnings = [row for row in capsys.readouterr().out.splitlines() if "plan warning" in row]
    if angle is None:
        assert warnings == []
        return
    assert len(warnings) == 1 and f"task.path[1] turns {angle:.1f} deg from the end of task.path[0]" in warnings[0]
    arc = 0.05 * np.pi / 2
    speed = _quintic_speed(arc + 0.1, arc / (arc + 0.1), 2.0)
    said = re.search(r"\(([\d.]+) mm/s\) turns .* a jump of ([\d.]+) mm/s", warnings[0]).groups()
    jump = 2 * speed * np.sin(np.deg2rad(45))
    assert [float(v) for v in said] == pytest.approx([speed * 1e3, jump * 1e3], rel=0.01)
