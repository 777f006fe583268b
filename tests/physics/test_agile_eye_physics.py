"""The Agile Eye in physics: the platform follows the plan, the loops stay closed, and a path through a
singularity is caught."""

import numpy as np
import pytest

from simbench.robots import agile_eye as E


def test_platform_follows_the_plan_within_1_deg_with_closed_loops(evaluated):
    _, ev = evaluated("agile_eye", "avoidance")
    extra = ev.analysis.extra
    ref = E.quat_to_matrix(ev.trajectory.series["platform_quat_ref"])
    actual = E.quat_to_matrix(ev.recording.sensors["platform_quat"])
    error = np.rad2deg(E.rotation_angle(ref, actual))
    assert error.max() < 1.0
    assert extra["orientation_error_max"] == pytest.approx(np.deg2rad(error.max()))
    assert extra["closure_error_max"] < 0.5e-3
    assert extra["assembly_mode_changes"] == 0
    assert not ev.analysis.singularity_events
    assert 0.30 <= extra["kci"]["mean"] <= 1.0
    assert ev.recording.warnings == ()


def test_timeseries_series_for_the_agile_eye(evaluated):
    _, ev = evaluated("agile_eye", "avoidance")
    n = ev.recording.t.size
    series = {**ev.trajectory.series, **ev.analysis.series}
    for name, shape in (("platform_quat_ref", (n, 4)), ("platform_quat", (n, 4)), ("kci", (n,)),
                        ("base_angles", (n, 3)), ("closure_error", (n,))):
        assert series[name].shape == shape, name
    assert np.allclose(np.linalg.norm(series["platform_quat"], axis=1), 1.0)


def test_driving_through_a_singularity_is_caught(evaluated):
    _, ev = evaluated("agile_eye", "through_singularity")
    kinds = [e["kind"] for e in ev.analysis.singularity_events]
    assert "type2" in kinds
    type2 = [e for e in ev.analysis.singularity_events if e["kind"] == "type2"]
    gap = E.axis_gaps(E.quat_to_matrix(ev.recording.sensors["platform_quat"])).min(axis=1)
    closest = ev.recording.t[np.argmin(gap)]
    assert any(e["t_start"] <= closest <= e["t_end"] for e in type2)
    # The simulated platform changes assembly mode (det A changes sign), and the report counts each change.
    changes = [e for e in ev.analysis.singularity_events if e["kind"] == "assembly_mode_change"]
    det = ev.analysis.series["det_a"]
    assert len(changes) == ev.analysis.extra["assembly_mode_changes"] == int(np.sum(det[1:] * det[:-1] < 0))
    assert changes
