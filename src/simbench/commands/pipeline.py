"""One run, end to end: plan, simulate, analyse, then write every output into a folder at once (simbench.core.atomic).

The run's cost is checked against the machine (simbench.core.budget) before anything big is allocated. A run whose
physics fails writes the report of the failure and the timeseries up to it.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, replace
from pathlib import Path

from simbench.analysis import Analyser, Analysis, analyse, plan_limit_events
from simbench.analysis.verdict import Verdict, plan_verdict, run_verdict
from simbench.api.trajectory import JointTrajectory
from simbench.core import budget, destination
from simbench.core.atomic import staged_folder
from simbench.core.errors import PhysicsError, TooSlow
from simbench.core.forked import forked
from simbench.core.plant import Plant
from simbench.outputs.page import run_page, write_page
from simbench.outputs.plot_formats import check_format
from simbench.outputs.plots import write_plots
from simbench.outputs.render import render_video
from simbench.outputs.report import build_failure_report, build_report, write_report, write_timeseries
from simbench.physics.fitting import fit
from simbench.physics.policy import refuse_code
from simbench.physics.sim import Recording, commanded, simulate
from simbench.physics.stepping import kept_rows
from simbench.robots import Tolerance
from simbench.scenario import Scenario, as_scenario


@dataclass(frozen=True)
class Evaluation:
    """A scenario planned, simulated and analysed, with its verdict, nothing written yet.

    Found from every sample; the plan, recording and series hold the kept rows (with `sim.record_every`, the
    control period is `recording.timestep`, not the thinned plan's dt).

    Attributes:
        trajectory: The plan.
        recording: The simulated run.
        analysis: Tracking, singularity and limit events, and per-sample series.
        verdict: The status (`ok`, `limits`, ...) and each promise broken.
        control: The controller, its actuation and its gains, as report.json gives them.
    """

    trajectory: JointTrajectory
    recording: Recording
    analysis: Analysis
    verdict: Verdict
    control: dict


@dataclass(frozen=True)
class Result:
    """A finished run: where its outputs are and what it found.

    Attributes:
        out: The output folder.
        report: report.json's contents.
        evaluation: The plan, the recording, the analysis and the verdict.
    """

    out: Path
    report: dict
    evaluation: Evaluation


# Who is told of each stage a run enters (a sweep's progress line), and the seconds a stage may take, per stage.
_LISTENER: ContextVar[Callable[[str], None] | None] = ContextVar("simbench_stage_listener", default=None)
_LIMITS: ContextVar[dict[str, float] | None] = ContextVar("simbench_stage_limits", default=None)
_AGAIN = 0.5  # s: how often a stage past its limit is cut again while it goes on


@contextmanager
def told(listener: Callable[[str], None]) -> Iterator[None]:
    """Within the block, `listener` is told the name of each stage a run enters (`load`, `plan`, `simulate`,
    `analyse`, ...): a sweep's or bench's progress line shows it."""
    token = _LISTENER.set(listener)
    try:
        yield
    finally:
        _LISTENER.reset(token)


@contextmanager
def limited(limits: dict[str, float] | None) -> Iterator[None]:
    """Within the block, a stage named in `limits` (`plan`: seconds) that runs longer than its seconds is cut by
    TooSlow: on the main thread of a system with SIGALRM (Linux, macOS) alone, where a signal can cut it."""
    token = _LIMITS.set(limits)
    try:
        yield
    finally:
        _LIMITS.reset(token)


_DOING = {"load": "loading", "plan": "planning", "simulate": "simulating", "analyse": "analysing"}


def doing(stage: str) -> str:
    """A stage's name as a progress line says it (`plan` -> `planning`)."""
    return _DOING.get(stage, stage)


@contextmanager
def _limited(name: str, seconds: float | None) -> Iterator[None]:
    """Stage `name` cut by TooSlow past `seconds` (SIGALRM, the previous handler and timer restored after)."""
    if seconds is None or not hasattr(signal, "SIGALRM") or threading.current_thread() is not threading.main_thread():
        yield
        return

    armed = [True]  # cleared first thing once the stage ends: an alarm that comes after cuts nothing

    def cut(signum, frame):
        if armed[0]:
            raise TooSlow(f"{doing(name)} passed the {seconds:g} s it may take")

    previous = signal.signal(signal.SIGALRM, cut)
    try:  # (the timer set inside: an alarm due at once is still the stage's, and the timer is then stopped)
        signal.setitimer(signal.ITIMER_REAL, seconds, _AGAIN)  # again and again: a library may swallow one
        yield
    finally:
        armed[0] = False
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


class _Stopwatch:
    """Wall time per stage; each stage told to the listener and held to its limit (`watched`)."""

    def __init__(self):
        self.times: dict[str, float] = {}

    @contextmanager
    def stage(self, name: str):
        listener = _LISTENER.get()
        if listener is not None:
            listener(name)
        start = time.perf_counter()
        try:
            with _limited(name, (_LIMITS.get() or {}).get(name)):
                yield
        finally:
            self.times[name] = self.times.get(name, 0.0) + time.perf_counter() - start

    def move(self, seconds: float, source: str, target: str) -> None:
        """Book `seconds` of stage `source` to stage `target` (the analysis done while a run is simulated)."""
        self.times[source] = self.times.get(source, 0.0) - seconds
        self.times[target] = self.times.get(target, 0.0) + seconds

    def summary(self) -> dict[str, float]:
        """Seconds per stage and their total, as report.json gives them."""
        wall = {k: round(v, 4) for k, v in self.times.items()}
        wall["total"] = round(sum(self.times.values()), 4)
        return wall


def evaluate(scenario: Scenario | str | os.PathLike, progress: bool = False, allow_code: bool = False) -> Evaluation:
    """Plan, simulate and analyse a scenario, writing nothing.

    Args:
        scenario: A Scenario, or the path of a scenario file.
        progress: Whether to show progress bars.
        allow_code: Whether a `policy` controller may import the Python its scenario names (`module:function`).

    Returns:
        The evaluation.

    Raises:
        ScenarioError: The scenario is bad input, or beyond what the machine can give (the run's budget).
        RunError: The run failed; PhysicsError where the physics did.
    """
    scenario = as_scenario(scenario, "simbench.evaluate")
    _afford(scenario, progress)
    return _evaluate(scenario, progress, allow_code=allow_code)


def _afford(scenario: Scenario, progress: bool, video: bool = False, outputs: bool = False,
            out: Path | None = None) -> budget.Estimate:
    """The run's estimate, checked against the machine; its cost on stderr if large and `progress` is on."""
    est = budget.check(scenario, video=video, outputs=outputs, out=out)
    if progress:
        budget.announce(est)
    return est


def _evaluate(scenario: Scenario, progress: bool = False, watch: _Stopwatch | None = None,
              allow_code: bool = False) -> Evaluation:
    """evaluate() once the budget is checked."""
    watch = watch or _Stopwatch()
    robot = scenario.robot_def
    with watch.stage("load"):
        sim = scenario.sim
        refuse_code(scenario, allow_code)  # before the controller imports anything
        controller = scenario.controller_def.from_scenario(scenario)
        plant = Plant.load(robot, sim.timestep, sim.kp, sim.kv, sim.force_limits, sim.gravity_compensation,
                           controller.actuation)
    with watch.stage("plan"):
        traj = scenario.planner_def.plan(scenario, robot, float(plant.model.opt.timestep))
        plant, traj, design = fit(scenario, plant, traj)
    a = scenario.analysis
    near, margin = Tolerance(a.near_angle, a.near_length), Tolerance(a.limit_angle, a.limit_length)
    # a strided run is analysed as it is simulated where the robot's summary comes a window at a time
    streamed = sim.record_every > 1 and robot.streams
    analyser = Analyser(robot, traj, near, margin, scenario=scenario) if streamed else None
    with watch.stage("simulate"):
        rec = simulate(plant, traj, controller, settle=sim.settle, progress=progress, record_every=sim.record_every,
                       revise_in_place=True,  # the plan as planned is not needed after the run
                       analyser=analyser)
        traj = commanded(traj, rec) if analyser is None else replace(traj, feedback=None)  # the feedback is spent
        control = {"controller": controller.name, "actuation": controller.actuation, **controller.gains(),
                   **({"servo_design": list(design)} if design else {})}
        del controller  # with its commands (the servo's: N x nu): `rec` has what the outputs need of them
    if analyser is not None:
        watch.move(analyser.seconds, "simulate", "analyse")
    with watch.stage("analyse"):
        result = analyser.finish() if analyser else analyse(robot, traj, rec, near, margin, scenario=scenario)
        found = run_verdict(robot, traj, result, a, scenario.expect)
    if sim.record_every > 1:  # the analysis has read every sample: the outputs show the kept ones
        traj = traj.rows(kept_rows(len(traj.t), sim.record_every)) if analyser is None else analyser.plan()
        rec = rec.thinned()  # as it is, where it was analysed as it was simulated
    return Evaluation(traj, rec, result, found, control)


def check_plan(scenario: Scenario) -> tuple[JointTrajectory, Verdict]:
    """Plan without simulating, and the verdict on what the plan alone breaks (`simbench validate`)."""
    budget.check(scenario)
    robot = scenario.robot_def
    plant = Plant.load(robot, scenario.sim.timestep)
    traj = scenario.planner_def.plan(scenario, robot, float(plant.model.opt.timestep))
    traj = fit(scenario, plant, traj)[1]
    return traj, plan_verdict(robot, traj, plan_limit_events(robot, traj), scenario.expect)


def evaluate_report(scenario: Scenario, allow_code: bool = False) -> dict:
    """Plan, simulate and analyse; the report.json document, with nothing written (what a sweep keeps)."""
    watch = _Stopwatch()
    _afford(scenario, progress=False)
    ev = _evaluate(scenario, watch=watch, allow_code=allow_code)
    return build_report(scenario, ev, watch.summary(), {}, scenario.source)


def run(scenario: Scenario | str | os.PathLike, out: str | Path | None = None, video: bool = True,
        progress: bool = False, force: bool = False, allow_code: bool = False, plot_format: str = "png") -> Result:
    """Plan, simulate and analyse a scenario, and write its outputs.

    The outputs are report.json, timeseries.npz, plots/, index.html and (unless `video` is false) video.mp4.

    Args:
        scenario: A Scenario, or the path of a scenario file.
        out: The output folder, which must be empty unless `force`; None: `renders/<name>/`.
        video: Whether to render the video.
        progress: Whether to show progress bars.
        force: Whether to replace what the folder holds.
        allow_code: As `evaluate`'s.
        plot_format: The plots' format: `png`, `svg` or `pdf`.

    Returns:
        The result: where the outputs are, and what they say.

    Raises:
        ScenarioError: The scenario or the output folder is bad input, or the run is beyond the machine.
        PhysicsError: The physics failed; the report and the timeseries so far are written first.
        RunError: The run failed otherwise (the task cannot be planned, say).
        OutputError: Writing the outputs failed (a full disk, say).
    """
    scenario = as_scenario(scenario, "simbench.run")
    check_format(plot_format, "simbench.run")
    out = destination.followed(Path(out) if out is not None else Path("renders") / scenario.name)
    _afford(scenario, progress, video=video, outputs=True, out=out)  # before anything is written
    inputs = [Path(scenario.source)] if scenario.source and Path(scenario.source).is_file() else []
    with destination.locked(out):
        destination.check(out, inputs, force)
        return _run(scenario, out, video, progress, allow_code, plot_format)


def _run(scenario: Scenario, out: Path, video: bool, progress: bool, allow_code: bool, plot_format: str) -> Result:
    """run() once `out` is locked and checked."""
    watch = _Stopwatch()
    try:
        ev = _evaluate(scenario, progress, watch, allow_code)
    except PhysicsError as err:
        _write_failure(scenario, err, out, watch)
        raise
    return write_outputs(scenario, ev, out, video, watch, plot_format)


def write_outputs(scenario: Scenario, ev: Evaluation, out: Path, video: bool = True,
                  watch: _Stopwatch | None = None, plot_format: str = "png") -> Result:
    """Write the outputs of an evaluated run into `out` at once (locking and checking `out` is the caller's). The
    plots are drawn in a forked process while the video renders; the `plots` stage is the wait for them."""
    check_format(plot_format, "simbench.write_outputs")
    watch = watch or _Stopwatch()
    robot = scenario.robot_def
    traj, rec = thinned(ev.trajectory, ev.recording)
    result = ev.analysis
    with staged_folder(out) as tmp, forked(write_plots, robot, traj, rec, result, tmp / "plots", plot_format,
                                           doing="drawing the plots") as plots:
        outputs = {"report": "report.json", "timeseries": "timeseries.npz", "page": "index.html"}
        if video:
            r = scenario.render
            decorations = scenario.planner_def.decorations(scenario)
            with watch.stage("video"):
                outputs["video"] = "video.mp4"
                outputs["video_info"] = render_video(robot.scene, rec, traj.tool_ref, tmp / "video.mp4",
                                                     width=r.width, height=r.height, fps=r.fps, camera=r.camera,
                                                     quality=r.quality, trace=r.trace, decorations=decorations,
                                                     paint=robot.paint)
        with watch.stage("write"):
            write_timeseries(robot, traj, rec, result, tmp / "timeseries.npz")
        with watch.stage("plots"):
            outputs["plots"] = [f"plots/{name}" for name in plots()]
        report = build_report(scenario, ev, watch.summary(), outputs, scenario.source)
        write_report(report, tmp / "report.json")
        write_page(tmp, run_page(tmp, report))
    return Result(out=out, report=report, evaluation=ev)


def thinned(traj: JointTrajectory, rec: Recording) -> tuple[JointTrajectory, Recording]:
    """The plan and the recording at the recording's kept rows: what the outputs of a strided run show."""
    return (traj, rec) if rec.kept is None else (traj.rows(rec.kept), rec.thinned())


def _write_failure(scenario: Scenario, err: PhysicsError, out: Path, watch: _Stopwatch) -> None:
    """The outputs of a run whose physics failed: report.json with the failure, and the timeseries up to it."""
    with staged_folder(out) as tmp:
        outputs = {"report": "report.json", "page": "index.html"}
        if err.recording is not None:
            outputs["timeseries"] = "timeseries.npz"
            traj, rec = thinned(err.trajectory, err.recording)
            write_timeseries(scenario.robot_def, traj, rec, None, tmp / "timeseries.npz")
        report = build_failure_report(scenario, err, watch.summary(), outputs, scenario.source)
        write_report(report, tmp / "report.json")
        write_page(tmp, run_page(tmp, report))
