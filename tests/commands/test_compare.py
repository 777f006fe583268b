"""The mink baseline (simbench.planners.mink_baseline) and methods compared side by side (simbench.commands.compare).

The baseline is checked against the robots' analytic kinematics (robots/puma600.py, robots/spherical_arm.py), not
against its own report: on random straight lines the tool stays on the line, every joint within its range and
its speed limit (the rates measured as differences of the joint references). A comparison's table is checked
against separate simbench.evaluate runs of the same methods, written out as scenario files by hand.
"""

import csv

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

import simbench
from simbench import api
from simbench.analysis.singularity_handling import SingularityHandling
from simbench.commands.compare import compare
from simbench.core.errors import RunError, ScenarioError
from simbench.core.resources import models_dir
from simbench.planners import mink_baseline, random_tasks
from simbench.robots import puma600 as P
from simbench.robots import spherical_arm as S
from simbench.scenario import parse_scenario
from tests.conftest import scenario_file, segment_distance

DT = 0.01  # s: the random lines' control grid (100 Hz; the shipped scenarios run at 1 kHz: the same method)
N_LINES = 12
ON_LINE = 5e-4  # m: the tool's largest distance from the line: a tenth of the shipped path tolerance (at a 1 ms
# grid it is ten times less: each step's QP lags its target by about damping / sigma^2 of the step)
ON_ORIENTATION = np.deg2rad(0.05)  # the PUMA torch's largest turn from the line's orientation
FAR = api.Tolerance(np.deg2rad(10.0), 0.02)  # followed plans stay farther than this from singular sets
_SPEED = 1 + 1e-9  # a joint speed within its limit, to rounding
WRIST = scenario_file("puma600", "wrist_singularity")


def follow(doc: dict, **settings) -> dict:
    """A scenario document with mink_baseline following the document's planner and task."""
    return {**doc, "planner": "mink_baseline", "task": {"follow": doc["planner"], "task": doc["task"], **settings}}


def followed_plan(doc: dict):
    """(scenario, the followed planner's plan) of a mink_baseline document, on the DT grid."""
    scenario = parse_scenario(doc, "random")
    inner = mink_baseline.followed(scenario)
    return scenario, inner.planner_def.plan(inner, scenario.robot_def, DT)


def inside_limits(robot, q: np.ndarray, room: np.ndarray) -> bool:
    """Every joint at least `room` inside its range all along q."""
    return bool((q >= robot.lower + room).all() and (q <= robot.upper - room).all())


def far_and_slow(kinematics, plan) -> bool:
    """The plan keeps away from every singular set of the robot's kinematics module (FAR) and within 80 % of
    every speed limit."""
    near = min(s.distance.min() for s in kinematics.singular_sets(plan.q_ref, FAR))
    return near > 1.0 and (np.abs(plan.qd_ref) / kinematics.QD_MAX).max() < 0.8


def puma_lines():
    """N_LINES random PUMA lines (random_tasks, the torch within 30 deg of straight down) whose followed plan is
    far from singular sets and joint limits and slow enough to follow: (line start, end, torch rotation, followed
    plan, baseline plan)."""
    out = []
    for doc in random_tasks.puma_lines(60, seed=3, cone=np.deg2rad(30)):
        try:
            scenario, ref = followed_plan(follow(doc))
        except RunError:  # no configuration keeps this line within the joint ranges
            continue
        if far_and_slow(P, ref) and inside_limits(P.ROBOT, ref.q_ref, np.deg2rad(5.0)):
            line = doc["task"]["path"][0]["line"]
            w, x, y, z = doc["task"]["orientation"]["value"]
            out.append((np.array(line["start"]), np.array(line["end"]), Rotation.from_quat([x, y, z, w]), ref,
                        scenario.planner_def.plan(scenario, P.ROBOT, DT)))
        if len(out) == N_LINES:
            return out
    raise AssertionError("too few random PUMA lines far from singularities")


