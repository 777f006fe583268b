"""`simbench bench` (issue 36): suites of random tasks through, near and far from a robot's singular set, run by
several methods into runs.csv and leaderboard.csv. Truths: the robots' analytic kinematics (a `through` task's
path meets the set the analytic measure defines), the leaderboard recomputed from runs.csv with the standard
library, a bootstrap interval against the normal approximation of a share's, and the same bytes from the same
seed serially, in parallel and after a killed run resumed."""

import csv
import json
import math
import os
import re
import shutil
import signal
import statistics
import sys

import numpy as np
import pytest

from simbench.cli import main
from simbench.commands.bench import board, kept_tasks, load_suite, run_bench
from simbench.commands.bench import tasks as bench_tasks
from simbench.commands.bench.methods import METHODS
from simbench.commands.bench.robots import SHIPPED
from simbench.commands.bench.runner import bench_spec
from simbench.commands.bench.tasks import bands, draw, draw_all
from simbench.commands.sweep import table
from simbench.core.errors import RunError, ScenarioError
from simbench.robots import puma600 as P
from simbench.robots import spherical_arm as S
from simbench.scenario import parse_scenario
from tests.conftest import interrupt

METHODS_2 = ["dls_adaptive", "mink"]


def _suite(tasks=2, seed=0):
    return load_suite("planar3r").with_options(tasks=tasks, seed=seed, methods=METHODS_2)


@pytest.fixture(scope="module")
def planar(tmp_path_factory):
    """A planar 3R bench of 2 tasks by 2 methods, run here one after another."""
    return run_bench(_suite(), tmp_path_factory.mktemp("bench") / "planar", workers=1)


