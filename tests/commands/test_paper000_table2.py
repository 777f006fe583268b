"""Paper 000's generation method against its Table 2 (nd = 11), with the typos its Errata list
(docs/papers/000-spherical-arm.md).

Rows are x, y, z (mm), q1 (deg), q2 (mm), q3 (deg), q4 (mm) as printed (simbench.commands.reproduce.paper000.PRINTED),
corrected where that module classifies a typo or an error; case 3's q1 is 120 deg, as its x and y say.
"""

import numpy as np
import pytest

from simbench.commands.reproduce import paper000
from simbench.core.errors import RunError
from simbench.planners import safe_straight_path as method
from simbench.robots import spherical_arm

TOL = 1e-3  # deg or mm: the table prints four decimals


def si(row_deg_mm):
    """[q1 deg, q2 mm, q3 deg, q4 mm] -> SI."""
    q1, q2, q3, q4 = row_deg_mm
    return np.array([np.deg2rad(q1), q2 / 1e3, np.deg2rad(q3), q4 / 1e3])


# The printed Table 2 lives in one place, simbench.commands.reproduce.paper000 (copied from the paper's text); the rows
# here are its path rows with the typos and errors that module classifies applied (paper 000's Errata).
TABLE2 = {case.name: case for case in paper000.PRINTED}
CASE1, CASE2, CASE3, CASE4 = (paper000.corrected_rows(TABLE2[f"case {k}"]) for k in (1, 2, 3, 4))


def table_rows(q_init, q_goal):
    """The method's 11 points as (x, y, z, q1, q2, q3, q4) in the table's units."""
    line = method.build(si(q_init), si(q_goal))
    rows = []
    for w in method.waypoints(line, 11):
        q = w["q"]
        rows.append([*(np.array(w["X"]) * 1e3), np.rad2deg(q[0]), q[1] * 1e3, np.rad2deg(q[2]), q[3] * 1e3])
    return np.array(rows)


def assert_rows(actual, printed):
    printed = np.array(printed, float)
    diff = actual - printed
    diff[:, 3] = (diff[:, 3] + 180.0) % 360.0 - 180.0  # q1 is printed modulo one turn
    assert np.abs(diff).max() < TOL, np.round(diff, 5)


@pytest.mark.parametrize("q_init, q_goal, printed", [
    ([120, 10, 120, 5], [120, 75, 5, 90], CASE1),
    ([100, 120, 110, 30], [10, 40, -15, 120], CASE2),
    ([120, 5, 66.32, 15], [120, 70, -60, 100], CASE3),
    ([300, 0, 36.6576, 30], [47, 400, -75, 100], CASE4),
], ids=["case1", "case2", "case3_from_new_start", "case4_from_new_start"])
def test_rows_reproduce_table2(q_init, q_goal, printed):
    assert_rows(table_rows(q_init, q_goal), printed)


@pytest.mark.parametrize("q_init, q_goal", [([120, 10, 120, 5], [120, 75, 5, 90]),
                                            ([100, 120, 110, 30], [10, 40, -15, 120])])
def test_cases_1_and_2_lie_inside_the_workspace(q_init, q_goal):
    assert method.exit_reasons(method.build(si(q_init), si(q_goal))) == []


def test_case3_leaves_the_workspace_and_the_tangent_construction_gives_66_32_deg():
    line = method.build(si([120, 5, 120, 15]), si([120, 70, -60, 100]))
    reasons = method.exit_reasons(line)
    assert any("q2 below" in r["condition"] for r in reasons)
    assert np.rad2deg(method.tangent_q3(line)["S"]) == pytest.approx(53.68, abs=0.01)
    repaired, info = method.repair(line, 11)
    assert info["chosen"] == "S"
    assert np.rad2deg(info["q3_init_new"]) == pytest.approx(66.32, abs=0.01)
    assert method.exit_reasons(repaired) == []


def test_case3_printed_attempt_q2_column():
    """The table's first block for case 3 (before the repair): q2 goes negative, the reason it leaves."""
    line = method.build(si([120, 5, 120, 15]), si([120, 70, -60, 100]))
    q2 = method.evaluate(line, np.linspace(0, 1, 11))[:, 1] * 1e3
    printed = np.array(TABLE2["case 3"].attempt, float)[:, 1]
    assert np.abs(q2 - printed).max() < TOL


def test_case4_printed_start_cannot_be_repaired():
    """The printed start leaves the workspace (eq. 27's jump) and Fig. 8's triangle is infeasible for it."""
    line = method.build(si([300, 0, 80, 30]), si([47, 400, -75, 100]))
    reasons = method.exit_reasons(line)
    assert any("eq. 27" in r["condition"] for r in reasons)
    assert np.isnan(method.tangent_q3(line)["S"]) and np.isnan(method.tangent_q3(line)["B"])
    with pytest.raises(RunError, match="cannot repair"):
        method.repair(line, 11)


def test_case4_printed_attempt_rows():
    """The table's first block for case 4: the unrepaired path, whose q2 and q3 step between rows 5 and 6."""
    line = method.build(si([300, 0, 80, 30]), si([47, 400, -75, 100]))
    q = method.evaluate(line, np.linspace(0, 1, 11))
    printed = np.array(TABLE2["case 4"].attempt, float)
    table = np.column_stack([np.rad2deg(q[:, 0]) % 360, q[:, 1] * 1e3, np.rad2deg(q[:, 2]), q[:, 3] * 1e3])
    diff = table - printed
    diff[:, 0] = (diff[:, 0] + 180) % 360 - 180
    assert np.abs(diff).max() < TOL


def test_case4_new_start_breaks_the_q3_limit_by_0_04_deg():
    line = method.build(si([300, 0, 36.6576, 30]), si([47, 400, -75, 100]))
    reasons = method.exit_reasons(line)
    assert [r["condition"] for r in reasons] == ["q3 < -75 deg"]
    assert np.rad2deg(method.evaluate(line, np.array([0.9]))[0, 2]) == pytest.approx(-75.0405, abs=TOL)


CASES = [([120, 10, 120, 5], [120, 75, 5, 90]), ([100, 120, 110, 30], [10, 40, -15, 120]),
         ([280, 120, 70, 30], [10, 40, -15, 120]), ([120, 5, 66.32, 15], [120, 70, -60, 100]),
         ([300, 0, 36.6576, 30], [47, 400, -75, 100])]


@pytest.mark.parametrize("q_init, q_goal", CASES)
def test_every_dense_point_lies_on_the_line(q_init, q_goal):
    line = method.build(si(q_init), si(q_goal))
    s = np.linspace(0, 1, 20001)
    q = method.evaluate(line, s)
    assert np.abs(spherical_arm.fk(q) - line.points(s)[0]).max() < 1e-9


@pytest.mark.parametrize("q_init, q_goal", CASES)
def test_derivative_matches_the_method_along_the_line(q_init, q_goal):
    """dq/ds from the method agrees with differences of q(s) wherever q(s) is smooth."""
    line = method.build(si(q_init), si(q_goal))
    s = np.linspace(0.01, 0.99, 4901)
    q = method.evaluate(line, s)
    fd = np.gradient(q, s, axis=0)
    dq = method.derivative(line, s)
    smooth = np.all(np.abs(np.diff(fd, axis=0)) < 0.05, axis=1)
    smooth = np.concatenate([[False], smooth[1:] & smooth[:-1], [False]])
    assert smooth.mean() > 0.9
    assert np.abs(fd[smooth] - dq[smooth]).max() < 1e-3