def spherical_lines():
    """N_LINES random lines of the spherical arm between two random configurations (paper 000's method, no
    workspace repair), whose followed plan is far from singular sets and limits: (line start, end, followed plan,
    baseline plan)."""
    rng = np.random.default_rng(5)
    lo, hi = np.array([0.0, 0.02, np.deg2rad(-60.0), 0.02]), np.array([2 * np.pi, 0.38, np.deg2rad(170.0), 0.38])
    out = []
    while len(out) < N_LINES:
        q0, q1 = rng.uniform(lo, hi, size=(2, 4))
        a, b = S.fk(q0)[0], S.fk(q1)[0]
        doc = {"robot": "spherical_arm", "planner": "safe_straight_path",
               "task": {"start": q0.tolist(), "goal": q1.tolist(), "workspace_repair": False},
               "timing": {"duration": max(1.0, float(np.linalg.norm(b - a)) / 0.1)}}
        scenario, ref = followed_plan(follow(doc))
        room = np.array([0.0, 0.01, 0.1, 0.01])
        if ref.warnings or not far_and_slow(S, ref) or not inside_limits(S.ROBOT, ref.q_ref, room):
            continue  # leaves the workspace, or comes near a singular set or a limit
        out.append((a, b, ref, scenario.planner_def.plan(scenario, S.ROBOT, DT)))
    return out


def assert_within_ranges_and_speeds(robot, plan) -> None:
    """Every joint inside its range, and its speed (differences of the references, and the plan's own rates)
    within its limit; the rates are those that carry each reference to the next."""
    q = plan.q_ref
    assert (q >= robot.lower - 1e-9).all() and (q <= robot.upper + 1e-9).all()
    assert (np.abs(np.diff(q, axis=0)) / plan.dt <= robot.qd_max * _SPEED).all()
    assert (np.abs(plan.qd_ref) <= robot.qd_max * _SPEED).all()
    assert np.allclose(q[:-1] + plan.qd_ref[:-1] * plan.dt, q[1:], rtol=0, atol=1e-12)


def test_on_random_puma_lines_the_baseline_keeps_the_torch_on_the_line_within_its_limits():
    for a, b, rotation, ref, plan in puma_lines():
        position, r06 = P.tool_pose(plan.q_ref)
        assert segment_distance(position, a, b).max() < ON_LINE
        assert np.linalg.norm(position[-1] - b) < ON_LINE  # it gets to the end, not only somewhere on the line
        turn = (Rotation.from_matrix(r06) * rotation.inv()).magnitude()
        assert turn.max() < ON_ORIENTATION
        assert_within_ranges_and_speeds(P.ROBOT, plan)
        assert plan.info["qp_failures"] == 0 and not plan.violations
        assert np.array_equal(plan.t, ref.t) and np.array_equal(plan.tool_ref, ref.tool_ref)  # the same reference


def test_on_random_spherical_arm_lines_the_baseline_keeps_the_tool_on_the_line_within_its_limits():
    """The arm is redundant for a tool point (4 joints, 3 coordinates): the baseline resolves that its own way
    (least joint motion, a weak pull to the start), which may take a joint to its range's end, where the arm
    loses a degree of freedom; there it may leave the line, and must say by how much."""
    on_line = 0
    for a, b, ref, plan in spherical_lines():
        assert_within_ranges_and_speeds(S.ROBOT, plan)
        deviation = segment_distance(S.fk(plan.q_ref), a, b)
        if deviation.max() < ON_LINE:
            assert np.linalg.norm(S.fk(plan.q_ref[-1])[0] - b) < ON_LINE
            on_line += 1
        else:  # only where a joint came to its range's end, and the plan says how far it left the line
            assert not inside_limits(S.ROBOT, plan.q_ref, np.array([0.0, 1e-3, 1e-2, 1e-3]))
            assert plan.info["plan_path_deviation_max"] == pytest.approx(deviation.max(), rel=0.05)
            assert any("leaves the followed path" in w for w in plan.warnings)
    assert on_line >= N_LINES - 2


