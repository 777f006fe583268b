"""The shipped metric `tracking` (simbench.analysis.tracking): report.json's tracking figures, against NumPy's
reductions of
the whole run's arrays (the recording, the plan and the analysis' per-sample series) at once."""

import numpy as np
import pytest
import yaml

from simbench.analysis.tracking import Tracking
from simbench.api import registry
from tests.conftest import SHIPPED

_WHOLE = [p for p in SHIPPED if yaml.safe_load(p.read_text()).get("sim", {}).get("record_every", 1) == 1]


def _rms(x: np.ndarray, axis=None):
    return np.sqrt(np.mean(np.square(x), axis=axis))


@pytest.mark.parametrize("path", _WHOLE, ids=lambda p: f"{p.parent.name}-{p.stem}")
def test_the_tracking_figures_are_the_whole_arrays_reductions(evaluated, path):
    scenario, ev = evaluated(path.parent.name, path.stem)
    robot, traj, rec, series = scenario.robot_def, ev.trajectory, ev.recording, ev.analysis.series
    tracking = ev.analysis.tracking
    joint_error = rec.q - traj.q_ref
    tool_error = np.linalg.norm(traj.tool_ref - rec.tool, axis=1)
    close = {"rtol": 1e-12, "atol": 1e-15}
    assert np.allclose([tracking["joint_rms"][j] for j in robot.joints], _rms(joint_error, axis=0), **close)
    assert [tracking["joint_max"][j] for j in robot.joints] == np.abs(joint_error).max(axis=0).tolist()
    assert np.isclose(tracking["tool_error_rms"], _rms(tool_error), **close)
    assert np.isclose(tracking["tool_error_max"], tool_error.max(), **close)
    assert np.isclose(tracking["tool_error_final"], tool_error[-1], **close)
    assert np.isclose(tracking["tool_rms"], _rms(series["path_deviation"]), **close)
    assert tracking["tool_max"] == series["path_deviation"].max()
    assert np.isclose(tracking["tool_lag_rms"], _rms(series["path_lag"]), **close)
    assert tracking["tool_lag_max"] == np.abs(series["path_lag"]).max()
    assert np.isclose(tracking["path_length"], np.linalg.norm(np.diff(traj.tool_ref, axis=0), axis=1).sum(), **close)
    if robot.orientation_error in series:
        error = series[robot.orientation_error]
        assert np.isclose(tracking["orientation_rms"], _rms(error), **close)
        assert (tracking["orientation_max"], tracking["orientation_final"]) == (error.max(), error[-1])
    else:
        assert "orientation_rms" not in tracking


def test_tracking_is_a_metric_of_simbench_s_own_entry_points():
    assert registry.metrics()["tracking"] is Tracking and registry.origin("metric", "tracking") == "simbench"
