"""The shipped PUMA 600 and spherical arm loaded as generic arms from their own MJCF (robot: a mapping, no code) agree
with their analytic selves on their shipped singularity scenarios.

Each scenario runs twice through the CLI: with the shipped robot, and with `robot: {model: <its MJCF>, tool: {site:
tool}, speed_limits: <the robot's>}`. The planners accept the generic arm (it bears the model's name), the scenes
hold the same arm and servos, so the two runs record the same motion, and the singular events are compared:

  - the instant closest to the singularity (`t_closest`): the generic arm's is where the Jacobian columns its
    rank loss binds (those its null motion moves) are nearest dependence (robots.rank_loss.closest_sample). On
    the spherical arm's case 1 it is the analytic set's (cos q3 = 0) to the sample; on the PUMA's wrist line the
    analytic wrist event's, the minimum of |q5|, to the sample. The whole Jacobian's least singular value (the
    generic one equal to the analytic closed-form frame-3 Jacobian's) reaches its minimum 3 samples (3 ms) later
    there: it is not a function of q5 alone (q4 and q6 spin near the singularity);
  - the spans: the generic gap (a singular value) is not the analytic one (an angle), so under the same near_angle
    the generic span contains the analytic one rather than equalling it.
"""

import json

import numpy as np
import yaml

from simbench.cli import main
from simbench.core.resources import models_dir
from simbench.robots import puma600 as P
from simbench.robots import spherical_arm as S
from simbench.robots.rank_loss import rank_loss_detail
from simbench.scenario import load_scenario
from tests.conftest import scenario_file


def _run(folder, doc: dict) -> tuple[dict, dict]:
    """The report and time series of the scenario `doc`, run through the CLI."""
    folder.mkdir()
    path = folder / "scenario.yaml"
    path.write_text(yaml.safe_dump(doc))
    assert main(["run", str(path), "--out", str(folder / "out"), "--no-video", "--quiet"]) == 0
    return json.loads((folder / "out" / "report.json").read_text()), dict(np.load(folder / "out" / "timeseries.npz"))


def _both(tmp_path, robot, scenario: str):
    """The shipped robot's run of a shipped scenario and the generic arm's of the same task, its speed limits the
    robot's (`robot`: the analytic module): ((report, series), (report, series))."""
    doc = yaml.safe_load(scenario_file(robot.ROBOT.name, scenario).read_text())
    shipped = _run(tmp_path / "shipped", doc)
    scale = {"revolute": np.rad2deg(1.0), "prismatic": 1e3}  # the scenarios' units: deg and mm
    assert doc["units"] == {"angle": "deg", "length": "mm"}
    name = robot.ROBOT.name
    doc["robot"] = {"model": str(models_dir() / name / f"{name}.xml"), "tool": {"site": "tool"},
                    "speed_limits": [float(v * scale[kind]) for v, kind in zip(robot.QD_MAX, robot.KINDS)]}
    generic = _run(tmp_path / "generic", doc)
    np.testing.assert_allclose(generic[1]["q"], shipped[1]["q"], atol=1e-9)  # the same motion
    return shipped, generic


def _event(report: dict, kind: str) -> dict:
    """The report's one singular event of `kind`."""
    found = [e for e in report["singularity_events"] if e["kind"] == kind]
    assert len(found) == 1, report["singularity_events"]
    return found[0]


def _samples(report: dict, a: float, b: float) -> int:
    """How many recorded samples apart the instants a and b are."""
    return round(abs(a - b) / (report["timestep"] * report["record_every"]))


def _contains(outer: dict, inner: dict) -> bool:
    return outer["t_start"] <= inner["t_start"] and outer["t_end"] >= inner["t_end"]


