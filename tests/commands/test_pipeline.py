"""One run end to end through the Python API (simbench.commands.pipeline): what `run` writes and what it says it wrote,
the report a sweep keeps, the stopwatch, a run whose physics fails, `check_plan`, and outputs that appear
whole or not at all. (What the CLI prints and every shipped scenario's outputs: test_outputs.py; file-system
refusals: test_filesystem.py; faults in the physics: test_reliability.py.)"""

import json
import time
from pathlib import Path

import imageio.v2 as imageio
import numpy as np
import pytest
import yaml

import simbench
from simbench.commands import pipeline
from simbench.core.destination import MARKER
from simbench.core.errors import PhysicsError, ScenarioError
from simbench.scenario import load_scenario, parse_scenario
from tests.conftest import scenario_file

TIMING = {"law": "quintic", "duration": 1.5, "hold": 0.2}
RENDER = {"width": 128, "height": 96, "fps": 5}
STAGES = {"load", "plan", "simulate", "analyse", "plots", "write"}  # and "video" when there is one


def short_case1() -> dict:
    """Table 2 case 1 in 1.5 s (in 1 s q3 would pass its speed limit) with a small video, as a document."""
    doc = yaml.safe_load(scenario_file("spherical_arm", "case1").read_text())
    doc.update(timing=TIMING, render=RENDER)
    return doc


def written(folder: Path) -> set[str]:
    """Every file under `folder` but simbench's marker, by path relative to it."""
    return {p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file() and p.name != MARKER}


def listed(outputs: dict) -> set[str]:
    """The files a report's `outputs` names."""
    names = set()
    for key, value in outputs.items():
        if key != "video_info":
            names |= set(value) if isinstance(value, list) else {value}
    return names


def no_plots(monkeypatch) -> None:
    """Skip the matplotlib plots (about a second a run) where they are not what a test looks at."""
    monkeypatch.setattr(pipeline, "write_plots", lambda *args: [])


def leftovers(parent: Path) -> list[str]:
    """Hidden staging or set-aside folders and lock files simbench left beside its outputs."""
    return sorted(p.name for p in parent.iterdir() if p.name.startswith("."))


@pytest.fixture(scope="module")
def full_run(tmp_path_factory):
    """One complete run (plots and video) into an existing empty folder: (scenario, out, result, seconds the
    call took)."""
    scenario = parse_scenario(short_case1(), "short")
    out = tmp_path_factory.mktemp("runs") / "short"
    out.mkdir()  # existing but empty: taken without force
    start = time.perf_counter()
    result = simbench.run(scenario, out=out)
    return scenario, out, result, time.perf_counter() - start


def test_a_run_writes_exactly_the_files_its_report_lists(full_run):
    scenario, out, result, _ = full_run
    report = json.loads((out / "report.json").read_text())
    assert report == json.loads(json.dumps(result.report))  # what run() returns is what it wrote
    assert written(out) == listed(report["outputs"])
    assert set(json.loads((out / MARKER).read_text())["files"]) == written(out)
    assert report["outputs"]["report"] == "report.json" and report["outputs"]["video"] == "video.mp4"
    assert {p.split("/")[0] for p in report["outputs"]["plots"]} == {"plots"} and report["outputs"]["plots"]
    for name in report["outputs"]["plots"]:
        assert (out / name).read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    assert np.load(out / "timeseries.npz")["t"].size == report["samples"]
    assert sorted(p.name for p in out.parent.iterdir()) == ["short"]  # nothing left beside it


def test_the_video_is_made_with_the_scenarios_render_settings(full_run):
    _, out, result, _ = full_run
    frames = [frame for frame in imageio.get_reader(out / "video.mp4")]
    duration = TIMING["duration"] + TIMING["hold"]
    assert len(frames) == int(duration * RENDER["fps"] + 1e-6) + 1
    assert frames[0].shape == (RENDER["height"], RENDER["width"], 3)
    assert result.report["outputs"]["video_info"] == {"frames": len(frames), **RENDER, "camera": "front",
                                                      "quality": "fast"}


def test_the_stopwatch_stages_add_up_to_the_total_within_the_calls_own_time(full_run):
    _, _, result, seconds = full_run
    wall = result.report["wall_time"]
    stages = {k: v for k, v in wall.items() if k != "total"}
    assert set(stages) == STAGES | {"video"}
    assert all(v >= 0 for v in stages.values()) and stages["simulate"] > 0 and stages["video"] > 0
    assert sum(stages.values()) == pytest.approx(wall["total"], abs=1e-4 * len(stages))
    assert wall["total"] <= seconds


def test_the_report_a_sweep_keeps_is_the_runs_but_for_what_was_written_and_when(full_run):
    """pipeline.evaluate_report (a sweep's runs/<id>/report.json) plans and simulates anew and writes nothing;
    everything it measures equals the written report's."""
    scenario, out, _, _ = full_run
    written_report = json.loads((out / "report.json").read_text())
    kept = json.loads(json.dumps(pipeline.evaluate_report(scenario)))
    assert kept["outputs"] == {} and set(kept["wall_time"]) == STAGES - {"plots", "write"} | {"total"}
    for report in (written_report, kept):
        del report["outputs"], report["wall_time"]
    assert kept == written_report


def test_without_a_video_none_is_made_listed_or_timed(tmp_path, monkeypatch):
    no_plots(monkeypatch)
    result = simbench.run(parse_scenario(short_case1(), "short"), out=tmp_path / "out", video=False)
    expected = {"report.json", "timeseries.npz", "index.html"}
    assert written(tmp_path / "out") == expected == listed(result.report["outputs"])
    assert set(result.report["wall_time"]) == STAGES | {"total"}