def test_near_the_puma_wrist_singularity_the_baseline_keeps_the_speed_limits_and_leaves_the_path():
    doc = yaml.safe_load(WRIST.read_text())
    doc.pop("expect")
    scenario = parse_scenario(follow(doc), str(WRIST))
    plan = scenario.planner_def.plan(scenario, P.ROBOT, 1e-3)
    inner = mink_baseline.followed(scenario)
    paper = inner.planner_def.plan(inner, P.ROBOT, 1e-3)
    # paper 002's method stays on the line at the price of the wrist speeds (q4, q6 over 1.3 times their limit)
    assert (np.abs(paper.qd_ref[:, [3, 5]]) / P.QD_MAX[[3, 5]]).max() > 1.3
    assert_within_ranges_and_speeds(P.ROBOT, plan)
    assert np.isclose(np.abs(plan.qd_ref[:, [3, 5]]).max(axis=0), P.QD_MAX[[3, 5]]).all()  # held at the limit
    line = doc["task"]["path"][0]["line"]
    a, b = np.array(line["start"]) * 1e-3, np.array(line["end"]) * 1e-3
    deviation = segment_distance(P.fk(plan.q_ref), a, b)
    k = int(np.argmax(deviation))
    assert 1e-3 < deviation[k] < 0.02  # damped: it leaves the line by millimetres, not by the arm's size
    assert P.wrist_gap(paper.q_ref[k:k + 1])[0] < np.deg2rad(10)  # where the wrist is near its singularity
    assert deviation[-1] < 1e-4  # and comes back to the line's end
    assert any("speed limit" in w for w in plan.warnings)


def test_the_baseline_refuses_a_robot_without_forward_kinematics_or_a_closed_chain_when_validated():
    task = {"follow": "round_robin", "task": {}}
    for robot, why in (("rsmg", "forward kinematics"), ("agile_eye", "closed chain")):
        doc = {"robot": robot, "planner": "mink_baseline", "task": task, "timing": {"duration": 1.0}}
        with pytest.raises(ScenarioError) as err:
            parse_scenario(doc, "x.yaml")
        assert err.value.field == "planner" and why in err.value.message and "\n" not in str(err.value)


def test_the_followed_task_is_checked_by_the_followed_planner_and_named_inside_task_task():
    doc = follow(yaml.safe_load(WRIST.read_text()))
    doc["task"]["task"]["configuratoin"] = "auto"
    with pytest.raises(ScenarioError, match=r"task\.task\.configuratoin: unknown field .*did you mean 'configuration'"):
        parse_scenario(doc, "x.yaml")
    doc = follow(yaml.safe_load(WRIST.read_text()))
    doc["task"]["task"]["path"][0]["line"]["end"] = doc["task"]["task"]["path"][0]["line"]["start"]
    with pytest.raises(ScenarioError, match=r"task\.task\.path\[0\]\.line: a line needs two different points"):
        parse_scenario(doc, "x.yaml")
    doc = follow(yaml.safe_load(WRIST.read_text()))
    doc["task"]["follow"] = "safe_straight_path"
    with pytest.raises(ScenarioError, match=r"task\.follow: 'safe_straight_path' works with spherical_arm"):
        parse_scenario(doc, "x.yaml")


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    out = tmp_path_factory.mktemp("compare") / "wrist"
    return out, compare(WRIST, ["decoupled_path", "mink_baseline"], None, out)


def test_compare_writes_a_table_whose_rows_are_separate_evaluate_runs(compared, tmp_path):
    out, result = compared
    with open(out / "comparison.csv") as f:
        rows = {r["method"]: r for r in csv.DictReader(f)}
    assert list(rows) == ["decoupled_path", "mink_baseline"]
    # the same methods as scenario files of their own, each evaluated separately
    doc = yaml.safe_load(WRIST.read_text())
    doc.pop("expect")
    mink_file = tmp_path / "mink.yaml"
    mink_file.write_text(yaml.safe_dump(follow(doc)))
    for method, path in (("decoupled_path", WRIST), ("mink_baseline", mink_file)):
        ev = simbench.evaluate(path)
        r, tracking = rows[method], ev.analysis.tracking
        assert r["status"] == ev.verdict.status
        assert r["violations"].split() == sorted({v["kind"] for v in ev.verdict.violations})
        for column, value in (("tool_error_max_m", tracking["tool_error_max"]),
                              ("tool_error_rms_m", tracking["tool_error_rms"]),
                              ("path_deviation_max_m", tracking["tool_max"]),
                              ("path_deviation_rms_m", tracking["tool_rms"])):
            assert float(r[column]) == value
        peak = np.abs(ev.trajectory.qd_ref).max(axis=0)
        for j, joint in enumerate(P.JOINTS):
            assert float(r[f"qd_peak_{joint}"]) == peak[j]
            assert float(r[f"qd_share_{joint}"]) == pytest.approx(peak[j] / P.QD_MAX[j], rel=1e-12)
        near = simbench.load_scenario(path).analysis.near_angle
        assert float(r["singular_min_wrist"]) == pytest.approx(P.wrist_gap(ev.recording.q).min() / near, rel=1e-12)
        wrist_events = sum(e["kind"] == "wrist" for e in ev.analysis.singularity_events)
        assert int(r["singular_events_wrist"]) == wrist_events
        speed_events = sum(e["kind"] == "velocity_limit" for e in ev.analysis.limit_events)
        assert int(r["limit_events_velocity_limit"]) == speed_events
    # what the comparison shows: the paper's method asks over the wrist speed limit, the baseline leaves the path
    assert float(rows["decoupled_path"]["qd_share_max"]) > 1.3 > 1.0 >= float(rows["mink_baseline"]["qd_share_max"])
    assert float(rows["mink_baseline"]["plan_path_deviation_max_m"]) > 1e-3 > float(
        rows["decoupled_path"]["plan_path_deviation_max_m"])


