"""RSMG: arm kinematics (IK, DK, Jacobians), the round-robin schedule, and the switched welds in physics."""

import copy

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import simbench
from simbench.api.trajectory import Switch
from simbench.core.errors import RunError
from simbench.core.plant import Plant
from simbench.physics.switches import apply_switch
from simbench.planners import round_robin
from simbench.planners.round_robin.feedback import EASE
from simbench.planners.round_robin.schedule import gammas
from simbench.robots import rsmg as S
from tests.conftest import scenario_file

V = Rotation.random(3000, random_state=0).as_matrix()[:, :, 0]  # unit vectors all over the sphere


def matrices(quat: np.ndarray) -> np.ndarray:
    """Rotation matrices of MuJoCo's w x y z quaternions, by SciPy (not simbench's own conversion)."""
    return Rotation.from_quat(quat[:, [1, 2, 3, 0]]).as_matrix()


@pytest.mark.parametrize("arm", range(S.ARMS))
def test_ik_reaches_the_em_axis_within_the_link_constraints(arm):
    theta, gamma = S.ik(arm, V)
    ok = ~np.isnan(gamma)
    assert ok.mean() > 0.85  # all directions within ALPHA + BETA = 140 deg of u_i
    reach = np.degrees(np.arccos(V @ S.U[arm]))
    assert np.all(ok[reach < 139]) and not ok[reach > 141].any()
    assert np.abs(S.em_axis(arm, theta[ok], gamma[ok]) - V[ok]).max() < 1e-12
    w = S.upper_axis(arm, theta[ok])
    assert np.allclose(w @ S.U[arm], np.cos(S.ALPHA))  # eq. 10
    assert np.allclose(np.einsum("ij,ij->i", w, V[ok]), np.cos(S.BETA))  # eq. 11
    assert np.all((gamma[ok] >= 0) & (gamma[ok] <= np.pi))


def test_dk_recovers_the_rotor_orientation_from_three_or_four_arms():
    for r in Rotation.random(50, random_state=1).as_matrix():
        for arms in ([0, 1, 2, 3], [0, 2, 3], [1, 2, 3]):
            points = np.array([S.POINTS[i, (i + 1) % 3] for i in arms])
            solved = [S.ik(i, (r @ p)[None]) for i, p in zip(arms, points)]
            if any(np.isnan(g[0]) for _, g in solved):
                continue
            theta, gamma = (np.array([x[0] for x in pair]) for pair in zip(*solved))
            assert np.abs(S.dk(arms, theta, gamma, points) - r).max() < 1e-9


def test_jacobian_rows_relate_rotor_rate_and_base_rates():
    """A omega + B theta_dot = 0 (eq. 33), each arm holding its point while the rotor turns."""
    rng = np.random.default_rng(2)
    for r in Rotation.random(30, random_state=3).as_matrix():
        omega = rng.normal(size=3)
        h = 1e-6
        step = Rotation.from_rotvec(omega * h).as_matrix()
        for arm in range(S.ARMS):
            p = S.POINTS[arm, 0]
            th0, g0 = S.ik(arm, (r @ p)[None])
            th1, _ = S.ik(arm, (step @ r @ p)[None])
            if np.isnan(g0[0]) or not 0.2 < g0[0] < np.pi - 0.2:
                continue
            a, b = S.jacobian_rows(arm, th0, g0)
            theta_dot = np.angle(np.exp(1j * (th1 - th0)))[0] / h
            assert a[0] @ omega + b[0] * theta_dot == pytest.approx(0.0, abs=1e-4)


def test_type_a_measure_vanishes_only_when_the_rows_lose_rank():
    rng = np.random.default_rng(4)
    rows = rng.normal(size=(200, 4, 3))
    engaged = np.ones((200, 4), bool)
    assert np.all(S.type_a_measure(rows, engaged) > 0)
    flat = rows.copy()
    flat[:, :, 2] = 0.0  # all four rows in one plane: rank 2
    assert np.allclose(S.type_a_measure(flat, engaged), 0.0)
    three = engaged.copy()
    three[:, 3] = False  # one arm free: only the minor of the other three counts
    assert np.allclose(S.type_a_measure(rows, three), np.abs(np.linalg.det(rows[:, :3])))