def test_the_generic_puma_finds_the_wrist_singularity(tmp_path):
    (shipped, _), (generic, series) = _both(tmp_path, P, "wrist_singularity")
    wrist, rank = _event(shipped, "wrist"), _event(generic, "rank_loss")
    assert [e["kind"] for e in generic["singularity_events"]] == ["rank_loss"]
    t, q = series["t"], series["q"]
    analytic = np.linalg.svd(P.frame3_jacobian(q), compute_uv=False)
    jac = load_scenario(tmp_path / "generic" / "scenario.yaml").robot_def.jacobian(q)
    jac[:, :3] /= P.A2 + P.D4  # the analytic Jacobian's characteristic length
    np.testing.assert_allclose(np.linalg.svd(jac, compute_uv=False), analytic, atol=1e-12)
    assert _samples(generic, rank["detail"]["t_closest"], wrist["detail"]["t_closest"]) <= 1  # measured: 0
    assert wrist["detail"]["t_closest"] == t[np.argmin(np.abs(q[:, 4]))]
    assert _samples(generic, t[np.argmin(analytic[:, -1])], wrist["detail"]["t_closest"]) == 3  # the whole J's
    assert _contains(rank, wrist)


def test_the_generic_spherical_arm_finds_the_lift_axis(tmp_path):
    (shipped, _), (generic, _) = _both(tmp_path, S, "case1")
    axis, rank = _event(shipped, "cos_q3_zero"), _event(generic, "rank_loss")
    assert [e["kind"] for e in generic["singularity_events"]] == ["rank_loss"]
    assert _samples(generic, rank["detail"]["t_closest"], axis["detail"]["t_closest"]) == 0
    assert _contains(rank, axis)
    assert _samples(generic, rank["t_start"], axis["t_start"]) <= 6 >= _samples(generic, rank["t_end"], axis["t_end"])



def test_rank_loss_names_the_pumas_wrist_shoulder_and_elbow_where_the_analytic_sets_are(tmp_path):
    """The generic PUMA (its MJCF, no code) at random configurations on each of its analytic singular sets (puma600:
    q5 = 0; a3 s3 + d4 c3 = 0, stretched; r = 0 solved for q2), away from the other two (|q5| of 40 deg at least,
    where the wrist undoing a turn of joint 1 does not need most of the null motion): rank_loss's
    sigma_min is 0 there and its `named` is the set's."""
    path = tmp_path / "puma.yaml"
    path.write_text(yaml.safe_dump({"robot": {"model": str(models_dir() / "puma600" / "puma600.xml"),
                                              "tool": {"site": "tool"}, "speed_limits": [250.0] * 6},
                                    "planner": "joint_move", "units": {"angle": "deg"},
                                    "task": {"start": [180, -135, -180, 0, 45, 0], "goal": [180, -135, -180, 0, 45, 1]},
                                    "timing": {"duration": 1.0}}))
    robot = load_scenario(path).robot_def
    rng = np.random.default_rng(11)
    named = {"wrist": 0, "shoulder": 0, "elbow": 0}
    while min(named.values()) < 10:
        q = rng.uniform(P.LOWER, P.UPPER)
        q[4] = np.deg2rad(rng.choice([-1, 1]) * rng.uniform(40, 100))
        wrist, elbow, shoulder = q.copy(), q.copy(), q.copy()
        wrist[4] = 0.0
        elbow[2] = P.STRETCH
        c3, s3 = np.cos(q[2]), np.sin(q[2])
        shoulder[1] = np.arctan2(P.A2 + P.A3 * c3 - P.D4 * s3, P.A3 * s3 + P.D4 * c3)  # r = c2 G - s2 H = 0
        for name, at in (("wrist", wrist), ("elbow", elbow), ("shoulder", shoulder)):
            gaps = {"wrist": P.wrist_gap(at)[0], "elbow": P.elbow_gap(at)[0], "shoulder": P.shoulder_gap(at)[0]}
            assert gaps[name] < 1e-12
            if min(v for k, v in gaps.items() if k != name) < 0.2:
                continue  # near another set too
            detail = rank_loss_detail(robot.jacobian(at[None])[0], robot.reach)
            assert detail["sigma_min"] < 1e-9 and detail.get("named") == name, (name, np.rad2deg(at), detail)
            named[name] += 1
