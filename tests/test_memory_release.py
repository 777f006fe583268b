"""What a run holds once it has simulated, and the analysis done a chunk of samples at a time to keep a long run's
temporaries small: the same numbers as computed whole (benchmarks/bench_soak.py measures the peak memory)."""

import numpy as np

from simbench import sim
from simbench.robots import rsmg as S
from simbench.robots import rsmg_outputs
from simbench.rotations import quat_to_matrix, rotation_angle


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
        got_error, got_closure = rsmg_outputs._rotor_errors(traj, rec, engaged)
        assert np.array_equal(got_error, error) and np.array_equal(got_closure, closure)
