"""sim.record_every: a long run's timeseries thinned to every k-th sample (and the last), while the report's errors
and events still come from every sample. The truth for each stride is the same run recorded whole (stride 1)."""

import json
import subprocess
import sys

import numpy as np
import pytest
import yaml

import simbench
from simbench import analysis
from simbench.analysis.verdict import run_verdict
from simbench.api import registry
from simbench.commands import pipeline
from simbench.core import windowed
from simbench.core.errors import ControlError
from simbench.physics import stepping
from simbench.physics.controllers import Servo
from simbench.physics.sim import simulate
from simbench.robots import Tolerance
from simbench.scenario import parse_scenario
from tests.conftest import scenario_file
from tests.physics.test_sim import ClosedServo, Scripted, planned, shipped

_HEAVY = ("qpos", "qd", "ctrl")  # the columns a stride thins in the Recording itself
_EVERY_ROW = ("t", "q", "tool", "force")  # and those the analysis reads at every row


def _rows(n: int, k: int) -> np.ndarray:
    """0, k, 2k, ... below n, and n - 1."""
    return np.array(sorted(set(range(0, n, k)) | {n - 1}))


def _strided(robot: str, name: str, k: int) -> simbench.Scenario:
    """A shipped scenario recorded with stride k."""
    raw = yaml.safe_load(scenario_file(robot, name).read_text())
    raw["sim"] = {**raw.get("sim", {}), "record_every": k}
    return parse_scenario(raw, f"{robot}/{name}", default_name=name)


@pytest.mark.parametrize("robot, name, k", [("rsmg", "three_turns", 10), ("spherical_arm", "case1", 7),
                                            ("puma600", "line", 3), ("agile_eye", "through_singularity", 9)])
def test_a_stride_keeps_the_whole_runs_rows_and_reports_the_same(evaluated, robot, name, k):
    """The evaluation of a strided run holds the stride-1 run's rows [::k] and its last, bit for bit: every column
    of the recording, the plan, and the analysis' series (the RSMG's and the Agile Eye's a window of samples at a
    time, from their Summarisers); the tracking figures, the events and the robot's report (the RSMG's re-grips,
    closure and rotor errors, the Agile Eye's assembly-mode changes) are those of every row."""
    _, whole = evaluated(robot, name)
    thin = simbench.evaluate(_strided(robot, name, k))
    assert thin.analysis.samples == whole.recording.t.size
    _same_at_the_kept_rows(thin, whole, k)


def _same_at_the_kept_rows(thin, whole, k: int) -> None:
    """Evaluation `thin` (stride k) holds `whole`'s rows [::k] and its last, bit for bit (the recording's columns,
    its sensors and constraints, the plan, the analysis' series), and the same figures, events and verdict."""
    rows = _rows(whole.recording.t.size, k)
    assert thin.recording.kept is None
    for column in _HEAVY + _EVERY_ROW:
        assert np.array_equal(getattr(thin.recording, column), getattr(whole.recording, column)[rows]), column
    for key in ("sensors", "eq_active"):
        for name, values in getattr(thin.recording, key).items():
            assert np.array_equal(values, getattr(whole.recording, key)[name][rows]), name
    assert np.array_equal(thin.trajectory.q_ref, whole.trajectory.q_ref[rows])
    assert thin.analysis.series.keys() == whole.analysis.series.keys()
    for name, values in thin.analysis.series.items():
        assert np.array_equal(values, whole.analysis.series[name][rows]), name
    assert thin.analysis.tracking == whole.analysis.tracking
    assert thin.analysis.singularity_events == whole.analysis.singularity_events
    assert thin.analysis.limit_events == whole.analysis.limit_events
    assert json.dumps(thin.analysis.extra, default=str) == json.dumps(whole.analysis.extra, default=str)
    assert thin.verdict == whole.verdict


def test_the_outputs_of_a_stride_are_the_whole_runs_at_the_kept_rows(tmp_path):
    """timeseries.npz at stride k holds every array of the stride-1 run's at rows [::k] and the last; report.json
    says the stride and reports the same samples, errors and events."""
    k = 25
    whole = simbench.run(_strided("rsmg", "three_turns", 1), out=tmp_path / "whole", video=False)
    thin = simbench.run(_strided("rsmg", "three_turns", k), out=tmp_path / "thin", video=False)
    rows = _rows(whole.report["samples"], k)
    with np.load(tmp_path / "whole" / "timeseries.npz") as a, np.load(tmp_path / "thin" / "timeseries.npz") as b:
        assert sorted(a.files) == sorted(b.files)
        for name in a.files:
            expected = a[name] if name == "joints" else a[name][rows]
            assert np.array_equal(b[name], expected), name
    assert (whole.report["record_every"], thin.report["record_every"]) == (1, k)
    for key in ("samples", "tracking", "singularity_events", "limit_events", "switch_events", "closure_error_max",
                "rotor_error_max", "status"):
        assert thin.report[key] == whole.report[key], key


