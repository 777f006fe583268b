"""Five of bench_random_lines' random lines on dm-control's Jaco (the benchmark's generator and seed): every run that
ends `ok` keeps every promise, checked from its timeseries.npz alone (issue 35)."""

import numpy as np

from benchmarks.bench_random_lines import jaco_robot, load, promises_broken, run_arm, scenario_text


def test_every_ok_line_keeps_its_promises_by_the_recording():
    rows = run_arm("jaco", n=5)
    assert len(rows) == 5 and all(row["outcome"] in ("ok", "limits") for row in rows), rows
    ok = [row for row in rows if row["outcome"] == "ok"]
    assert ok  # measured: 3 of the 5
    for row in ok:
        assert row["broken"] == [], row


def test_the_checks_see_a_tool_off_the_line(tmp_path):
    scenario = load(scenario_text(jaco_robot(), [24.4, 133.3, 286.9, -28.9, 70.8, 177.6], [478.2, 0, 307.6], 2.0),
                    tmp_path, "line")
    a = scenario.robot_def.fk(np.array([scenario.task.start]))[0]
    b = np.array(scenario.task.path[0].line.end)
    t = np.linspace(0.0, 2.0, 11)
    tool = a + (t / 2.0)[:, None] * (b - a)
    tool[5, 2] += 0.01  # 10 mm off the line
    q_ref = np.tile(scenario.task.start, (11, 1))
    np.savez(tmp_path / "series.npz", t=t, tool=tool, q_ref=q_ref)
    with np.load(tmp_path / "series.npz") as series:
        broken, figures = promises_broken(series, scenario)
    assert broken == ["path_tolerance"] and abs(figures["deviation"] - 0.01) < 1e-3