def test_model_em_tips_follow_the_arm_kinematics():
    plant = Plant.load(S.ROBOT)
    model, data = plant.model, mujoco.MjData(plant.model)
    rng = np.random.default_rng(5)
    for _ in range(50):
        q = rng.uniform(-np.pi, np.pi, 8)
        data.qpos[:] = model.qpos0
        data.qpos[plant.qpos_adr] = q
        mujoco.mj_kinematics(model, data)
        for arm in range(S.ARMS):
            expected = S.RADIUS * S.em_axis(arm, q[arm], q[S.ARMS + arm])
            assert np.abs(data.site(f"em{arm + 1}_tip").xpos - expected).max() < 1e-12


def test_schedule_keeps_three_gripping_in_round_robin_order(evaluated):
    scenario, ev = evaluated("rsmg", "tumble")
    engaged = ev.trajectory.series["engaged_ref"]
    assert engaged.sum(axis=1).min() >= 3
    grips = [w for w in ev.trajectory.switches if w.active and w.detail["from_point"]]
    assert grips
    for w in grips:
        order = "abc"
        gap = (order.index(w.detail["to_point"]) - order.index(w.detail["from_point"])) % 3
        assert gap in (1, 2)  # the next candidate, or the one after if the next is out of the band
    # The planned gammas of gripping arms keep the band with the margin.
    gamma = ev.trajectory.q_ref[:, S.ARMS:]
    margin = scenario.task.gamma_margin
    assert gamma[engaged].min() > S.GAMMA_BAND[0] + margin - 1e-9
    assert gamma[engaged].max() < S.GAMMA_BAND[1] - margin + 1e-9
    # While an arm swings, the three holding it keep |det A| (eq. 46's measure, from the planned joints) above the
    # schedule's floor, far from the paper's 0.01.
    theta = ev.trajectory.q_ref[:, :S.ARMS]
    rows = np.stack([S.jacobian_rows(i, theta[:, i], gamma[:, i])[0] for i in range(S.ARMS)], axis=1)
    three = engaged.sum(axis=1) == 3
    assert three.any() and S.type_a_measure(rows, engaged)[three].min() >= scenario.task.det_a_min - 1e-3
    # Swings are smooth: no reference steps between samples.
    assert np.abs(np.diff(ev.trajectory.q_ref, axis=0)).max() < 0.02


def test_three_turns_are_scheduled_at_every_speed_the_swings_allow():
    """From 6 to 15 s for three turns (the sweep sweeps/rsmg_speed.yaml, without physics): three arms grip at
    every instant, each on a point inside the band. In 5 s the band's stretches on arm 2's points are shorter than
    a swing and its approach allow: a RunError naming the time and the arm; without the approach, 5 s works."""
    base = simbench.load_scenario(scenario_file("rsmg", "three_turns"))
    for duration in range(6, 16):
        sc = base.model_copy(update={"timing": base.timing.model_copy(update={"duration": float(duration)})})
        traj = round_robin.PLANNER.plan(sc, S.ROBOT, 0.001)
        engaged = traj.series["engaged_ref"]
        assert engaged.sum(axis=1).min() >= 3, duration
        gamma = traj.q_ref[:, S.ARMS:][engaged]
        margin = sc.task.gamma_margin
        assert S.GAMMA_BAND[0] + margin - 1e-9 < gamma.min() and gamma.max() < S.GAMMA_BAND[1] - margin + 1e-9
    fast = base.model_copy(update={"timing": base.timing.model_copy(update={"duration": 5.0})})
    with pytest.raises(RunError, match=r"at t = 1\.\d+ s arm 2 has no next contact point"):
        round_robin.PLANNER.plan(fast, S.ROBOT, 0.001)
    direct = fast.model_copy(update={"task": fast.task.model_copy(update={"approach_time": 0.0})})
    assert round_robin.PLANNER.plan(direct, S.ROBOT, 0.001).series["engaged_ref"].sum(axis=1).min() >= 3


def test_control_samples_past_the_schedules_end_hold_the_last_reference():
    """control_grid rounds the count of samples, so with a control step that does not divide duration + hold the
    last sample lies up to half a step past the schedule's end: there every arm keeps its last reference (the
    rotor rests through the hold) instead of having none (before: NaN, refused as a plan without a finite
    reference)."""
    base = simbench.load_scenario(scenario_file("rsmg", "three_turns"))
    for dt, duration in ((0.003, 6.7647), (0.002, 7.0013), (0.007, 9.304)):
        sc = base.model_copy(update={"timing": base.timing.model_copy(update={"duration": duration})})
        traj = round_robin.PLANNER.plan(sc, S.ROBOT, dt)
        assert traj.t[-1] > duration + sc.timing.hold, dt
        assert np.isfinite(traj.q_ref).all() and np.isfinite(traj.qd_ref).all(), dt
        assert np.array_equal(traj.q_ref[-1], traj.q_ref[-2]), dt


