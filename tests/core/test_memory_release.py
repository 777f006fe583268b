"""What a run holds once it has simulated, and the analysis done a chunk of samples at a time to keep a long run's
temporaries small: the same numbers as computed whole (benchmarks/bench_soak.py measures the peak memory)."""

import gc
import tracemalloc
import weakref

import numpy as np
import yaml

import simbench
from simbench import analysis
from simbench.core import windowed
from simbench.core.errors import RunError
from simbench.core.plant import Plant
from simbench.maths.rotations import quat_to_matrix, rotation_angle
from simbench.physics import sim
from simbench.planners.round_robin import feedback, paths
from simbench.planners.round_robin.paths import Orientations
from simbench.robots import Tolerance, rsmg_outputs
from simbench.robots import rsmg as S
from simbench.scenario import parse_scenario
from tests.conftest import scenario_file
from tests.physics.test_sim import planned, shipped


def test_a_revised_plan_comes_without_its_spent_feedback_and_the_forces_are_views_of_the_sensors(evaluated):
    """The RSMG's grip feedback revises the references: the evaluated plan has the revised ones and no feedback
    (which holds the plan's own arrays); the actuator forces are a view of the recorded sensor rows, not a copy."""
    _, ev = evaluated("rsmg", "tumble")
    rec = ev.recording
    assert rec.q_ref is not None and ev.trajectory.q_ref is rec.q_ref
    assert ev.trajectory.feedback is None
    assert rec.force.base is not None and rec.force.base is rec.tool.base  # both views of the sensor rows
    assert sim._columns(np.array([3, 4, 5])) == slice(3, 6)
    assert np.array_equal(sim._columns(np.array([3, 5])), [3, 5])


def test_revising_the_plan_in_place_steps_as_revising_copies_of_it():
    """simulate(..., revise_in_place=True), as the pipeline asks, revises the plan's own references instead of
    copies: the same recording and the same commanded references, bit for bit, while the plan's own references
    are left as planned by default. The RSMG's feedback reads the plan's references as it re-solves each grip:
    the same results show that no change touched a row a later change read."""
    scenario = simbench.load_scenario(scenario_file("rsmg", "tumble"))
    robot = scenario.robot_def
    plant = Plant.load(robot, scenario.sim.timestep)
    dt = float(plant.model.opt.timestep)
    copied_plan, own_plan = (scenario.planner_def.plan(scenario, robot, dt) for _ in range(2))
    planned = copied_plan.q_ref.copy()
    copied = sim.simulate(plant, copied_plan, settle=scenario.sim.settle)
    own = sim.simulate(plant, own_plan, settle=scenario.sim.settle, revise_in_place=True)
    assert np.array_equal(copied_plan.q_ref, planned)  # left as planned
    assert copied.q_ref is not None and not np.array_equal(copied.q_ref, planned)  # the feedback revised them
    assert own.q_ref is own_plan.q_ref and own.qd_ref is own_plan.qd_ref
    for name in ("q_ref", "qd_ref", "qpos", "q", "ctrl", "tool", "force"):
        assert np.array_equal(getattr(own, name), getattr(copied, name)), name


def _random_rsmg_task(rng: np.random.Generator) -> dict:
    """The shipped tumble's scenario with a random motion (turns or a tumble about random axes), swing and
    approach times, contact scheme, timestep and duration."""
    doc = yaml.safe_load(scenario_file("rsmg", "tumble").read_text())
    axis, other = (list(np.round(v / np.linalg.norm(v), 3)) for v in rng.normal(size=(2, 3)))
    doc["task"]["motion"] = ({"kind": "turns", "axis": axis, "turns": float(rng.uniform(0.5, 2.0))}
                             if rng.random() < 0.5 else
                             {"kind": "tumble", "spin_axis": axis, "spin_turns": float(rng.uniform(0.5, 2.0)),
                              "precession_axis": other, "precession_turns": float(rng.uniform(0.2, 1.0))})
    doc["task"]["swing_time"] = float(rng.choice([0.5, rng.uniform(0.3, 0.6)]))  # on the schedule's grid or off
    doc["task"]["approach_time"] = float(rng.choice([0.0, 0.002, 0.05, 0.1]))
    doc["task"]["contacts"] = str(rng.choice(["general", "fixed"]))
    doc["sim"] = {**doc.get("sim", {}), "timestep": float(rng.choice([0.001, 0.002, 0.003]))}
    doc["timing"]["duration"] = float(rng.uniform(6.0, 10.0))
    return doc


