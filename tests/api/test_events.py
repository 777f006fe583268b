"""api.Event and api.Violation: typed records that report.json writes exactly as the dicts they replaced, and that
read as those dicts. The truths: the dicts written out by hand, in report.json's order."""

import json
from types import SimpleNamespace

import pytest

from simbench.analysis.verdict import _planner_violations
from simbench.api import Event, Violation
from simbench.outputs.report import plain


def test_an_event_is_written_and_read_as_its_dict():
    event = Event(0.5, 0.75, "at_limit", {"joint": "q1", "bound": "upper"})
    written = {"t_start": 0.5, "t_end": 0.75, "kind": "at_limit", "detail": {"joint": "q1", "bound": "upper"}}
    assert json.dumps(plain(event)) == json.dumps(written)  # the same keys, in the same order
    assert event["kind"] == "at_limit" and event["detail"]["joint"] == "q1" and event.get("missing") is None
    assert dict(event) == written and list(event) == ["t_start", "t_end", "kind", "detail"]


def test_a_violation_is_written_kind_message_t_events_then_its_detail():
    violation = Violation("joint_limit", "q1 is asked for too much", 0.25, 3, {"joint": "q1", "excess": 0.1})
    written = {"kind": "joint_limit", "message": "q1 is asked for too much", "t": 0.25, "events": 3, "joint": "q1",
               "excess": 0.1}
    assert json.dumps(plain(violation)) == json.dumps(written)
    assert violation["joint"] == "q1" and violation.detail == {"joint": "q1", "excess": 0.1}


def test_old_style_dicts_are_read_at_the_boundary():
    """A robot's events and a planner's violations written before the types, as dicts, become the types."""
    assert Event.of({"t_start": 1.0, "t_end": 1.0, "kind": "assembly_mode_change", "detail": {"det_a": [1, -1]}}) \
        == Event(1.0, 1.0, "assembly_mode_change", {"det_a": [1, -1]})
    typed = Violation("off_path", "typed already")
    traj = SimpleNamespace(violations=(
        {"kind": "goal_missed", "message": "ends 3 mm away", "error": 0.003},
        {"kind": "singular_crossing", "t": 0.9, "message": "crosses", "crossings": [0.9]}, typed))
    found = _planner_violations(traj)
    assert found == [Violation("goal_missed", "ends 3 mm away", None, 0, {"error": 0.003}),
                     Violation("singular_crossing", "crosses", 0.9, 0, {"crossings": [0.9]}), typed]
    assert found[2] is typed


def test_records_are_frozen():
    with pytest.raises(AttributeError):
        Event(0.0, 1.0, "x").kind = "y"
