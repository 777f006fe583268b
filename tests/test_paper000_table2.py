"""Paper 000's generation method against its Table 2 (nd = 11), with the typos NOTES.md section 1 lists.

Rows are x, y, z (mm), q1 (deg), q2 (mm), q3 (deg), q4 (mm) as printed, corrected where marked.
"""

import numpy as np
import pytest

from simbench.errors import RunError
from simbench.planners import safe_straight_path as method
from simbench.robots import spherical_arm

TOL = 1e-3  # deg or mm: the table prints four decimals


def si(row_deg_mm):
    """[q1 deg, q2 mm, q3 deg, q4 mm] -> SI."""
    q1, q2, q3, q4 = row_deg_mm
    return np.array([np.deg2rad(q1), q2 / 1e3, np.deg2rad(q3), q4 / 1e3])


CASE1 = [  # q_init [120, 10, 120, 5], q_goal [120, 75, 5, 90]
    (8.7500, -15.1554, 70.3109, 120, 10.0000, 120.0000, 5.0000),
    (1.8978, -3.2871, 74.8257, 120, 15.0668, 97.2687, 0),
    (-4.9543, 8.5812, 79.3404, 120, 21.0241, 70.7137, 0),
    (-11.8065, 20.4495, 83.8552, 120, 29.5000, 45.8865, 3.9227),
    (-18.6587, 32.3178, 88.37008, 120, 36.0000, 30.9407, 13.5086),  # z printed 8.37008
    (-25.5108, 44.1861, 92.8848, 120, 42.5000, 21.7783, 24.9432),
    (-32.3630, 56.0544, 97.3996, 120, 49.0000, 15.8688, 37.2904),  # q4 of rows 7 and 8 printed swapped
    (-39.2152, 67.9227, 101.9143, 120, 55.5000, 11.8206, 50.1296),
    (-46.0673, 79.7910, 106.4291, 120, 62.0000, 8.9007, 63.2577),
    (-52.9195, 91.6593, 110.9439, 120, 68.5000, 6.7057, 76.5681),
    (-59.7717, 103.5276, 115.4587, 120, 75.0000, 5.0000, 90.0000),
]

CASE2 = [  # q_init [100, 120, 110, 30], q_goal [10, 40, -15, 120]
    (3.5635, -20.2094, 206.3816, 100.0000, 120, 110.0000, 30.0000),
    (17.4759, -15.6725, 188.8611, 318.1140, 112, 63.3923, 22.4118),
    (31.3883, -11.1356, 171.3407, 340.4669, 104, 48.2694, 20.0355),
    (45.3007, -6.5987, 153.8202, 351.7123, 96, 31.2875, 23.5693),
    (59.2132, -2.0618, 136.2998, 358.0058, 88, 17.1639, 32.0107),
    (73.1256, 2.4751, 118.7794, 1.9386, 80, 6.8422, 43.6923),
    (87.0380, 7.0120, 101.2589, 4.6060, 72, -0.4863, 57.3231),
    (100.9504, 11.5489, 83.7385, 6.5264, 64, -5.7668, 72.1257),  # q1 printed ".52646"
    (114.8628, 16.0859, 66.2180, 7.9721, 56, -9.6791, 87.6586),
    (128.7753, 20.6228, 48.6976, 9.0984, 48, -12.6631, 103.6675),
    (142.6877, 25.1597, 31.1771, 10.0000, 40, -15.0000, 120.0000),  # q4 printed "0000.120"
]

CASE3 = [  # from the new q_init [120, 5, 66.32, 15]; q1 printed 350 where x, y say 120
    (-9.0366, 15.6519, 76.2111, 120, 5.0000, 66.3200, 15.0000),
    (-11.3830, 19.7159, 67.3317, 120, 11.5000, 48.6097, 4.4320),
    (-13.7293, 23.7799, 58.4522, 120, 16.3682, 23.7535, 0),
    (-16.0756, 27.8438, 49.5728, 120, 24.5000, -8.7128, 2.5266),
    (-18.4220, 31.9078, 40.6934, 120, 31.0000, -28.8615, 12.0694),
    (-20.7683, 35.9718, 31.8139, 120, 37.5000, -40.6674, 24.7612),
    (-23.1147, 40.0358, 22.9345, 120, 44.0000, -47.8457, 38.8828),
    (-25.4610, 44.0997, 14.0550, 120, 50.5000, -52.5342, 53.7137),
    (-27.8073, 48.1637, 5.1756, 120, 57.0000, -55.7967, 68.9355),
    (-30.1537, 52.2277, -3.7039, 120, 63.5000, -58.1837, 84.3921),
    (-32.5000, 56.2917, -12.5833, 120, 70.0000, -60.0000, 100.0000),
]

CASE4 = [  # from the new q_init [300, 0, 36.6576, 30], q_goal [47, 400, -75, 100]
    (24.0665, -41.6845, 65.8219, 300.0000, 0, 36.6576, 30.0000),
    (23.9546, -35.0553, 89.6827, 304.3462, 40, 24.8714, 16.7985),  # q1, q3 printed 124.3462, 15.1286
    (23.8426, -28.4261, 113.5434, 309.9885, 80, 5.4556, 7.2702),
    (23.7306, -21.7969, 137.4042, 317.4321, 120, -21.3509, 4.5962),  # q2 printed "012"
    (23.6187, -15.1677, 161.2650, 327.2918, 160, -45.6712, 10.1696),
    (23.5067, -8.5385, 185.1258, 340.0371, 200, -60.8681, 21.3728),
    (23.3947, -1.9093, 208.9865, 355.3343, 240, -68.9578, 35.3728),
    (23.2827, 4.7199, 232.8473, 11.4597, 280, -72.8857, 50.7273),
    (23.1708, 11.3491, 256.7081, 26.0957, 320, -74.5406, 66.7939),
    (23.0588, 17.9783, 280.5689, 37.9425, 360, -75.0405, 83.2700),
    (22.9468, 24.6075, 304.4296, 47.0000, 400, -75.0000, 100.0000),
]


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
    printed = [5.0, 8.6523, -2.9201, -11.7599, -17.9224, 37.5, 44.0, 50.5, 57.0, 63.5, 70.0]
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
    printed = np.array([[300, 0, 80, 30], [320.9747, 40, 77.5227, 11.6052], [345.3025, 73.5553, 72.4359, 0],
                        [5.7809, 95.6200, 69.3403, 0], [19.7972, 118.2252, 64.1568, 0],
                        [28.9644, 200, -64.1700, 6.9307], [35.1348, 240, -69.4503, 25.2206],
                        [39.4785, 280, -71.9744, 43.7947], [42.6683, 320, -73.4243, 62.4818],
                        [45.0963, 360, -74.3555, 81.2250], [47, 400, -75, 100]])
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
