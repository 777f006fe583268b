"""examples/rl_cem: the cross-entropy search runs as a user runs it (a command) and writes its reward curve; its
scores are the environment's mean reward a step, recomputed here from an episode stepped by hand."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from simbench import env as simbench_env

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "examples" / "rl_cem" / "train.py"


def test_train_runs_and_writes_its_curve(tmp_path):
    out = tmp_path / "cem"
    proc = subprocess.run([sys.executable, str(SCRIPT), "--task", "spherical_arm/case1", "--iterations", "2",
                           "--population", "3", "--elite", "2", "--no-report", "--out", str(out)],
                          capture_output=True, text=True, cwd=tmp_path, timeout=300,
                          env={**os.environ, "MUJOCO_GL": "egl"})
    assert proc.returncode == 0, proc.stderr
    assert "iteration   2: population mean" in proc.stdout
    assert (out / "curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = list(csv.DictReader((out / "history.csv").open()))
    assert [int(r["iteration"]) for r in rows] == [1, 2]
    for r in rows:
        best, elite, mean = float(r["best"]), float(r["elite_mean"]), float(r["population_mean"])
        assert 0.0 <= mean <= elite <= best <= 1.0
    policy = json.loads((out / "policy.json").read_text())
    assert policy["best_score"] == max(float(r["best"]) for r in rows)

    # The reference as target (every gain zero), stepped here with the environment's own API: the same score.
    env = simbench_env.load_task("spherical_arm", "case1")
    step, rewards = env.reset(), []
    while not step.last():
        step = env.step(step.observation["q_ref"])
        rewards.append(step.reward)
    assert policy["reference_score"] == pytest.approx(np.mean(rewards), rel=1e-12)
