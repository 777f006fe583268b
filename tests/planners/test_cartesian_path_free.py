"""cartesian_path's `orientation: free` (the tool's point alone follows the path) on two arms of fewer than six
joints, example-robot-data's SO-100 (5 joints, its URDF) and the shipped spherical arm (4, its MJCF), each judged by
MuJoCo's own kinematics of the untouched file (test_derived_plant's raw_model and tool_pose: a plain compile,
mj_kinematics on a fresh MjData), never simbench's:

  - LINES random lines per arm (start uniform within the ranges, 10 % of each width clear; the end the tool's point
    at a second configuration near the start, 50-150 mm away), planned at a path tolerance of KEPT: wherever the
    plan of dls_adaptive, pinv or time_scaling reports no `off_path`, its q_ref keeps the tool within KEPT of the
    line, and wherever it reports one, not; it keeps the line on most (measured, of 24: 22, 22 and 22 on the
    SO-100, worst 0.0004, 0.0004 and 4e-10 mm; 22, 24 and 24 on the spherical arm, worst 0.0011, 0.0037 and 0.0014
    mm; the lines it leaves, near a rank loss or a joint's limit, by 0.5-13 mm);
  - runs of three of them per arm whose tool turns by more than 10 deg end `ok`, the tool within the path tolerance
    at the recorded joints, the orientation unjudged: no `tool_orientation_ref`, no `orientation_error`, the report's
    orientation figures the recorded tool's from the planned tool's (measured: turning 35, 29 and 21 deg on the
    SO-100, 48, 11 and 33 deg on the spherical arm; the tool within 0.09 and 0.43 mm of the line);
  - `orientation: hold` on the SO-100 is still accepted, its plan reporting its own `orientation_error` as far as
    the tool turns from the start's orientation;
  - a bench suite file with the SO-100 as an arm of its own: its tasks by the cartesian_path methods with
    `orientation: free`, and by mink on the same path with the orientation's cost 0.
"""

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml

import simbench
from simbench.commands.bench import load_suite
from simbench.commands.bench.runner import plan_bench
from simbench.core.resources import models_dir
from simbench.robots.spherical_arm import QD_MAX
from simbench.scenario import load_scenario, parse_scenario
from tests.robots.test_derived_plant import SO100, SO100_JOINTS, raw_model, tool_pose

ARMS = {  # name: the robot mapping as a user writes it
    "so100": {"model": str(SO100), "tool": {"body": "gripper"}, "joints": SO100_JOINTS},
    "spherical_arm": {"model": str(models_dir() / "spherical_arm" / "spherical_arm.xml"), "tool": {"site": "tool"},
                      "speed_limits": QD_MAX.tolist()},
}
LINES, SEED = 24, 5
KEPT = 1e-4  # m: the path kept, the plans' path tolerance
SPEED, FLOOR, DT = 0.05, 0.03, 0.002  # m/s along a line (at least 1 s); m: both ends this high; s
METHODS = ("dls_adaptive", "pinv", "time_scaling")