@pytest.mark.parametrize("controller", [Servo, ClosedServo])
def test_a_stride_across_many_chunks_of_either_stepper(monkeypatch, controller):
    """With chunks of 97 steps (the open-loop rollout's and the closed-loop scratch's), a stride of 10 keeps the
    same rows as a whole recording, for the rollout in C and for the controller asked every step."""
    plant, traj = planned(shipped("spherical_arm", "case1", duration=1.0))
    whole = simulate(plant, traj, controller())
    monkeypatch.setattr(stepping, "CHUNK", 97)
    thin = simulate(plant, traj, controller(), record_every=10)
    rows = _rows(whole.t.size, 10)
    for column in _HEAVY:
        assert np.array_equal(getattr(thin, column), getattr(whole, column)[rows]), column
    assert np.array_equal(thin.q, whole.q) and np.array_equal(thin.force, whole.force)


def test_a_failed_run_with_a_stride_keeps_the_strided_rows_before_the_failure():
    """A bad command at sample 250: the recording has every row's q before it, and the state of the kept rows
    among them, as a whole recording of the same failure has them."""
    plant, traj = planned(shipped("spherical_arm", "case1", duration=1.0), "torque")
    caught = []
    for k in (1, 20):
        with pytest.raises(ControlError) as err:
            simulate(plant, traj, Scripted(lambda nu: np.full(nu, np.nan), at=250), settle=0.05, record_every=k)
        caught.append(err.value.recording)
    whole, thin = caught
    assert np.array_equal(thin.t, whole.t) and np.array_equal(thin.q, whole.q)
    assert np.array_equal(thin.kept, np.arange(0, 250, 20))
    assert np.array_equal(thin.qpos, whole.qpos[::20])


@pytest.mark.parametrize("value", ["0", "-1", "1.5", "x"])
def test_a_bad_stride_is_refused_in_one_line_naming_the_field(tmp_path, value):
    """Not a whole number of at least 1: exit 2 before anything runs, one line naming sim.record_every."""
    raw = scenario_file("spherical_arm", "case1").read_text() + f"sim: {{record_every: {value}}}\n"
    path = tmp_path / "bad.yaml"
    path.write_text(raw)
    done = subprocess.run([sys.executable, "-m", "simbench", "run", str(path), "--out", str(tmp_path / "out"),
                           "--no-video"], capture_output=True, text=True)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "sim.record_every" in lines[0], done.stderr
    assert not (tmp_path / "out").exists()


def _windows_of_a_block(monkeypatch, dt: float) -> int:
    """Analysis windows (and path-search groups) of one path-search block: a few windows a shipped run."""
    block = windowed.near_reference(dt)
    monkeypatch.setattr(windowed, "WINDOW", block)  # a run of more than a block is long
    monkeypatch.setattr(windowed, "LONG", block)
    return block


@pytest.mark.parametrize("robot, name, k", [("rsmg", "three_turns", 10), ("agile_eye", "through_singularity", 9),
                                            ("spherical_arm", "case2", 7), ("puma600", "wrist_singularity", 4)])
def test_a_strided_run_analysed_as_it_is_simulated_is_the_whole_runs(monkeypatch, peak_speed, robot, name, k):
    """A strided run is analysed while it is simulated, a window at a time, and each window's every-step rows
    are let go after it (Rows.drop: every sample once, in order): its evaluation is the stride-1 run's
    (simulated whole and analysed after, in the same windows) at the kept rows, bit for bit, with the same
    figures, events (re-grips, reference jumps and their cost, spans cut by windows) and verdict; an outside
    metric's figures (conftest.PEAK_SPEED: the joints' speeds, recorded at the kept rows) are the stride-1
    recording's own at those rows, from every window; the shipped singularity_handling's speed share is the
    stride-1 plan's max |qd_ref| / qd_max."""
    whole = simbench.evaluate(_strided(robot, name, 1))
    window = _windows_of_a_block(monkeypatch, whole.trajectory.dt)
    whole = simbench.evaluate(_strided(robot, name, 1))
    dropped, windows = [], []
    drop, add = stepping.Rows.drop, analysis.Analyser.add
    monkeypatch.setattr(stepping.Rows, "drop", lambda self, samples: (dropped.append(samples), drop(self, samples)))
    monkeypatch.setattr(analysis.Analyser, "add", lambda self, rec: (windows.append(
        (self.samples, rec.kept, rec.ctrl.copy(), rec.qpos.copy())), add(self, rec)))
    thin = simbench.evaluate(_strided(robot, name, k))
    n = whole.recording.t.size
    assert n > window and thin.analysis.samples == n  # two windows at least
    assert dropped == [min(lo + window, n) for lo in range(0, n, window)]
    for lo, kept, ctrl, qpos in windows:  # each window's commands and states at its kept rows, as Recording.rows
        assert np.array_equal(ctrl, whole.recording.ctrl[lo + kept])
        assert np.array_equal(qpos, whole.recording.qpos[lo + kept])
    _same_at_the_kept_rows(thin, whole, k)
    truth = np.abs(whole.recording.qd[_rows(n, k)]).max(axis=0)  # qd is recorded at the kept rows
    assert thin.analysis.metrics["peak_speed"] == {"qd0_max": truth[0], "qd_max": truth.tolist(), "samples": n}
    # the shipped singularity_handling reads the plan of every sample
    shares = np.abs(whole.trajectory.qd_ref) / _strided(robot, name, 1).robot_def.qd_max
    assert thin.analysis.metrics["singularity_handling"]["speed_share_max"] == shares.max()
    assert thin.analysis.metrics["singularity_handling"] == whole.analysis.metrics["singularity_handling"]