def test_impossible_band_is_a_run_error():
    task = round_robin.Task.model_validate({"motion": {"kind": "turns", "axis": [1, 0, 0], "turns": 2},
                                            "gamma_margin": np.deg2rad(75)})
    law_grid = np.linspace(0, 1, 400)
    _, gamma = gammas(task.motion.orientation(law_grid))
    firm = np.broadcast_to(S.U[:, None, None, :], gamma.shape + (3,))  # rows of A far from rank loss
    with pytest.raises(RunError, match="contact point"):
        round_robin.schedule(gamma, firm, task, 60)


@pytest.mark.parametrize("name", ["three_turns", "tumble"])
def test_physics_meets_the_round_robin_claims(evaluated, name):
    _, ev = evaluated("rsmg", name)
    extra, series = ev.analysis.extra, ev.analysis.series
    assert np.rad2deg(extra["rotor_error_max"]) < 2.0
    assert extra["closure_error_max"] < 2e-4  # m: each gripping EM stays where it gripped the rotor
    assert series["engaged"].sum(axis=1).min() >= 3 and extra["fewest_gripping"] >= 3
    held = series["gamma"][series["engaged"]]
    assert S.GAMMA_BAND[0] < held.min() and held.max() < S.GAMMA_BAND[1]
    assert not [e for e in ev.analysis.singularity_events if e["kind"] == "typeA"]
    switches = extra["switch_events"]
    assert len(switches) >= 5
    for e in switches:
        assert {"arm", "from_point", "to_point"} <= set(e["detail"]) and e["t_start"] < e["t_end"]
        assert e["detail"]["contact_jump"] < 1e-3
    n = ev.recording.t.size
    assert series["gamma"].shape == (n, 4) and series["engaged"].dtype == bool
    assert ev.trajectory.series["rotor_quat_ref"].shape == (n, 4) and series["rotor_quat"].shape == (n, 4)
    assert ev.recording.warnings == ()


def test_dk_of_the_simulated_joints_is_the_simulated_rotor(evaluated):
    """Before the first re-grip every arm holds its planned point exactly, so eq. 32 on the simulated theta and
    gamma gives the rotor orientation MuJoCo simulates."""
    _, ev = evaluated("rsmg", "tumble")
    first = min(w.t for w in ev.trajectory.switches if not w.active)
    holds = {w.detail["arm"] - 1: "abc".index(w.detail["to_point"]) for w in ev.trajectory.switches if w.t == 0}
    arms = sorted(holds)
    points = np.array([S.POINTS[i, holds[i]] for i in arms])
    rot = matrices(ev.recording.sensors["rotor_quat"])
    for k in np.flatnonzero(ev.recording.t < first)[::200]:
        q = ev.recording.q[k]
        solved = S.dk(arms, q[arms], q[[S.ARMS + i for i in arms]], points)
        u, _, vt = np.linalg.svd(solved)
        angle = np.arccos(np.clip((np.trace((u @ vt).T @ rot[k]) - 1) / 2, -1, 1))
        assert np.rad2deg(angle) < 0.05


def test_with_every_weld_off_the_rotor_coasts_freely():
    """No hidden constraint: released, the rotor keeps its spin (a sphere, so its angular velocity is conserved)
    while the arms move."""
    plant = Plant.load(S.ROBOT)
    model = copy.copy(plant.model)
    model.opt.gravity[:] = 0
    rotor_dofs = slice(model.joint("rotor").dofadr[0], model.joint("rotor").dofadr[0] + 3)
    model.dof_damping[rotor_dofs] = 0.0
    data = mujoco.MjData(model)
    data.qvel[rotor_dofs] = [1.0, -2.0, 0.5]
    assert not data.eq_active.any()
    for k in range(1000):
        data.ctrl[:4] = 0.8 * np.sin(0.01 * k + np.arange(4))
        mujoco.mj_step(model, data)
    assert np.allclose(data.qvel[rotor_dofs], [1.0, -2.0, 0.5], atol=1e-9)


