"""What `python -m simbench run` writes, checked as a user would read it (docs/guide/outputs.md)."""

import json

import imageio.v2 as imageio
import mujoco
import numpy as np
import pytest
import yaml

from simbench.cli import main
from simbench.outputs.report import write_timeseries
from tests.conftest import SHIPPED, scenario_file


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("runs") / "demo"
    assert main(["run", str(scenario_file("spherical_arm", "demo")), "--out", str(out), "--quiet"]) == 0
    return out


def test_report_has_the_contract_fields(demo_run):
    report = json.loads((demo_run / "report.json").read_text())
    for key in ("scenario", "robot", "planner", "versions", "timestep", "duration", "tracking",
                "singularity_events", "limit_events", "warnings", "wall_time", "outputs", "waypoints"):
        assert key in report, key
    assert report["versions"]["mujoco"] == mujoco.__version__
    tracking = report["tracking"]
    assert set(tracking["joint_rms"]) == {"q1", "q2", "q3", "q4"} == set(tracking["joint_max"])
    assert 0 < tracking["tool_rms"] <= tracking["tool_max"] < 2e-3
    for stage in ("plan", "simulate", "analyse", "plots", "video", "write", "total"):
        assert report["wall_time"][stage] >= 0
    for event in report["singularity_events"] + report["limit_events"]:
        assert set(event) == {"t_start", "t_end", "kind", "detail"} and event["t_start"] <= event["t_end"]
    assert [e["kind"] for e in report["singularity_events"]] == ["cos_q3_zero"]
    waypoint = report["waypoints"][0]
    assert len(waypoint["X"]) == 3 and len(waypoint["q"]) == 4


def test_timeseries_rows_match_the_report(demo_run):
    report = json.loads((demo_run / "report.json").read_text())
    ts = np.load(demo_run / "timeseries.npz")
    n = report["samples"]
    assert ts["t"].shape == (n,)
    assert ts["t"][-1] == pytest.approx(report["duration"] + report["hold"])
    for name, width in (("q_ref", 4), ("q", 4), ("qd", 4), ("ctrl", 4), ("tool_ref", 3), ("tool", 3)):
        assert ts[name].shape == (n, width), name
    for name in ("manipulability", "axis_distance", "path_deviation"):
        assert ts[name].shape == (n,), name
    deviation = ts["path_deviation"]
    assert np.sqrt(np.mean(deviation**2)) == pytest.approx(report["tracking"]["tool_rms"])
    assert np.abs(ts["q"][:, 2]).max() < np.pi + 0.01  # radians, not degrees


def test_plots_are_pngs(demo_run):
    report = json.loads((demo_run / "report.json").read_text())
    assert len(report["outputs"]["plots"]) == 5
    for name in report["outputs"]["plots"]:
        image = imageio.imread(demo_run / name)
        assert image.shape[0] > 300 and image.shape[1] > 500
        assert image.std() > 10


def test_video_plays_with_the_path_and_the_moving_arm(demo_run):
    report = json.loads((demo_run / "report.json").read_text())
    frames = np.array([frame for frame in imageio.get_reader(demo_run / "video.mp4")])
    fps = report["outputs"]["video_info"]["fps"]
    assert frames.shape[1:] == (480, 640, 3)
    assert len(frames) == int((report["duration"] + report["hold"]) * fps) + 1
    assert np.abs(frames[-1].astype(int) - frames[0].astype(int)).mean() > 1.0
    blue = (frames[0, :, :, 2] > 180) & (frames[0, :, :, 0] < 80)

    def red(frame):  # the trace's red, also where the faint past plan overlays it; not the orange links
        f = frame.astype(int)
        return ((f[:, :, 0] > 160) & (f[:, :, 1] < 100) & (f[:, :, 2] < 120)).sum()

    assert blue.sum() > 50, "planned path not visible"
    middle = len(frames) // 2  # by the end the radial link lies along the line and hides much of the trace
    assert red(frames[middle]) - red(frames[0]) > 200, "tool trace not visible"


def test_same_run_twice_gives_identical_timeseries(tmp_path):
    path = str(scenario_file("spherical_arm", "case1"))
    for name in ("a", "b"):
        assert main(["run", path, "--out", str(tmp_path / name), "--no-video", "--quiet"]) == 0
    a, b = np.load(tmp_path / "a" / "timeseries.npz"), np.load(tmp_path / "b" / "timeseries.npz")
    assert set(a.files) == set(b.files)
    for name in a.files:
        assert np.array_equal(a[name], b[name]), name
    assert not (tmp_path / "a" / "video.mp4").exists()


