"""simbench chooses no GL backend for the process: importing it leaves MUJOCO_GL unset; its videos render through
EGL where the user has not set MUJOCO_GL, and through the user's choice where they have (Linux)."""

from __future__ import annotations

import os
import subprocess
import sys

import imageio.v2 as imageio
import numpy as np
import pytest
import yaml

from tests.conftest import scenario_file

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="EGL and the MUJOCO_GL values tested are Linux's")

PROBE = """
import os
import simbench, simbench.cli, simbench.commands.pipeline, simbench.outputs.render, simbench.env
from dm_control import _render
print("MUJOCO_GL" in os.environ, _render.BACKEND)
"""


def _env(**chosen: str) -> dict[str, str]:
    """This process's environment without a GL choice or a display, and with `chosen`."""
    unset = ("MUJOCO_GL", "PYOPENGL_PLATFORM", "DISPLAY", "WAYLAND_DISPLAY")
    return {**{k: v for k, v in os.environ.items() if k not in unset}, **chosen}


def test_importing_simbench_and_its_environments_leaves_mujoco_gl_unset():
    """...while dm_control, which picks its backend when first imported, got EGL for the environments' pixels."""
    done = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, env=_env(), timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["False", "egl"]
    assert "DISPLAY" not in done.stderr  # no GLFW complaint about a missing display


def _video(tmp_path, name: str, env: dict[str, str]) -> subprocess.CompletedProcess:
    document = yaml.safe_load(scenario_file("spherical_arm", "demo").read_text())
    document.update(timing={"law": "quintic", "duration": 3.0, "hold": 0.1},
                    render={"camera": "front", "width": 96, "height": 64, "fps": 10})
    scenario = tmp_path / "short.yaml"
    scenario.write_text(yaml.safe_dump(document))
    return subprocess.run([sys.executable, "-m", "simbench", "run", str(scenario), "--out", str(tmp_path / name),
                           "--quiet"], capture_output=True, text=True, env=env, timeout=300)


def test_a_video_renders_with_mujoco_gl_unset_as_with_the_users_egl(tmp_path):
    frames = {}
    for name, env in (("unset", _env()), ("egl", _env(MUJOCO_GL="egl"))):
        done = _video(tmp_path, name, env)
        assert done.returncode == 0, done.stderr[-2000:]
        with imageio.get_reader(tmp_path / name / "video.mp4") as reader:
            frames[name] = np.array([frame for frame in reader])
    assert frames["unset"].shape == (32, 64, 96, 3)  # a frame every 0.1 s from 0 to 3.1 s
    assert frames["unset"].std() > 10  # a scene, not a blank frame
    assert np.array_equal(frames["unset"], frames["egl"])


def test_the_users_mujoco_gl_wins(tmp_path):
    """GLFW chosen without a display: the video is refused naming the user's choice, not drawn through EGL."""
    done = subprocess.run([sys.executable, "-m", "simbench", "run", str(scenario_file("spherical_arm", "demo")),
                           "--out", str(tmp_path / "out"), "--quiet"], capture_output=True, text=True,
                          env=_env(MUJOCO_GL="glfw"), timeout=300)
    assert done.returncode == 1
    assert done.stderr.strip().splitlines()[-1].startswith(
        "run failed: cannot open an offscreen renderer through MUJOCO_GL=glfw")