def test_only_a_strided_run_of_a_robot_whose_summary_streams_is_analysed_as_it_is_simulated():
    """simulate refuses an analyser at stride 1 in one line (its windows' series would be views of readings
    handed back); which robots stream: those whose summary is Robot's, or whose summariser is defined with
    their summary or below it, not a subclass that overrides only `summary` (its parent's Summariser would not
    give its summary)."""
    scenario = shipped("spherical_arm", "case1", duration=1.0)
    plant, traj = planned(scenario)
    a = scenario.analysis
    near, margin = Tolerance(a.near_angle, a.near_length), Tolerance(a.limit_angle, a.limit_length)
    with pytest.raises(ValueError, match="record_every > 1"):
        simulate(plant, traj, record_every=1, analyser=analysis.Analyser(scenario.robot_def, traj, near, margin))
    rsmg_robot, arm = type(registry.robots()["rsmg"]), type(scenario.robot_def)

    class OwnSummary(rsmg_robot):
        def summary(self, traj, rec, series):
            return super().summary(traj, rec, series)

    class OwnBoth(OwnSummary):
        def summariser(self, traj):
            return super().summariser(traj)

    class ArmSummary(arm):
        def summary(self, traj, rec, series):
            return super().summary(traj, rec, series)

    streams = {cls.__name__: cls.streams.fget(object.__new__(cls)) for cls in (rsmg_robot, OwnSummary, OwnBoth, arm,
                                                                                ArmSummary)}
    assert streams == {rsmg_robot.__name__: True, "OwnSummary": False, "OwnBoth": True, arm.__name__: True,
                       "ArmSummary": False}


def test_the_outputs_of_a_run_simulated_strided_and_analysed_after_are_at_its_kept_rows(tmp_path):
    """write_outputs of an Evaluation put together from simulate (stride 5) and analyse, whose series are at the
    kept rows already: the timeseries holds the kept rows (the series were thinned a second time: IndexError)."""
    scenario = shipped("spherical_arm", "case1", duration=1.0)
    plant, traj = planned(scenario)
    a = scenario.analysis
    rec = simulate(plant, traj, record_every=5)
    result = analysis.analyse(scenario.robot_def, traj, rec, Tolerance(a.near_angle, a.near_length),
                              Tolerance(a.limit_angle, a.limit_length))
    ev = pipeline.Evaluation(traj, rec, result, run_verdict(scenario.robot_def, traj, result, a), {})
    pipeline.write_outputs(scenario, ev, tmp_path / "out", video=False)
    with np.load(tmp_path / "out" / "timeseries.npz") as saved:
        assert np.array_equal(saved["t"], traj.t[rec.kept])
        assert np.array_equal(saved["path_deviation"], result.series["path_deviation"])


def test_a_closed_loop_run_whose_last_window_is_its_last_sample_keeps_its_last_command():
    """A closed loop at stride 20 whose last window holds only the run's last sample (48,001 samples, settle 0):
    the last sample's command (the step before's, repeated) is kept, as the stride-1 run has it, though the rows
    of that step's window were let go (Rows.drop)."""
    raw = yaml.safe_load(scenario_file("spherical_arm", "case1").read_text())
    raw["timing"] = {**raw["timing"], "duration": 47.5, "hold": 0.5}
    raw["control"] = {"controller": "computed_torque"}
    runs = {}
    for k in (1, 20):
        raw["sim"] = {"settle": 0.0, "record_every": k}
        runs[k] = simbench.evaluate(parse_scenario(raw, "case1", default_name="case1"))
    n = runs[1].recording.t.size
    window = windowed.window_size(runs[1].trajectory.dt, n)
    assert (n - 1) % window == 0
    assert runs[1].recording.ctrl[-1].any()
    _same_at_the_kept_rows(runs[20], runs[1], 20)