def test_existing_output_is_replaced_whole_only_with_force_and_never_a_users_file(tmp_path, capsys):
    out = tmp_path / "out"
    path = str(scenario_file("spherical_arm", "case1"))
    assert main(["run", path, "--out", str(out), "--no-video", "--quiet"]) == 0
    (out / "notes.txt").write_text("the user's own")
    before = (out / "report.json").read_bytes()
    capsys.readouterr()
    assert main(["run", path, "--out", str(out), "--no-video", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"error: {out}: the output folder exists; pass --force to replace it, or --out to write elsewhere"]
    assert main(["run", path, "--out", str(out), "--no-video", "--quiet", "--force"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "simbench did not write (such as notes.txt)" in err[0]
    assert (out / "notes.txt").exists() and (out / "report.json").read_bytes() == before
    (out / "notes.txt").unlink()
    (out / "plots" / "joints.png").write_bytes(b"an older run's plot")  # simbench's own: replaced
    assert main(["run", path, "--out", str(out), "--no-video", "--quiet", "--force"]) == 0
    assert (out / "plots" / "joints.png").read_bytes().startswith(b"\x89PNG")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_shipped_scenarios_validate(path, capsys):
    assert main(["validate", str(path)]) == 0
    assert capsys.readouterr().out.startswith(f"{path}: valid")


@pytest.mark.parametrize("name", ["case3", "case4"])
def test_validate_prints_the_plans_warnings_as_a_run_does(name, capsys, evaluated):
    """case3's start moved by the repair, case4's path leaving the workspace: each of the plan's warnings on its
    own line, as the run's summary prints them."""
    _, ev = evaluated("spherical_arm", name)
    assert ev.trajectory.warnings
    main(["validate", str(scenario_file("spherical_arm", name))])
    lines = capsys.readouterr().out.splitlines()
    printed = [line for line in lines if "plan warning" in line]
    assert printed == [f"  plan warning: {w}" for w in ev.trajectory.warnings]


def test_list_names_robots_planners_and_scenarios(capsys):
    assert main(["list"]) == 0
    text = capsys.readouterr().out
    assert "spherical_arm" in text and "safe_straight_path" in text and "joint_move" in text
    for path in SHIPPED:
        assert path.name in text


@pytest.mark.parametrize("path", SHIPPED, ids=[f"{p.parent.name}/{p.stem}" for p in SHIPPED])
def test_every_shipped_scenario_runs_to_complete_and_bit_for_bit_repeatable_outputs(path, tmp_path, evaluated):
    """The run's outputs are all there, it ends `ok` unless its scenario says it shows a failure, and then with
    exactly the violations it names; and its timeseries equals, byte for byte, the one written from the
    session's own evaluation of the scenario (made separately, among other runs in this process)."""
    out = tmp_path / path.stem
    assert main(["run", str(path), "--out", str(out), "--no-video", "--quiet"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["scenario"]["name"] == path.stem
    expect = yaml.safe_load(path.read_text()).get("expect")
    assert report["status"] == (expect["status"] if expect else "ok")
    assert sorted({v["kind"] for v in report["violations"]}) == sorted(expect["violations"] if expect else [])
    assert all((out / name).is_file() for name in report["outputs"]["plots"])
    scenario, other = evaluated(path.parent.name, path.stem)
    write_timeseries(scenario.robot_def, other.trajectory, other.recording, other.analysis, tmp_path / "other.npz")
    a, b = np.load(out / "timeseries.npz"), np.load(tmp_path / "other.npz")
    assert a["t"].size == report["samples"]
    assert a.files == b.files and len(a.files) > 10
    for name in a.files:
        assert a[name].dtype == b[name].dtype and a[name].tobytes() == b[name].tobytes(), name


def test_the_fast_npz_writer_round_trips_through_np_load(tmp_path):
    """report.savez_fast writes what np.load reads back bit for bit, as np.savez_compressed's file: floats of
    any shape, integers, booleans, strings, empty arrays."""
    from simbench.outputs.report import savez_fast

    rng = np.random.default_rng(11)
    arrays = {"t": np.linspace(0, 1, 1001), "q": rng.normal(size=(1001, 7)), "flags": rng.random(50) < 0.5,
              "counts": rng.integers(-5, 5, (3, 4, 5)), "joints": np.array(["q1", "q2", "wrist_3"]),
              "none": np.zeros((0, 3)), "scalar": np.float64(np.pi)}
    with open(tmp_path / "a.npz", "wb") as f:
        savez_fast(f, arrays)
    back = np.load(tmp_path / "a.npz")
    assert sorted(back.files) == sorted(arrays)
    for name, value in arrays.items():
        assert back[name].dtype == np.asarray(value).dtype and np.array_equal(back[name], value), name