def test_the_default_folder_is_renders_name_and_evaluate_writes_nothing(tmp_path, monkeypatch):
    """Given a path, run writes into renders/<the file's name>/ under the working folder; evaluate, given the
    same path, writes nothing anywhere there."""
    path = tmp_path / "scenario" / "quick.yaml"
    path.parent.mkdir()
    path.write_text(yaml.safe_dump(short_case1()))
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    ev = simbench.evaluate(str(path))
    assert list(work.iterdir()) == [] and ev.verdict.status == "ok"
    no_plots(monkeypatch)
    result = simbench.run(path, video=False)
    assert result.out == Path("renders") / "quick"
    assert written(work) == {"renders/quick/report.json", "renders/quick/timeseries.npz", "renders/quick/index.html"}
    description = yaml.safe_load(path.read_text())["description"]
    assert result.report["scenario"] == {"name": "quick", "file": str(path), "description": description}


def test_a_folder_simbench_did_not_write_is_never_replaced(tmp_path):
    """A folder holding a user's file is refused with or without force, before anything is planned, and left as
    it was."""
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("the user's own")
    scenario = parse_scenario(short_case1(), "short")
    with pytest.raises(ScenarioError, match="the output folder exists; pass force=True"):
        simbench.run(scenario, out=out, video=False)
    with pytest.raises(ScenarioError,
                       match=r"holds 1 file\(s\) or folder\(s\) simbench did not write \(such as notes.txt\)"):
        simbench.run(scenario, out=out, video=False, force=True)
    assert written(out) == {"notes.txt"} and (out / "notes.txt").read_text() == "the user's own"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine"]


@pytest.mark.parametrize("error", [RuntimeError("a bug while writing"), KeyboardInterrupt()],
                         ids=["exception", "ctrl-c"])
def test_outputs_appear_whole_or_not_at_all(tmp_path, monkeypatch, error):
    """An error while the last output (the report) is half-written, every other one already made: into a new
    folder nothing appears; over an earlier run's output (force) that output stays byte for byte."""
    no_plots(monkeypatch)
    scenario = parse_scenario(short_case1(), "short")
    earlier = tmp_path / "earlier"
    simbench.run(scenario, out=earlier, video=False)
    before = {name: (earlier / name).read_bytes() for name in written(earlier)}

    def half_then_fail(report, path):
        Path(path).write_text(json.dumps(report)[:100])
        raise error

    monkeypatch.setattr(pipeline, "write_report", half_then_fail)
    for out, force in ((tmp_path / "new", False), (earlier, True)):
        with pytest.raises(type(error)):
            simbench.run(scenario, out=out, video=False, force=force)
    assert not (tmp_path / "new").exists()
    assert {name: (earlier / name).read_bytes() for name in written(earlier)} == before
    assert leftovers(tmp_path) == []


def test_a_run_whose_physics_fails_raises_what_it_wrote(tmp_path):
    """The PUMA's q3 servo 1000 times too stiff diverges (test_reliability.py): run() writes the report of the
    failure and the timeseries up to it, lists exactly those, and raises PhysicsError carrying the same time,
    cause and recording."""
    doc = yaml.safe_load(scenario_file("puma600", "line").read_text())
    doc["sim"] = {"force_limits": False, "kp": [8000, 12000, 5.0e6, 800, 800, 600]}
    out = tmp_path / "out"
    with pytest.raises(PhysicsError) as caught:
        simbench.run(parse_scenario(doc, "stiff"), out=out)
    err = caught.value
    report = json.loads((out / "report.json").read_text())
    assert written(out) == {"report.json", "timeseries.npz", "index.html"} == listed(report["outputs"])
    assert report["status"] == "failed"
    assert report["failure"] == {"stage": "simulate", "t": pytest.approx(err.t), "cause": err.cause}
    ts = np.load(out / "timeseries.npz")
    assert report["samples"] == ts["t"].size == err.recording.t.size > 0
    assert np.array_equal(ts["t"], err.recording.t) and np.array_equal(ts["q"], err.recording.q)
    assert "video" not in report["wall_time"] and report["wall_time"]["simulate"] > 0


def test_check_plan_finds_the_plans_limit_without_simulating(monkeypatch, evaluated):
    """Case 4's plan takes q3 past its -75 deg limit: check_plan names that joint, and only the joints its own
    reference takes out of range, with the run's own words for it, and never simulates."""
    scenario, ev = evaluated("spherical_arm", "case4")
    monkeypatch.setattr(pipeline, "simulate", lambda *args, **kwargs: pytest.fail("check_plan simulated"))
    traj, verdict = pipeline.check_plan(load_scenario(scenario_file("spherical_arm", "case4")))
    robot = scenario.robot_def
    beyond = {joint for j, joint in enumerate(robot.joints)
              if traj.q_ref[:, j].min() < robot.lower[j] or traj.q_ref[:, j].max() > robot.upper[j]}
    assert beyond == {"q3"} and np.rad2deg(traj.q_ref[:, 2].min()) < -75.0
    plan_limits = [v for v in verdict.violations if v["kind"] == "joint_limit"]
    assert {v["joint"] for v in plan_limits} == beyond
    assert verdict.status == "limits" and verdict.expected["met"]
    assert plan_limits == [v for v in ev.verdict.violations if v["kind"] == "joint_limit"]