def test_compare_writes_its_outputs_at_once_and_never_over_a_folder_it_did_not_write(compared, tmp_path):
    out, result = compared
    written = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file())
    assert written == sorted([".simbench", *result.files])
    assert {"comparison.csv", "comparison.md", "plots/tool_error.png", "plots/joint_speeds.png",
            "plots/singular_distance.png"} <= set(result.files)
    assert all((out / f).stat().st_size > 0 for f in result.files)
    assert "| status | limits | limits |" in (out / "comparison.md").read_text()
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("my notes")
    with pytest.raises(ScenarioError, match="did not write"):
        compare(WRIST, ["decoupled_path"], None, mine, force=True)
    assert (mine / "notes.txt").read_text() == "my notes" and len(list(mine.iterdir())) == 1


def test_compare_refuses_an_unknown_planner_in_one_line_before_anything_runs(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(ScenarioError) as err:
        compare(WRIST, ["decoupled_path", "mink_basline"], None, out)
    message = str(err.value)
    assert "\n" not in message and "unknown planner 'mink_basline'" in message and "'mink_baseline'" in message
    with pytest.raises(ScenarioError, match="safe_straight_path cannot run .*works with spherical_arm"):
        compare(WRIST, ["safe_straight_path"], None, out)
    with pytest.raises(ScenarioError, match="unknown controller 'servos'"):
        compare(WRIST, ["decoupled_path"], ["servos"], out)
    assert not out.exists()


def test_the_compare_command_prints_the_table_and_refuses_a_typo_in_one_line(tmp_path, capsys):
    from simbench.cli import main

    scenario = str(scenario_file("puma600", "wrist_singularity"))
    code = main(["compare", scenario, "--planners", "decoupled_path,mink_basline", "--out", str(tmp_path / "c")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "mink_basline" in err[0] and not (tmp_path / "c").exists()
    code = main(["compare", scenario, "--planners", "decoupled_path", "--controllers", "servo,computed_torque",
                 "--out", str(tmp_path / "c"), "--quiet"])
    printed = capsys.readouterr().out
    assert code == 0 and printed == (tmp_path / "c" / "comparison.md").read_text() + "\n" + \
        f"table, plots and index.html in {tmp_path / 'c'}\n"
    assert (tmp_path / "c" / "index.html").is_file()


def test_the_compare_command_writes_by_default_under_the_scenarios_name(tmp_path, monkeypatch, capsys):
    """As `run` does, compare names its default folder after the scenario's `name:`, which stands in for a file
    name that could not name a folder (renders/compare/<name>/)."""
    from simbench.cli import main

    monkeypatch.chdir(tmp_path)
    path = tmp_path / "case 1 (copy).yaml"
    path.write_text(yaml.safe_dump({**yaml.safe_load(scenario_file("spherical_arm", "case1").read_text()),
                                    "name": "case1_copy"}))
    assert main(["compare", str(path), "--planners", "safe_straight_path", "--quiet"]) == 0, capsys.readouterr().err
    assert (tmp_path / "renders" / "compare" / "case1_copy" / "comparison.csv").is_file()


def test_compare_of_a_strided_scenario_reads_the_speed_share_of_every_state(tmp_path):
    """With sim.record_every, a recording keeps qd at every k-th state only: the comparison still draws its speed
    plot, and its simulated speed share is the largest over every state of the run recorded whole
    (Recording.qd_peak), not over the kept ones, whose largest is lower here; a run's qd_peak is its states'
    largest |qd|, recorded whole or at a stride, open-loop or closed."""
    doc = yaml.safe_load(WRIST.read_text())
    doc["sim"] = {**doc.get("sim", {}), "record_every": 101}
    strided = tmp_path / "strided.yaml"
    strided.write_text(yaml.safe_dump(doc))
    result = compare(strided, ["decoupled_path"], None, tmp_path / "out")
    with open(tmp_path / "out" / "comparison.csv") as f:
        share = float(next(csv.DictReader(f))["qd_share_max_simulated"])
    assert "plots/joint_speeds.png" in result.files
    whole = simbench.evaluate(WRIST).recording
    speeds = np.abs(whole.qd) / P.ROBOT.qd_max
    kept = np.union1d(np.arange(0, len(whole.t), 101), [len(whole.t) - 1])
    assert share == pytest.approx(float(speeds.max()), rel=1e-12) and speeds[kept].max() < 0.99 * share
    np.testing.assert_array_equal(whole.qd_peak, np.abs(whole.qd).max(axis=0))
    closed = {**yaml.safe_load(WRIST.read_text()), "control": {"controller": "computed_torque"}}
    every = simbench.evaluate(parse_scenario(closed, "closed")).recording
    closed["sim"] = {**closed.get("sim", {}), "record_every": 13}
    thin = simbench.evaluate(parse_scenario(closed, "closed, strided")).recording
    assert len(thin.t) < len(every.t) / 10  # the kept rows only
    np.testing.assert_array_equal(thin.qd_peak, np.abs(every.qd).max(axis=0))


def test_compare_of_a_strided_scenario_takes_peaks_and_singular_minima_from_every_sample(tmp_path):
    """With sim.record_every the outputs keep every k-th row, but the table's planned speed peaks and least
    distances to each singular set are of every sample: those of the run recorded whole, its plan's |qd_ref| and
    its recording's singular sets (robot.singular_sets at every state), not of the kept rows (where the wrist's
    least distance is larger)."""
    doc = yaml.safe_load(WRIST.read_text())
    doc["sim"] = {**doc.get("sim", {}), "record_every": 101}
    strided = tmp_path / "strided.yaml"
    strided.write_text(yaml.safe_dump(doc))
    compare(strided, ["decoupled_path"], None, tmp_path / "out")
    with open(tmp_path / "out" / "comparison.csv") as f:
        row = next(csv.DictReader(f))
    whole = simbench.evaluate(WRIST)
    scenario = simbench.load_scenario(WRIST)
    a = scenario.analysis
    sets = P.ROBOT.singular_sets(whole.recording, simbench.api.Tolerance(a.near_angle, a.near_length))
    kept = np.union1d(np.arange(0, len(whole.recording.t), 101), [len(whole.recording.t) - 1])
    for sset in sets:
        assert float(row[f"singular_min_{sset.name}"]) == pytest.approx(float(sset.distance.min()), rel=1e-12)
    assert any(sset.distance[kept].min() > 1.01 * sset.distance.min() for sset in sets)  # the kept rows miss it
    peak = np.abs(whole.trajectory.qd_ref).max(axis=0)
    for j, name in enumerate(P.ROBOT.joints):
        assert float(row[f"qd_peak_{name}"]) == pytest.approx(float(peak[j]), rel=1e-12)
    assert (np.abs(whole.trajectory.qd_ref[kept]).max(axis=0) < 0.99 * peak).any()  # and the peaks


def test_compare_exits_0_once_written_even_where_every_method_ends_limits(tmp_path):
    """A method that ends `limits` is the comparison's finding, in its row, not a failure of the command (the
    outputs page's exit codes)."""
    from simbench.cli import main

    out = tmp_path / "cmp"
    assert main(["compare", str(WRIST), "--planners", "decoupled_path", "--quiet", "--out", str(out)]) == 0
    with open(out / "comparison.csv") as f:
        assert [r["status"] for r in csv.DictReader(f)] == ["limits"]


def test_the_baseline_following_a_retimed_plan_has_its_slowdown(tmp_path):
    """mink_baseline following cartesian_path's time_scaling along the PUMA's wrist line (its MJCF, its drives'
    60 deg/s arm and 300 deg/s wrist) runs on the retimed plan's grid, so its slowdown, the metric compare's table
    and a bench row read, is its own motion's duration over the asked one: when its reference reaches the line's
    end (not 1: the baseline stated none)."""
    doc = {"robot": {"model": str(models_dir() / "puma600" / "puma600.xml"), "tool": {"site": "tool"},
                     "speed_limits": [60, 60, 60, 300, 300, 300]},
           "planner": "cartesian_path", "units": {"angle": "deg", "length": "mm"},
           "task": {"start": [181.8737, -117.777, -222.6356, 15.0872, 15.8376, -13.0006],
                    "path": [{"line": {"end": [780.0, -149.0, -200.0]}}], "method": "time_scaling"},
           "timing": {"law": "quintic", "duration": 2.0, "hold": 0.3}}
    scenario = parse_scenario(follow(doc), "retimed")
    robot = scenario.robot_def
    plan = scenario.planner_def.plan(scenario, robot, 0.002)
    end = np.array([0.780, -0.149, -0.200])
    arrived = plan.t[np.argmax(np.linalg.norm(plan.tool_ref - end, axis=1) < 1e-12)]
    assert arrived / 2.0 > 1.01  # the wrist's limits stretch the line
    figures = SingularityHandling.for_run(robot, plan, scenario).finish()
    assert figures["slowdown"] == pytest.approx(arrived / 2.0, abs=0.002 / 2.0)


def test_compare_methods_runs_each_of_cartesian_paths_methods_as_its_own_scenario_would(tmp_path):
    """`--methods pinv,dls_adaptive` on a UR5 line (its URDF untouched) whose file asks dls with its damping: one row
    a method, each the run of the same file with its task.method written in (dls's damping, which no other method
    reads, left out), evaluated separately."""
    from simbench.cli import main
    from tests.outputs.test_export import ur5_line

    path, out = ur5_line(tmp_path, task="method: dls\ndamping: 0.2"), tmp_path / "cmp"
    assert main(["compare", str(path), "--methods", "pinv,dls_adaptive", "--out", str(out), "--quiet"]) == 0
    with open(out / "comparison.csv") as f:
        rows = {r["method"]: r for r in csv.DictReader(f)}
    assert list(rows) == ["pinv", "dls_adaptive"] and {r["planner"] for r in rows.values()} == {"cartesian_path"}
    assert "| | `pinv` | `dls_adaptive` |" in (out / "comparison.md").read_text()
    for method, row in rows.items():
        ev = simbench.evaluate(ur5_line(tmp_path, method, task=f"method: {method}"))
        assert row["status"] == ev.verdict.status == "ok"
        assert float(row["tool_error_max_m"]) == ev.analysis.tracking["tool_error_max"]
        assert float(row["path_deviation_rms_m"]) == ev.analysis.tracking["tool_rms"]
        peak = np.abs(ev.trajectory.qd_ref).max(axis=0)
        assert [float(v) for k, v in row.items() if k.startswith("qd_peak_")] == peak.tolist()


def test_compare_methods_refuses_an_unknown_method_or_a_scenario_not_cartesian_paths_in_one_line(tmp_path, capsys):
    from simbench.cli import main

    out = tmp_path / "c"
    for scenario, methods, words in ((WRIST, "pinv", "plans with decoupled_path: compare planners with --planners"),
                                     (WRIST, "pinv,dls_adaptiv", "unknown method 'dls_adaptiv'")):
        assert main(["compare", str(scenario), "--methods", methods, "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], err
    with pytest.raises(ScenarioError, match="planners or methods"):
        compare(WRIST, ["decoupled_path"], None, out, methods=["pinv"])
    for both_or_neither in (["--planners", "decoupled_path", "--methods", "pinv"], []):
        with pytest.raises(SystemExit) as exited:
            main(["compare", str(WRIST), *both_or_neither, "--out", str(out)])
        assert exited.value.code == 2
    assert not out.exists()