def test_revising_in_place_steps_as_revising_copies_on_random_rsmg_tasks():
    """The same on random motions, contact schemes, swing and approach times and timesteps (fixed seed): among them
    approaches of 0 and swings off the schedule's 5 ms grid or timesteps that do not divide it, where an arm's
    next grip comes before its swing's planned end (the change then ends at that grip). In place or on copies,
    the same commanded references and the same recording, bit for bit."""
    rng = np.random.default_rng(26)
    revised = 0
    for _ in range(16):
        scenario = parse_scenario(_random_rsmg_task(rng), "random", default_name="random")
        plant = Plant.load(scenario.robot_def, scenario.sim.timestep)
        dt = float(plant.model.opt.timestep)
        try:
            copied_plan, own_plan = (scenario.planner_def.plan(scenario, scenario.robot_def, dt) for _ in range(2))
        except RunError:
            continue  # a motion the arms cannot follow: refused before any simulation
        copied = sim.simulate(plant, copied_plan, settle=scenario.sim.settle)
        own = sim.simulate(plant, own_plan, settle=scenario.sim.settle, revise_in_place=True)
        revised += copied.q_ref is not None
        for name in ("q_ref", "qd_ref", "qpos", "q", "ctrl", "tool", "force"):
            assert np.array_equal(getattr(own, name), getattr(copied, name)), (scenario.task.motion, name)
    assert revised >= 8


def test_the_schedules_contacts_and_their_caches_are_freed_when_planning_returns(monkeypatch):
    """With general contacts, the schedule's contacts (their IK cache, the rotor's axes on the schedule grid) are
    freed as soon as the planner drops them, by reference counting alone: nothing the plan keeps refers to them,
    and no reference cycle holds them until the interpreter's collector comes by."""
    from simbench.planners.round_robin import planner

    doc = yaml.safe_load(scenario_file("rsmg", "tumble").read_text())
    doc["task"]["contacts"] = "general"
    scenario = parse_scenario(doc, "general", default_name="general")
    found = []
    schedule = planner.schedule_grips
    monkeypatch.setattr(planner, "schedule_grips", lambda *a: found.append(schedule(*a)) or found[-1])
    robot = scenario.robot_def
    dt = float(Plant.load(robot, scenario.sim.timestep).model.opt.timestep)
    gc.disable()
    try:
        traj = scenario.planner_def.plan(scenario, robot, dt)
        contacts = weakref.ref(found.pop().contacts)
        assert contacts() is None
    finally:
        gc.enable()
    assert len(traj.t) > 1


def test_a_streamed_runs_plan_is_freed_when_evaluate_returns(monkeypatch):
    """A strided RSMG run analysed as it is simulated: once evaluate returns, the plan's per-sample arrays are
    freed by reference counting alone (the outputs keep the plan at the kept rows, copies), with no reference cycle
    holding the run, and the plan with it, until the interpreter's collector comes by."""
    from simbench.planners.round_robin import planner

    doc = yaml.safe_load(scenario_file("rsmg", "tumble").read_text())
    doc["sim"] = {**doc.get("sim", {}), "record_every": 10}
    scenario = parse_scenario(doc, "strided", default_name="strided")
    planned = []
    plan = planner.RoundRobin.plan
    monkeypatch.setattr(planner.RoundRobin, "plan", lambda *a: planned.append(plan(*a)) or planned[-1])
    gc.disable()
    try:
        ev = simbench.evaluate(scenario)
        arrays = [weakref.ref(a) for a in (planned[0].q_ref, planned[0].qd_ref, planned[0].tool_ref)]
        planned.clear()
        assert [a() for a in arrays] == [None] * 3
    finally:
        gc.enable()
    assert len(ev.trajectory.t) == len(ev.recording.t)


def test_the_grip_feedback_finds_the_rotors_orientations_block_by_block_as_the_plan_has_them(monkeypatch):
    """The feedback finds the rotor's commanded orientations a block at a time as grips ask for them, dropping the
    blocks behind: the same numbers as all of them found at once, bit for bit, for rows asked for in time order
    and out of it, across blocks; and those of the plan's own rotor quaternions."""
    monkeypatch.setattr(paths, "BLOCK", 1000)  # the plan's own quaternions too, from 1,000 rows at a time
    scenario = simbench.load_scenario(scenario_file("rsmg", "tumble"))
    dt = float(Plant.load(scenario.robot_def, scenario.sim.timestep).model.opt.timestep)
    plan = scenario.planner_def.plan(scenario, scenario.robot_def, dt)
    motion, s = scenario.task.motion, plan.s
    every = motion.orientation(s)
    assert np.abs(every - quat_to_matrix(plan.series["rotor_quat_ref"])).max() < 1e-12
    rot = Orientations(motion, s)
    rng = np.random.default_rng(7)
    starts = np.sort(rng.integers(0, len(s) - 1, 30)).tolist() + rng.integers(0, len(s) - 1, 10).tolist()
    for a in starts:
        b = min(a + int(rng.integers(1, 4000)), len(s))
        assert np.array_equal(rot.rows(a, b), every[a:b])
        assert min(rot.blocks) == a // 1000  # the blocks behind are dropped