class Arm:
    """MuJoCo's own compile of an arm's file: its chain's joints' ranges (a continuous joint's a turn) and the tool's
    point and rotation at joint values."""

    def __init__(self, name: str):
        self.mapping = ARMS[name]
        self.joints = self.mapping.get("joints") or ["q1", "q2", "q3", "q4"]  # the spherical arm's chain
        self.model = raw_model(Path(self.mapping["model"]))
        ids = [self.model.joint(j).id for j in self.joints]
        limited = self.model.jnt_limited[ids].astype(bool)
        self.lower = np.where(limited, self.model.jnt_range[ids, 0], -np.pi)
        self.upper = np.where(limited, self.model.jnt_range[ids, 1], np.pi)

    def pose(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return tool_pose(self.model, self.mapping["tool"], self.joints, q)


def _lines(arm: Arm, n: int, seed: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """n random lines: start joints, the tool's point there, the end (the tool's point at joints near the start)."""
    rng = np.random.default_rng(seed)
    width = arm.upper - arm.lower
    lines = []
    while len(lines) < n:
        q = rng.uniform(arm.lower + 0.1 * width, arm.upper - 0.1 * width)
        near = q + rng.uniform(-0.15, 0.15, len(q)) * width
        if np.any((near < arm.lower) | (near > arm.upper)):
            continue
        (a, b), _ = arm.pose(np.array([q, near]))
        if 0.05 <= np.linalg.norm(b - a) <= 0.15 and min(a[2], b[2]) >= FLOOR:
            lines.append((q, a, b))
    return lines


def _scenario(folder, arm: Arm, q, end, method: str, orientation: str = "free", analysis: str = ""):
    """A cartesian_path scenario (SI) of the line from the tool at q to `end`, quintic at about SPEED."""
    duration = max(1.0, float(np.linalg.norm(end - arm.pose(q)[0][0])) / SPEED)
    path = folder / f"line-{method}.yaml"
    path.write_text(f"robot: {json.dumps(arm.mapping)}\nplanner: cartesian_path\ntask:\n"
                    f"  start: {[float(v) for v in q]}\n  path: [{{line: {{end: {[float(v) for v in end]}}}}}]\n"
                    f"  orientation: {orientation}\n  method: {method}\n{analysis}"
                    f"timing: {{law: quintic, duration: {duration:.3f}, hold: 0.2}}\n")
    return load_scenario(str(path))


def _plan(scenario):
    return scenario.planner_def.plan(scenario, scenario.robot_def, DT)


def _off_line(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Each point's distance (N,) from the segment a-b."""
    along = np.clip((points - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
    return np.linalg.norm(points - (a + along[:, None] * (b - a)), axis=1)


def _angle(r: np.ndarray, r0: np.ndarray) -> np.ndarray:
    """The angles (N,) from rotations r0 to r (N, 3, 3 each, or r0 one)."""
    return np.arccos(np.clip((np.einsum("nij,nij->n", r, np.broadcast_to(r0, r.shape)) - 1) / 2, -1.0, 1.0))


@pytest.fixture(scope="module", params=list(ARMS))
def arm(request) -> tuple[str, Arm, list]:
    mj = Arm(request.param)
    return request.param, mj, _lines(mj, LINES, SEED)


@pytest.mark.parametrize("method", METHODS)
def test_a_free_plan_on_the_path_keeps_the_tool_on_the_line_by_mujocos_kinematics(arm, method, tmp_path):
    name, mj, lines = arm
    kept = 0
    for q, a, b in lines:
        plan = _plan(_scenario(tmp_path, mj, q, b, method, analysis=f"analysis: {{path_tolerance: {KEPT}}}\n"))
        assert "tool_orientation_ref" not in plan.series and plan.info["plan_orientation_error_max"] is None
        off = _off_line(mj.pose(plan.q_ref)[0], a, b).max()
        reported = any(v.kind == "off_path" for v in plan.violations)
        assert (off > KEPT) == reported, (name, method, q.round(4).tolist(), b.tolist(), off)
        kept += not reported
    assert kept >= 0.8 * LINES, (name, method, kept)  # measured: see the module's docstring


def test_free_runs_end_ok_with_the_orientation_unjudged(arm, tmp_path):
    """The first three lines whose planned tool turns by more than 10 deg (MuJoCo's kinematics at q_ref)."""
    name, mj, lines = arm
    runs = 0
    for i, (q, a, b) in enumerate(lines):
        scenario = _scenario(tmp_path, mj, q, b, "dls_adaptive")
        turn = _angle(mj.pose(_plan(scenario).q_ref)[1], mj.pose(q)[1][0]).max()
        if np.rad2deg(turn) <= 10:
            continue
        result = simbench.run(scenario, out=tmp_path / f"run{i}", video=False)
        report, ts = result.report, np.load(tmp_path / f"run{i}" / "timeseries.npz")
        assert report["status"] == "ok", (name, i, report["violations"])
        points, rotations = mj.pose(ts["q"])
        assert _off_line(points, a, b).max() <= scenario.analysis.path_tolerance
        assert "tool_orientation_ref" not in ts
        assert turn > 5 * scenario.analysis.orientation_tolerance  # held, it would have broken the promise
        from_plan = _angle(rotations, mj.pose(ts["q_ref"])[1])  # unjudged: the recorded tool's from the planned's
        assert report["tracking"]["orientation_max"] == pytest.approx(from_plan.max(), abs=1e-6)
        runs += 1
        if runs == 3:
            break
    assert runs == 3


def test_hold_on_the_so100_reports_the_plans_own_orientation_error(tmp_path):
    """The SO-100's 5 joints cannot hold the tool's orientation along a line across its reach: the plan is made,
    and its orientation_error is as far as MuJoCo's kinematics turn its tool from the start's orientation."""
    mj = Arm("so100")
    q = np.array([0.2, 1.5, -1.5, 0.5, 0.3])
    (point,), (r0,) = mj.pose(q)
    plan = _plan(_scenario(tmp_path, mj, q, point + [0.05, 0.04, -0.03], "dls_adaptive", orientation="hold"))
    turned = _angle(mj.pose(plan.q_ref)[1], r0)
    errors = [v for v in plan.violations if v.kind == "orientation_error"]
    assert "tool_orientation_ref" in plan.series and len(errors) == 1
    assert turned.max() > np.deg2rad(2.0)  # the default orientation tolerance
    assert errors[0].detail["worst"] == pytest.approx(turned.max(), abs=1e-6)


def _first_point(segment: dict) -> np.ndarray:
    """A scenario segment's first point: a line's start, an arc's at its start angle (from `ref` towards
    normal x ref)."""
    if "line" in segment:
        return np.array(segment["line"]["start"])
    arc = segment["arc"]
    ref, normal = np.array(arc["ref"]), np.array(arc["normal"]) / np.linalg.norm(arc["normal"])
    return np.array(arc["center"]) + arc["radius"] * (np.cos(arc["start"]) * ref
                                                      + np.sin(arc["start"]) * np.cross(normal, ref))


def test_a_bench_suite_gives_the_so100_free_paths(tmp_path):
    """Its tasks (a line, an arc, a line) by every method but the paper's, which it has none of: cartesian_path's
    with the orientation free, mink on the same path with the orientation's cost 0; each a valid scenario whose path
    starts at the tool's point at its start joints (MuJoCo's)."""
    path = tmp_path / "suite.yaml"
    path.write_text(yaml.safe_dump({"name": "small", "tasks": 3, "seed": 0,
                                    "robots": [{"name": "so100", **ARMS["so100"]}]}))
    variants = plan_bench(load_suite(path)).variants
    methods = {"dls_adaptive": None, "pinv": "pinv", "dls": "dls", "time_scaling": "time_scaling", "mink": None}
    assert [v.params["method"] for v in variants] == 3 * list(methods)
    mj = Arm("so100")
    for variant in variants:
        task, method = variant.document["task"], variant.params["method"]
        assert variant.document["planner"] == ("mink_baseline" if method == "mink" else "cartesian_path")
        assert task["orientation"] == "free" and task.get("method") == methods[method]
        assert task.get("orientation_cost") == (0.0 if method == "mink" else None)
        parse_scenario(variant.document, variant.id)
        (start,), _ = mj.pose(np.array(task["start"]))
        assert np.linalg.norm(start - _first_point(task["path"][0])) < 1e-6


def test_mink_holds_the_orientation_a_planar_arms_bench_task_asks(tmp_path):
    """The planar 3R's bench tasks hold the tool's orientation (about the plane's normal, all its three joints can
    hold): mink's plan of each keeps the tool site's orientation, by MuJoCo's kinematics of the planned joints,
    within the analysis' orientation tolerance of its start (with the orientation's cost 0 it turned 7 and 15 deg
    while its report said ok)."""
    variants = plan_bench(load_suite("planar3r").with_options(tasks=2, methods=["mink"])).variants
    assert [v.params["method"] for v in variants] == ["mink", "mink"]
    for variant in variants:
        scenario = parse_scenario(variant.document, variant.id)
        plan = scenario.planner_def.plan(scenario, scenario.robot_def, 0.001)
        model = mujoco.MjModel.from_xml_path(variant.document["robot"]["model"])
        data, site = mujoco.MjData(model), model.site(variant.document["robot"]["tool"]["site"]).id
        turns = []
        for q in plan.q_ref:
            data.qpos[:len(q)] = q
            mujoco.mj_kinematics(model, data)
            turns.append(data.site_xmat[site].reshape(3, 3).copy())
        worst = max(np.degrees(np.arccos(np.clip((np.trace(turns[0].T @ r) - 1) / 2, -1, 1))) for r in turns)
        assert worst < np.degrees(scenario.analysis.orientation_tolerance), (variant.id, worst)
