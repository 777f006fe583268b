"""examples/rl_ppo: bad arguments refused in one line before any training; with stable-baselines3 installed (the
`train` extra), a short run writes its curve, and the servo's return it reports is the one an episode stepped here
with the environment's own API earns."""

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
from simbench.env.rl_mode import with_rl

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "examples" / "rl_ppo" / "train.py"


def train(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True, cwd=tmp_path,
                          timeout=600, env={**os.environ, "MUJOCO_GL": "egl"})


@pytest.mark.parametrize("args, message", [
    (["--task", "puma600/nope"], "argument --task: invalid choice: 'puma600/nope'"),
    (["--rl", "{bad"], "argument --rl: expected a JSON object of rl_mode.RL's fields"),
    (["--rl", '{"width": 0}'], "rl width: a distance > 0 (m) expected"),
    (["--steps", "0"], "--steps, --eval-every and --random-episodes must be at least 1"),
])
def test_a_bad_argument_is_refused_in_one_line(tmp_path, args, message):
    proc = train(tmp_path, *args, "--out", str(tmp_path / "out"))
    assert proc.returncode == 2 and message in proc.stderr and proc.stderr.count("\n") == 1
    assert not (tmp_path / "out").exists()


def test_a_short_run_writes_its_curve_and_the_servos_return(tmp_path):
    pytest.importorskip("stable_baselines3", reason="pip install -e '.[train]'")
    out = tmp_path / "ppo"
    proc = train(tmp_path, "--task", "spherical_arm/case1", "--steps", "256", "--eval-every", "1024",
                 "--random-episodes", "1", "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    rows = list(csv.DictReader((out / "curve.csv").open()))
    assert [int(r["steps"]) for r in rows] == [0, 1024, 2048]  # PPO collects its 2048-step rollout whole
    summary = json.loads((out / "references.json").read_text())
    assert (out / "curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    env = simbench_env.load_task("spherical_arm", "case1", *with_rl(
        {"residual": True, "residual_of": "servo", "width": 0.005, "float32": True}))
    step, total = env.reset(), 0.0
    while not step.last():
        step = env.step(np.zeros(env.action_spec().shape, np.float32))
        total += step.reward
    assert summary["references"]["servo"] == pytest.approx(total, rel=1e-9)
    assert summary["target"] == pytest.approx(0.8 * total, rel=1e-9)
