"""safe_straight_path's joint rates where a line crosses the lift axis (paper 000, case 1's kind of line). A line
whose ground projection passes through the axis keeps its azimuth (mod pi), so q1 holds its value along the whole
line and its rate is zero: where a sample lay within the central difference's step of the crossing, the difference
straddled the axis on one branch and the plan asked q1 for some 1e7 deg/s (the timestep sweep's 0.25 ms, 4 s run)."""

from pathlib import Path

import numpy as np
import yaml

import simbench
from simbench.commands.pipeline import check_plan
from simbench.planners import safe_straight_path as ssp
from simbench.robots.spherical_arm import fk


def _crossing_lines(count: int, seed: int = 3):
    """Random lines whose ends lie on opposite sides of the lift axis in one vertical plane (q1 the same, q3 on
    either side of 90 deg), each with its crossing found by the planner."""
    rng = np.random.default_rng(seed)
    lines = []
    while len(lines) < count:
        q1 = rng.uniform(-np.pi, np.pi)
        start = np.array([q1, rng.uniform(0.02, 0.3), np.deg2rad(rng.uniform(100, 170)), rng.uniform(0.0, 0.3)])
        goal = np.array([q1, rng.uniform(0.02, 0.3), np.deg2rad(rng.uniform(-60, 80)), rng.uniform(0.0, 0.3)])
        line = ssp.build(start, goal)
        if line.flip_at is not None and not line.forward_only:
            lines.append(line)
    return lines


def test_q1_rate_is_zero_at_samples_within_the_difference_step_of_the_crossing():
    offsets = np.concatenate([-np.logspace(-12, -5, 15), [0.0], np.logspace(-12, -5, 15)])
    for line in _crossing_lines(24):
        s = np.clip(line.flip_at + offsets, 0.0, 1.0)
        xy = fk(ssp.evaluate(line, np.array([0.0, 1.0])))[:, :2]
        assert abs(xy[0, 0] * xy[1, 1] - xy[0, 1] * xy[1, 0]) < 1e-9  # the two ends in one plane with the axis
        rates = ssp.derivative(line, s)
        assert np.all(np.isfinite(rates))
        assert np.abs(rates[:, 0]).max() < 1e-3, (line.flip_at, rates[:, 0])  # rounding's; about pi / 2e-6 before


def test_the_timestep_sweeps_finest_long_run_asks_q1_for_no_speed(tmp_path):
    """Case 1 at a 0.25 ms timestep and 4 s: a control sample 8e-7 of s past the crossing."""
    spec = yaml.safe_load((Path(__file__).resolve().parents[2] / "scenarios/spherical_arm/case1.yaml").read_text())
    spec.setdefault("sim", {})["timestep"] = 0.00025
    spec["timing"]["duration"] = 4.0
    path = tmp_path / "case1_fine.yaml"
    path.write_text(yaml.safe_dump(spec))
    traj, _ = check_plan(simbench.load_scenario(path))
    assert np.abs(traj.qd_ref[:, 0]).max() < 1e-3  # rad/s: 4.6e5 before
    assert np.ptp(traj.q_ref[:, 0]) < 1e-9  # q1 holds its value, as the paper's case 1 says