def grip_jump(update: bool) -> float:
    """Turn arm 1's weld on with the rotor turned 20 deg from where the weld's stored pose has it; return the EM
    tip's jump (second difference of its position) across the switch."""
    plant = Plant.load(S.ROBOT)
    model = copy.copy(plant.model)
    data = mujoco.MjData(model)
    theta, gamma = S.ik(0, S.POINTS[0, 0][None])
    data.qpos[plant.qpos_adr[[0, 4]]] = [theta[0], gamma[0]]
    adr = model.joint("rotor").qposadr[0]
    data.qpos[adr:adr + 4] = Rotation.from_rotvec([0, 0, np.deg2rad(20)]).as_quat()[[3, 0, 1, 2]]
    data.ctrl[plant.actuators] = data.qpos[plant.qpos_adr]
    mujoco.mj_forward(model, data)
    tips = [data.site("em1_tip").xpos.copy()]
    mujoco.mj_step(model, data)
    tips.append(data.site("em1_tip").xpos.copy())
    if update:
        apply_switch(model, data, Switch(t=0.0, equality="grip1", active=True, servo_group=1))
    else:
        data.eq_active[model.equality("grip1").id] = 1
    mujoco.mj_step(model, data)
    mujoco.mj_kinematics(model, data)
    tips.append(data.site("em1_tip").xpos.copy())
    return float(np.linalg.norm(tips[2] - 2 * tips[1] + tips[0]))


def test_switching_a_weld_on_without_the_pose_update_snaps():
    assert grip_jump(update=True) < 1e-6
    assert grip_jump(update=False) > 1e-3


def test_grip_feedback_re_solves_each_hold_for_the_point_really_gripped(evaluated):
    """With the feedback (the default), from each grip on, the arm's commanded EM axis is the commanded rotor
    orientation applied to the point the EM really gripped (read from the recording at the grip: the tip in the
    rotor's frame), once the change has eased in; and the rotor ends on its command. Open loop, the same tumble
    ends with the grips' offsets held in: the rotor stays off by more."""
    scenario, ev = evaluated("rsmg", "tumble")
    traj, rec = ev.trajectory, ev.recording
    rot = matrices(rec.sensors["rotor_quat"])
    ref = matrices(traj.series["rotor_quat_ref"])
    ease = int(round(EASE / traj.dt))
    grips = [w for w in traj.switches if w.active and w.t > 0]
    assert grips
    for w in grips:
        arm, k = w.detail["arm"] - 1, int(round(w.t / traj.dt))
        release = min([int(round(v.t / traj.dt)) for v in traj.switches
                       if not v.active and v.detail["arm"] == arm + 1 and v.t > w.t], default=traj.t.size)
        tip = rec.sensors[f"em{arm + 1}_tip"][k]
        point = rot[k].T @ tip / np.linalg.norm(tip)
        rows = np.arange(k + ease, release)
        axis = S.em_axis(arm, traj.q_ref[rows, arm], traj.q_ref[rows, S.ARMS + arm])
        assert np.abs(axis - ref[rows] @ point).max() < 1e-9
    final = ev.analysis.series["rotor_error"][-1]
    assert final < np.deg2rad(0.01)
    open_loop = scenario.model_copy(update={"task": scenario.task.model_copy(update={"regrip_feedback": False})})
    drifted = simbench.evaluate(open_loop).analysis.series["rotor_error"][-1]
    assert drifted > 10 * final and drifted > np.deg2rad(0.1)


def test_the_type_a_measure_is_each_samples_own_however_the_samples_are_chunked(monkeypatch):
    """The measures build A a chunk of samples at a time (memory on long runs): on random joints and grips the
    type A measure equals the largest |3 x 3 minor| of A from jacobian_rows, sample by sample, for chunks smaller
    and larger than the run."""
    rng = np.random.default_rng(21)
    q = rng.uniform(-2 * np.pi, 2 * np.pi, (3001, 2 * S.ARMS))
    engaged = rng.random((3001, S.ARMS)) < 0.8
    rows = np.stack([S.jacobian_rows(arm, q[:, arm], q[:, S.ARMS + arm])[0] for arm in range(S.ARMS)], axis=1)
    want = np.zeros(len(q))
    for drop in range(S.ARMS):
        three = [arm for arm in range(S.ARMS) if arm != drop]
        det = np.abs(np.linalg.det(rows[:, three]))
        want = np.where(engaged[:, three].all(axis=1), np.maximum(want, det), want)
    for chunk in (1, 7, 1000, 1 << 16):
        monkeypatch.setattr(S, "CHUNK", chunk)
        assert np.allclose(S._type_a(q, engaged), want, rtol=0, atol=1e-14)