def _read(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


# --- suite files -----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("text, field", [
    ("robots: [planar3r]\ntaks: 3\n", "taks"),
    ("robots: [planar3r]\ntasks: 0\n", "tasks"),
    ("robots: [nobody]\n", "robots[0]"),
    ("robots: [planar3r]\nmethods: [dls_adaptive, magic]\n", "methods[1]"),
    ("robots: [planar3r]\nmethods: [nonesuch]\n", "methods[0]"),
    ("robots: [planar3r, planar3r]\n", "robots[1]"),
    ("robots:\n  - {model: arm.xml}\n", "robots[0].name"),
    ("robots:\n  - {name: mine, model: nowhere.xml, tool: {site: tool}}\n", "robots[0].model"),
    ("robots:\n  - {name: mine, model: nowhere.xml, speed: -1}\n", "robots[0].speed"),
])
def test_suite_file_errors_name_the_file_and_field(tmp_path, capsys, text, field):
    path = tmp_path / "suite.yaml"
    path.write_text(text)
    with pytest.raises(ScenarioError) as err:
        load_suite(path)
    assert err.value.source == str(path) and err.value.field == field
    assert main(["bench", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {path}: {field}: ")


def test_an_empty_suite_file_and_a_bench_of_no_run_are_one_line(tmp_path, capsys):
    """An empty suite file asks for suite fields; methods that apply to none of the robots (the papers' planner on
    the planar 3R) make no run: one line naming them, exit 2, and no folder written."""
    empty = tmp_path / "empty.yaml"
    empty.write_text("# nothing yet\n")
    out = tmp_path / "out"
    assert main(["bench", str(empty), "--out", str(out), "--quiet"]) == 2
    assert capsys.readouterr().err.strip() == f"error: {empty}: empty file: expected a mapping of suite fields"
    assert main(["bench", "planar3r", "--methods", "paper", "--tasks", "1", "--out", str(out), "--quiet"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.endswith("methods: no run: no robot of the suite (planar3r) takes one of its methods (paper)")
    assert not out.exists()


def test_a_suite_file_runs_an_arm_of_its_own(tmp_path):
    """A robot mapping in a suite file, its model relative to the file: the planar 3R's own MJCF."""
    model = os.path.relpath(SHIPPED["planar3r"]().mapping["model"], tmp_path)
    path = tmp_path / "suite.yaml"
    path.write_text(f"name: mine\ntasks: 1\nmethods: [dls_adaptive]\nrobots:\n"
                    f"  - {{name: flat, model: {model}, tool: {{site: tool}}, speed_limits: [3, 6, 6], speed: 0.2}}\n")
    suite = load_suite(path)
    assert [r.name for r in suite.robots] == ["flat"] and suite.tasks == 1
    assert suite.robots[0].speed == 0.2 and suite.robots[0].model_arm().dof == 3


def test_every_methods_document_is_a_valid_scenario():
    """Each method's scenario for a task of each robot it applies to passes the scenario schema and the planner's
    own check."""
    for name in ("puma600", "spherical_arm", "planar3r"):
        robot = SHIPPED[name]()
        task = draw(robot, 1, 0)[0]
        for method in METHODS:
            doc = METHODS[method].document(task, robot)
            if doc is not None:
                parse_scenario(doc, f"{name} {method}")
    assert set(METHODS) == {"dls_adaptive", "pinv", "dls", "time_scaling", "mink", "paper", "sns", "gradient",
                            "priority", "ruckig"}


# --- tasks: through, near, far ------------------------------------------------------------------------------------

def _point_line_distance(p, a, b):
    d = (b - a) / np.linalg.norm(b - a)
    return np.linalg.norm((p - a) - np.dot(p - a, d) * d)


def test_a_puma_through_line_meets_the_wrist_singularity_by_the_analytic_kinematics():
    """On the PUMA's `through` line the tool's pose at the anchor (a point of the line, the orientation held) is
    one whose analytic inverse kinematics (puma600.ik, paper 002) puts q5 at 0; `near` ones keep q5 off 0 within
    the near band, `far` ones beyond the far threshold; the start joints are on the line's start by the analytic
    forward kinematics."""
    robot = SHIPPED["puma600"]()
    (near_lo, near_hi), far = bands(robot)
    for task in draw(robot, 6, 3):
        if task.shape != "line":
            continue
        a, b = (np.array(task.segment["line"][k]) for k in ("start", "end"))
        anchor = np.array(task.anchor)
        point, rotation = P.tool_pose(anchor[None])
        assert _point_line_distance(point[0], a, b) < 1e-9
        q = P.ik(point, rotation, P.configuration(anchor[None]))[0]
        np.testing.assert_allclose(P.fk(q[None])[0], point[0], atol=1e-9)
        gap = P.wrist_gap(q[None])[0]
        if task.kind == "through":
            assert gap < 1e-9
        elif task.kind == "near":
            assert near_lo - 1e-6 <= gap <= near_hi + 1e-6
        else:
            assert gap >= far - 1e-9
        np.testing.assert_allclose(P.fk(np.array([task.start]))[0], a, atol=1e-6)


def test_a_spherical_arm_through_line_crosses_the_lift_axis():
    """The spherical arm's singular set is its lift axis (x = y = 0, paper 000): a `through` line crosses it, a
    `far` one passes it at a distance; the start and goal joints are on the line's ends (analytic fk, eq. 19)."""
    robot = SHIPPED["spherical_arm"]()
    for task in draw(robot, 3, 1):
        a, b = (np.array(task.segment["line"][k]) for k in ("start", "end"))
        s = np.linspace(0, 1, 20001)[:, None]
        axis_distance = np.hypot(*(a + s * (b - a))[:, :2].T).min()
        if task.kind == "through":
            assert axis_distance < 1e-4  # the grid's step along a line of at most 0.26 m
        elif task.kind == "far":
            assert axis_distance > 1e-3
        np.testing.assert_allclose(S.fk(np.array([task.start]))[0], a, atol=1e-6)
        np.testing.assert_allclose(S.fk(np.array([task.goal]))[0], b, atol=1e-6)


def test_more_tasks_keep_the_first_ones_and_another_seed_changes_them():
    robot = SHIPPED["planar3r"]()
    two, three = draw(robot, 2, 5), draw(robot, 3, 5)
    assert two == three[:2]
    assert draw(robot, 2, 6)[0].start != two[0].start


def test_tasks_drawn_by_forked_processes_are_the_tasks_drawn_here_in_turn():
    """draw_all by 2 and 3 processes (a robot whose set is found by minimising its gap among them) gives each
    robot's tasks as draw gives them here, in order, equal to the last bit."""
    robots = [SHIPPED[name]() for name in ("planar3r", "so100", "spherical_arm")]
    here = [draw(robot, 4, 2) for robot in robots]
    for workers in (2, 3):
        assert draw_all(robots, 4, 2, workers=workers) == here, workers


def test_a_task_none_of_whose_draws_found_one_raises_the_first_in_order(monkeypatch):
    """Tasks 1 and 2 of 4 find none: drawn by 2 processes (task 1 the child's first), task 1's error is the one
    raised, as drawn in turn."""
    def generator(robot, index, seed):
        if index in (1, 2):
            raise RunError(f"none for task {index} in process {os.getpid()}")
        return index

    monkeypatch.setitem(bench_tasks.VERSIONS, "sb-test", generator)
    robot = SHIPPED["planar3r"]()
    with pytest.raises(RunError, match="none for task 1 in process") as raised:
        draw_all([robot], 4, 0, "sb-test", workers=2)
    assert str(os.getpid()) not in str(raised.value)  # drawn by the child
    with pytest.raises(RunError, match="none for task 1 in process"):
        draw_all([robot], 4, 0, "sb-test", workers=1)


# --- runs and leaderboard -----------------------------------------------------------------------------------------

def test_runs_csv_has_a_row_per_task_and_method(planar):
    rows = _read(planar.out / "runs.csv")
    assert sorted((r["task"], r["method"]) for r in rows) == sorted(
        (f"planar3r-t{i:04d}", m) for i in range(2) for m in METHODS_2)
    assert {r["kind"] for r in rows} == {"through", "near"}
    for r in rows:
        assert r["status"] in table.STATUSES
        if r["status"] in ("ok", "limits"):
            assert float(r["deviation_max_mm"]) >= 0 and float(r["speed_share_max"]) > 0
            assert float(r["slowdown"]) == 1.0 and float(r["closest_approach"]) >= 0


def test_the_leaderboard_is_runs_csv_summarised(planar):
    """ok_share, the 95th percentile of the deviation (linear interpolation between order statistics, written out
    here), the largest speed share and the median slowdown, from runs.csv with the standard library."""
    runs, board_rows = _read(planar.out / "runs.csv"), _read(planar.out / "leaderboard.csv")
    assert [(r["robot"], r["method"]) for r in board_rows] == [("planar3r", m) for m in METHODS_2]
    for row in board_rows:
        mine = [r for r in runs if r["method"] == row["method"]]
        assert int(row["tasks"]) == len(mine)
        assert float(row["ok_share"]) == pytest.approx(sum(r["status"] == "ok" for r in mine) / len(mine), rel=1e-6)
        dev = sorted(float(r["deviation_max_mm"]) for r in mine if r["deviation_max_mm"])
        h = 0.95 * (len(dev) - 1)
        p95 = dev[math.floor(h)] + (h - math.floor(h)) * (dev[math.ceil(h)] - dev[math.floor(h)])
        assert float(row["deviation_p95_mm"]) == pytest.approx(p95, rel=1e-5)
        assert float(row["speed_share_max"]) == pytest.approx(max(float(r["speed_share_max"]) for r in mine),
                                                              rel=1e-5)
        assert float(row["slowdown_median"]) == pytest.approx(statistics.median(float(r["slowdown"])
                                                                                 for r in mine), rel=1e-6)
        for name in ("ok_share", "deviation_p95_mm", "slowdown_median"):
            assert float(row[f"{name}_lo"]) <= float(row[name]) <= float(row[f"{name}_hi"])
    by_kind = _read(planar.out / "leaderboard_by_kind.csv")
    for row in by_kind:
        mine = [r for r in runs if (r["method"], r["kind"]) == (row["method"], row["kind"])]
        assert int(row["tasks"]) == len(mine) and int(row["ok"]) == sum(r["status"] == "ok" for r in mine)
    assert sum(int(r["tasks"]) for r in by_kind) == len(runs)


def test_a_bootstrap_interval_of_a_share_is_the_normal_approximations():
    """400 draws of a share of 0.3: the percentile interval is 0.3 +- 1.96 sqrt(0.3 0.7 / 400) within a tenth."""
    values = (np.arange(400) < 120).astype(float)
    lo, hi = board.bootstrap(values, np.mean, np.random.default_rng(0))
    half = 1.96 * math.sqrt(0.3 * 0.7 / 400)
    assert lo == pytest.approx(0.3 - half, abs=0.1 * half) and hi == pytest.approx(0.3 + half, abs=0.1 * half)
    assert lo <= 0.3 <= hi


def test_the_same_seed_gives_the_same_leaderboard_bytes_on_two_workers(planar, tmp_path):
    again = run_bench(_suite(), tmp_path / "again", workers=2)
    assert (again.out / "leaderboard.csv").read_bytes() == (planar.out / "leaderboard.csv").read_bytes()
    assert again.summary["backend"] == "2 processes"


def test_a_killed_bench_resumes_to_the_same_leaderboard(planar, tmp_path):
    """SIGKILL once a row is on disk: the same command runs only the runs without a row, and writes the leaderboard
    an uninterrupted bench writes."""
    out = tmp_path / "killed"
    command = [sys.executable, "-m", "simbench", "bench", "planar3r", "--tasks", "2", "--methods", ",".join(METHODS_2),
               "--workers", "1", "--out", str(out), "--quiet"]
    done = interrupt(command, lambda: len(list((out / "rows").glob("*.json"))) >= 1 if (out / "rows").is_dir()
                     else False, tmp_path, signum=signal.SIGKILL)
    assert done.returncode == -signal.SIGKILL
    finished = len(list((out / "rows").glob("*.json")))
    assert 1 <= finished < 4 and not (out / "leaderboard.csv").exists()
    assert main(command[3:]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["resumed"] == finished and summary["runs"] == 4
    assert (out / "leaderboard.csv").read_bytes() == (planar.out / "leaderboard.csv").read_bytes()


def _no_draw(*args, **kwargs):
    raise AssertionError("the bench drew its tasks again")


def test_a_resumed_bench_takes_the_tasks_its_folder_keeps(planar, tmp_path, monkeypatch):
    """The folder keeps the drawn tasks (tasks.json: the planar 3R's first two at seed 0, as draw draws them anew);
    the same bench resumed there takes them, draws nothing and writes the same leaderboard; --force draws anew."""
    out = tmp_path / "resumed"
    shutil.copytree(planar.out, out)
    models = bench_spec(_suite()).models
    assert kept_tasks._taken(out / kept_tasks.KEPT, _suite(), models) == [draw(SHIPPED["planar3r"](), 2, 0)]
    monkeypatch.setattr(kept_tasks, "draw_all", _no_draw)
    again = run_bench(_suite(), out, workers=1)
    assert again.summary["resumed"] == 4
    assert (out / "leaderboard.csv").read_bytes() == (planar.out / "leaderboard.csv").read_bytes()
    with pytest.raises(AssertionError, match="drew its tasks again"):
        run_bench(_suite(), out, workers=1, force=True)


def test_a_destination_it_cannot_use_is_refused_before_the_tasks_are_drawn(planar, tmp_path, monkeypatch):
    """--out a file, another bench's folder, or a folder with a file of the user's (without and with --force): one
    line, before any task is drawn (a draw takes minutes on a big suite); the user's file is left as it was."""
    monkeypatch.setattr(kept_tasks, "draw_all", _no_draw)
    afile, strange = tmp_path / "afile", tmp_path / "strange"
    afile.write_text("mine")
    strange.mkdir()
    (strange / "notes.txt").write_text("mine")
    for out, force, words in ((afile, False, "is a file, not a folder"), (planar.out, False, "other results"),
                              (strange, False, "simbench did not write (such as notes.txt)"),
                              (strange, True, "simbench did not write (such as notes.txt)")):
        with pytest.raises(ScenarioError, match=re.escape(words)):
            run_bench(_suite(tasks=3), out, workers=1, force=force)
    assert afile.read_text() == (strange / "notes.txt").read_text() == "mine"


@pytest.mark.parametrize("change", ["numpy", "seed", "task", "garbled"])
def test_kept_tasks_are_taken_only_where_the_draw_would_give_them(planar, tmp_path, monkeypatch, change):
    """Another NumPy (whose floating point the draw's searches follow), another seed, a task edited in the file
    (its digest then differs) or a file that is no record: the tasks are drawn again, not taken."""
    out = tmp_path / "kept"
    shutil.copytree(planar.out, out)
    path, suite = out / kept_tasks.KEPT, _suite()
    if change == "numpy":
        monkeypatch.setattr(kept_tasks.np, "__version__", "0.0.1")
    elif change == "seed":
        suite = _suite(seed=1)
    elif change == "task":
        record = json.loads(path.read_text())
        record["tasks"][0][1]["duration"] *= 2
        path.write_text(json.dumps(record))
    else:
        path.write_text(path.read_text()[:-40])
    models = bench_spec(suite).models
    assert kept_tasks._taken(path, suite, models) is None
    drawn = []
    monkeypatch.setattr(kept_tasks, "draw_all", lambda *args: drawn.append(args) or [[]])
    assert kept_tasks.tasks_for(out, suite, models, 1, False) == [[]] and len(drawn) == 1


def test_a_bench_folder_is_not_replaced_without_force(planar, tmp_path, capsys):
    """Another suite into the folder is refused (exit 2); --force replaces it; a stranger's file in it stops that."""
    out = planar.out
    args = ["bench", "planar3r", "--tasks", "1", "--methods", "dls_adaptive", "--workers", "1", "--quiet"]
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    assert main(args + ["--out", str(foreign), "--force"]) == 2
    assert (foreign / "notes.txt").read_text() == "mine"
    assert main(args + ["--out", str(out)]) == 2
    assert "other results" in capsys.readouterr().err


def _bench_document(method, task=0):
    """The scenario document the planar 3R bench runs for its task `task` by `method` (the `planar` fixture's)."""
    robot = SHIPPED["planar3r"]()
    return METHODS[method].document(draw(robot, 2, 0)[task], robot)


def test_a_fresh_process_run_reports_the_shipped_metric_by_mujocos_jacobian(tmp_path):
    """`simbench run` in a fresh process (no bench, no Ray) of a bench scenario (planar 3R, pinv): report.json's
    metrics.singularity_handling has speed_share_max = max |qd_ref| / the mapping's speed_limits over
    timeseries.npz's plan, closest_approach = the least singular value of [Jp / L; Jr] by MuJoCo's own mj_jacSite
    at the recorded joints (L the derived reach), and slowdown 1 (pinv keeps the timing)."""
    import subprocess

    import mujoco
    import yaml

    document = _bench_document("pinv")
    (tmp_path / "run.yaml").write_text(yaml.safe_dump(document))
    out = tmp_path / "out"
    subprocess.run([sys.executable, "-m", "simbench", "run", str(tmp_path / "run.yaml"), "--out", str(out),
                    "--no-video", "--quiet"], check=True, timeout=300)
    report = json.loads((out / "report.json").read_text())
    figures = report["metrics"]["singularity_handling"]
    with np.load(out / "timeseries.npz") as series:
        qd_ref, q = series["qd_ref"], series["q"]
    share = np.max(np.abs(qd_ref) / np.array(document["robot"]["speed_limits"]))
    assert figures["speed_share_max"] == pytest.approx(share, rel=1e-12)
    model = mujoco.MjModel.from_xml_path(document["robot"]["model"])
    data = mujoco.MjData(model)
    site, reach = model.site(document["robot"]["tool"]["site"]).id, report["derived_arm"]["reach"]
    jp, jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    least = np.inf
    for row in q:
        data.qpos[:] = row
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_jacSite(model, data, jp, jr, site)
        least = min(least, np.linalg.svd(np.vstack([jp / reach, jr]), compute_uv=False)[-1])
    assert figures["closest_approach"] == pytest.approx(least, rel=1e-6, abs=1e-9)
    assert figures["slowdown"] == 1.0


def test_compare_and_bench_agree_on_the_shared_figures(planar, tmp_path):
    """comparison.csv's row of a bench scenario's own method (planar 3R, task 0, dls_adaptive) and runs.csv's row
    of that task and method give the same status, deviation (m against mm), speed share, slowdown and closest
    approach: two separate runs of the same document, scored by simbench.analysis.scoring."""
    import yaml

    (tmp_path / "task.yaml").write_text(yaml.safe_dump(_bench_document("dls_adaptive")))
    assert main(["compare", str(tmp_path / "task.yaml"), "--planners", "cartesian_path", "--out",
                 str(tmp_path / "cmp"), "--quiet"]) in (0, 1)
    ours = _read(tmp_path / "cmp" / "comparison.csv")[0]
    theirs = next(r for r in _read(planar.out / "runs.csv")
                  if (r["task"], r["method"]) == ("planar3r-t0000", "dls_adaptive"))
    assert ours["status"] == theirs["status"]
    assert float(ours["path_deviation_max_m"]) * 1e3 == pytest.approx(float(theirs["deviation_max_mm"]), rel=1e-12)
    assert float(ours["qd_share_max"]) == pytest.approx(float(theirs["speed_share_max"]), rel=1e-12)
    for name in ("slowdown", "closest_approach"):
        assert float(ours[name]) == pytest.approx(float(theirs[name]), rel=1e-12)


def test_the_shipped_metric_never_fails_a_run_of_a_robot_without_speed_limits():
    """A robot with no qd_max and a plan with no rates: the figures are None or 1, not an exception."""
    from types import SimpleNamespace

    from simbench.analysis.singularity_handling import SingularityHandling

    robot = SimpleNamespace(dof=2)
    traj = SimpleNamespace(info=None, qd_ref=None)
    metric = SingularityHandling.for_run(robot, traj, None)
    metric.add(traj, None, {})
    assert metric.finish() == {"speed_share_max": None, "closest_approach": None, "slowdown": 1.0}
    robot = SimpleNamespace(dof=2, qd_max=[1.0, 0.0])  # a limit that is no limit
    assert SingularityHandling.for_run(robot, SimpleNamespace(info={"slowdown": "x"}), None).finish() == {
        "speed_share_max": None, "closest_approach": None, "slowdown": None}


def test_a_jaco_through_task_passes_a_rank_loss_by_mujocos_own_jacobian():
    """The Jaco's `through` anchor, found by minimising rank_loss, is singular by MuJoCo's own mj_jacSite on the
    untouched model ([Jp / L; Jr] of least singular value under 1e-4, L the derived reach), and its tool point lies
    on the task's line at the orientation held there."""
    import mujoco

    robot = SHIPPED["jaco"]()
    task = draw(robot, 1, 0)[0]
    model = mujoco.MjModel.from_xml_path(robot.mapping["model"])
    data = mujoco.MjData(model)
    data.qpos[:6] = task.anchor
    mujoco.mj_forward(model, data)
    site = model.site("wristsite").id
    jp, jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    mujoco.mj_jacSite(model, data, jp, jr, site)
    ju = np.vstack([jp[:, :6] / robot.model_arm().reach, jr[:, :6]])
    assert np.linalg.svd(ju, compute_uv=False)[-1] < 1e-4
    a, b = (np.array(task.segment["line"][k]) for k in ("start", "end"))
    assert _point_line_distance(data.site_xpos[site], a, b) < 1e-9