def test_the_grip_feedbacks_ik_found_block_by_block_is_that_of_every_row_at_once(monkeypatch):
    """The feedback solves a hold's IK a block of rows at a time (blocks of 1,000 here, from rows mid-block): the
    same numbers, bit for bit, as rsmg.ik of all the rows' orientations of the motion at once, across blocks, for
    random points (NaN where out of the arm's reach), and none for no rows."""
    monkeypatch.setattr(feedback, "BLOCK", 1000)
    scenario = simbench.load_scenario(scenario_file("rsmg", "tumble"))
    dt = float(Plant.load(scenario.robot_def, scenario.sim.timestep).model.opt.timestep)
    plan = scenario.planner_def.plan(scenario, scenario.robot_def, dt)
    assert isinstance(plan.feedback, feedback.RegripFeedback)
    motion, s = scenario.task.motion, plan.s
    rng = np.random.default_rng(11)
    for arm, a, length in [(0, 0, 1000), (1, 999, 2), (2, 1234, 3500), (3, 17, 4), (0, len(s) - 2500, 2500)]:
        point = rng.normal(size=3)
        point /= np.linalg.norm(point)
        truth = S.ik(arm, motion.orientation(s[a:a + length]) @ point)
        found = plan.feedback._ik(arm, point, a, a + length)
        assert all(np.array_equal(f, t, equal_nan=True) for f, t in zip(found, truth)), (arm, a, length)
    assert [len(x) for x in plan.feedback._ik(0, np.array([0.0, 0.0, 1.0]), 5, 5)] == [0, 0]


def test_the_rotor_and_closure_errors_are_each_samples_own_however_the_samples_are_chunked(evaluated, monkeypatch):
    """rsmg_outputs computes the rotor's error and the closure error a chunk of samples at a time: on a run with
    re-grips both equal those computed over every sample at once, bit for bit, for chunks smaller and larger than
    the run (grips inside a chunk and before it)."""
    _, ev = evaluated("rsmg", "tumble")
    traj, rec = ev.trajectory, ev.recording
    engaged = S.gripping(rec)
    rot = quat_to_matrix(rec.sensors["rotor_quat"])
    error = rotation_angle(quat_to_matrix(traj.series["rotor_quat_ref"]), rot)
    closure = np.zeros(rec.t.size)
    for arm in range(S.ARMS):
        on_rotor = np.einsum("nji,nj->ni", rot, rec.sensors[f"em{arm + 1}_tip"])
        grip = engaged[:, arm] & ~np.concatenate([[False], engaged[:-1, arm]])
        since = np.maximum.accumulate(np.where(grip, np.arange(rec.t.size), 0))
        drift = np.linalg.norm(on_rotor - on_rotor[since], axis=1)
        closure = np.maximum(closure, np.where(engaged[:, arm], drift, 0.0))
    assert closure.max() > 0
    for chunk in (7, 1000, 1 << 16):
        monkeypatch.setattr(rsmg_outputs, "CHUNK", chunk)
        got_error, got_closure = rsmg_outputs._rotor_errors(traj, rec, engaged, np.zeros((S.ARMS, 3)),
                                                               np.zeros(S.ARMS, bool))
        assert np.array_equal(got_error, error) and np.array_equal(got_closure, closure)


def _streamed_peak(duration: float, every: int) -> tuple[int, int]:
    """tracemalloc's peak of simulating the spherical arm's case1 for `duration` s at stride `every`, analysed as it
    is simulated (its plan made before), and its samples."""
    scenario = shipped("spherical_arm", "case1", duration=duration)
    plant, traj = planned(scenario)
    a = scenario.analysis
    analyser = analysis.Analyser(scenario.robot_def, traj, Tolerance(a.near_angle, a.near_length),
                                 Tolerance(a.limit_angle, a.limit_length))
    tracemalloc.start()
    try:
        sim.simulate(plant, traj, record_every=every, revise_in_place=True, analyser=analyser)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return peak, traj.t.size


def test_a_long_strided_run_holds_every_steps_readings_a_window_at_a_time():
    """A run analysed as it is simulated holds every step's sensors, joint positions and constraints in buffers of a
    window's size (simbench.core.buffers): its peak memory grows with the samples by what it keeps of them (the kept
    rows, the analysis' series at them), less than a sensor row a sample, where whole-run arrays would take more."""
    (short, n_short), (long, n_long) = (_streamed_peak(duration, 20) for duration in (40.0, 160.0))
    assert n_long - n_short > 3 * windowed.WINDOW
    sensor_row = 8 * Plant.load(shipped("spherical_arm", "case1").robot_def).model.nsensordata
    assert (long - short) / (n_long - n_short) < sensor_row, (short, long, sensor_row)