def test_a_run_analysed_as_it_is_simulated_fails_with_the_kept_rows_before_the_failure(monkeypatch, tmp_path):
    """A bad command at sample 2500, after two windows were analysed and let go: the error's recording and plan
    are the kept rows before it, as the same failure recorded whole has them at those rows."""
    scenario = shipped("spherical_arm", "case1", duration=4.0)
    plant, traj = planned(scenario, "torque")
    window = _windows_of_a_block(monkeypatch, traj.dt) // 2
    monkeypatch.setattr(stepping, "CHUNK", 97)  # windows are analysed as the stepper's chunks come in
    a = scenario.analysis
    near, margin = Tolerance(a.near_angle, a.near_length), Tolerance(a.limit_angle, a.limit_length)
    caught = {}
    for at in (10, 2500):  # before the first kept row after row 0, and after two windows
        for k in (1, 20):
            analyser = analysis.Analyser(scenario.robot_def, traj, near, margin, window) if k > 1 else None
            with pytest.raises(ControlError) as err:
                simulate(plant, traj, Scripted(lambda nu: np.full(nu, np.nan), at=at), settle=0.05, record_every=k,
                         analyser=analyser)
            caught[at, k] = err.value
            pipeline._write_failure(scenario, err.value, tmp_path / f"{at}_{k}", pipeline._Stopwatch())
            report = json.loads((tmp_path / f"{at}_{k}" / "report.json").read_text())
            assert (report["samples"], report["timestep"]) == (at, traj.dt), (at, k)
            with np.load(tmp_path / f"{at}_{k}" / "timeseries.npz") as saved:
                assert np.array_equal(saved["t"], traj.t[np.arange(0, at, k)])
    whole, thin = caught[2500, 1], caught[2500, 20]
    rows = np.arange(0, 2500, 20)
    assert 2500 > 2 * window and analyser.samples >= 2 * window and thin.t == whole.t
    assert thin.recording.kept is None
    for column in _HEAVY + _EVERY_ROW:
        assert np.array_equal(getattr(thin.recording, column), getattr(whole.recording, column)[rows]), column
    assert np.array_equal(thin.trajectory.q_ref, traj.q_ref[rows])


def test_a_streamed_run_keeps_its_plan_whole_as_its_feedback_revised_it(monkeypatch):
    """A streamed RSMG run (stride 10, windows of a path-search block) revises its plan in place and lets none of it
    go: after the run every row of it is the one a run recorded whole commanded (its copies of the revised
    references), and the two runs' recordings are the same at the kept rows, bit for bit."""
    scenario = _strided("rsmg", "three_turns", 10)
    plant, traj = planned(scenario)
    _windows_of_a_block(monkeypatch, traj.dt)
    a = scenario.analysis
    near, margin = Tolerance(a.near_angle, a.near_length), Tolerance(a.limit_angle, a.limit_length)
    rec = simulate(plant, traj, Servo(), record_every=10, revise_in_place=True,
                   analyser=analysis.Analyser(scenario.robot_def, traj, near, margin))
    whole = simulate(plant, planned(scenario)[1], Servo())
    assert whole.q_ref is not None  # the feedback revised the references
    assert np.array_equal(traj.q_ref, whole.q_ref) and np.array_equal(traj.qd_ref, whole.qd_ref)
    rows = _rows(len(whole.t), 10)
    assert np.array_equal(rec.qpos, whole.qpos[rows]) and np.array_equal(rec.ctrl, whole.ctrl[rows])


def test_a_streamed_run_steps_on_the_chunks_of_the_run_recorded_whole(monkeypatch):
    """MuJoCo's non-fatal warnings are read and stamped at the end of each chunk the stepper hands to
    mujoco.rollout: a strided run analysed as it is simulated (windows of a path-search block, several to a chunk
    and across chunk edges) steps on the same chunks as the run recorded whole, so that its warnings are the
    whole run's; the windows are analysed as the chunks come in."""
    chunks = {}
    real = stepping.rollout

    class Counted:
        @staticmethod
        def rollout(model, data, initial, control, **kw):
            chunks[key].append(control.shape[1])
            return real.rollout(model, data, initial, control, **kw)

    monkeypatch.setattr(stepping, "rollout", Counted)
    dt = simbench.load_scenario(scenario_file("rsmg", "three_turns")).sim.timestep
    _windows_of_a_block(monkeypatch, dt or 1e-3)
    for key in (1, 10):
        chunks[key] = []
        simbench.evaluate(_strided("rsmg", "three_turns", key))
    assert len(chunks[1]) > 8 and chunks[10] == chunks[1]
