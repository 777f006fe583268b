"""What needs an optional package (simbench.core.extras) is refused in one line naming the extra that installs it, as
bad input (exit 2), with the package made unimportable as Python makes a blocked import (None in sys.modules);
what needs none runs without any: the demo, in a fresh interpreter whose import system refuses them all."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from simbench.cli import main
from simbench.core import extras
from tests.conftest import scenario_file

ROOT = Path(__file__).resolve().parents[2]

# A half turn keeping 80 deg from every singular curve: the ends keep it, no bent path does, so the planner turns
# to its global search in SO(3) (tests/planners/test_agile_eye_start_and_crossing.py), which needs OMPL.
SEARCH = {"robot": "agile_eye", "planner": "avoidance_4567", "units": {"angle": "deg", "length": "m"},
          "task": {"start": {"convention": "zyx", "value": [0, 0, 0]},
                   "goal": {"convention": "zyx", "value": [0, 0, 180]},
                   "singularity_clearance": 80, "avoidance": {"time_budget": 1.0}},
          "timing": {"law": "4567", "duration": 3.0, "hold": 0.0}}
LINE = yaml.safe_load(scenario_file("puma600", "line").read_text())
MINK_BASELINE = {**LINE, "planner": "mink_baseline",
                 "task": {"follow": "decoupled_path", "task": LINE["task"]}}


def _file(folder: Path, name: str, document: dict) -> str:
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(document))
    return str(path)


def _refused(capsys, monkeypatch, module: str, argv: list[str]) -> str:
    """The one line on stderr of the command run with `module` unimportable; it exits 2."""
    monkeypatch.setitem(sys.modules, module, None)
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    return err.strip()


def _says(line: str, module: str) -> None:
    extra, package = extras.EXTRAS[module]
    assert line.startswith("error: ")
    assert line.endswith(f"needs {package}, which is not installed: pip install 'simbench[{extra}]'"), line


@pytest.mark.parametrize("command", ["validate", "run"])
def test_a_scenario_whose_planner_needs_the_global_search_is_refused_naming_the_ompl_extra(
        tmp_path, capsys, monkeypatch, command):
    path = _file(tmp_path, "search", SEARCH)
    argv = [command, path] if command == "validate" else [command, path, "--no-video", "--out", str(tmp_path / "o")]
    line = _refused(capsys, monkeypatch, "ompl", argv)
    _says(line, "ompl")
    assert line.startswith(f"error: {path}: task.avoidance: the global search in SO(3)")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("command", [["validate", "--no-plan"], ["run", "--no-video"]])
def test_mink_baseline_is_refused_naming_the_mink_extra_before_it_plans(tmp_path, capsys, monkeypatch, command):
    path = _file(tmp_path, "mink", MINK_BASELINE)
    line = _refused(capsys, monkeypatch, "mink", [*command, path])
    assert line.startswith(f"error: {path}: planner: mink_baseline needs mink")
    _says(line, "mink")


def test_cartesian_paths_mink_method_is_refused_naming_the_mink_extra(tmp_path, capsys, monkeypatch):
    import dm_control

    jaco = Path(dm_control.__file__).parent / "third_party" / "kinova" / "jaco_arm.xml"
    path = _file(tmp_path, "line", {
        "robot": {"model": str(jaco), "tool": {"site": "wristsite"}, "speed_limits": [36, 36, 36, 48, 48, 48]},
        "planner": "cartesian_path",
        "units": {"angle": "deg", "length": "mm"},
        "task": {"start": [24.4, 133.3, 286.9, -28.9, 70.8, 177.6], "method": "mink",
                 "path": [{"line": {"end": [478.2, 186.9, 307.6]}}]},
        "timing": {"duration": 4.0}})
    line = _refused(capsys, monkeypatch, "mink", ["validate", "--no-plan", path])
    assert line.startswith(f"error: {path}: task.method: the mink method needs mink")
    _says(line, "mink")


def test_the_bench_refuses_the_mink_method_named_and_leaves_it_out_by_default(capsys, monkeypatch):
    _says(_refused(capsys, monkeypatch, "mink", ["bench", "puma600", "--methods", "paper,mink", "--tasks", "1"]),
          "mink")
    from simbench.commands.bench import load_suite

    assert "mink" not in load_suite("puma600").methods  # still refused: sys.modules['mink'] is None
    monkeypatch.delitem(sys.modules, "mink")
    assert "mink" in load_suite("puma600").methods


@pytest.mark.parametrize("command", ["sweep", "bench"])
def test_ray_is_refused_naming_the_ray_extra(capsys, monkeypatch, command):
    what = str(ROOT / "sweeps" / "spherical_arm_timestep.yaml") if command == "sweep" else "puma600"
    line = _refused(capsys, monkeypatch, "ray", [command, what, "--ray", "local"])
    assert line.startswith("error: --ray: ")
    _says(line, "ray")


def test_training_the_learnt_fk_is_refused_naming_the_train_extra(tmp_path, capsys, monkeypatch):
    out = tmp_path / "weights.npz"
    _says(_refused(capsys, monkeypatch, "sklearn", ["train-fk", "--samples", "100", "--out", str(out)]), "sklearn")
    assert not out.exists()


def test_a_sweep_without_pyarrow_writes_its_csv_and_says_why_there_is_no_parquet(tmp_path, capsys, monkeypatch):
    sweep = _file(tmp_path, "sweep", {"base": str(scenario_file("spherical_arm", "case1")),
                                      "grid": {"timing.duration": [1, 2]}})
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    assert main(["sweep", sweep, "--workers", "1", "--out", str(tmp_path / "out")]) == 0
    note = extras.words("pyarrow", "results.parquet")
    assert f"note: {note}" in capsys.readouterr().out
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["outputs"]["table"] == ["results.csv"] and note in summary["notes"]
    assert (tmp_path / "out" / "results.csv").is_file() and not (tmp_path / "out" / "results.parquet").exists()


def test_an_installed_package_that_fails_to_import_is_told_apart_from_a_missing_one(monkeypatch):
    def broken(name):  # as an installed package whose shared library is missing
        raise ImportError("libompl.so: cannot open shared object file")

    monkeypatch.setattr(extras.importlib, "import_module", broken)
    with pytest.raises(extras.MissingExtra, match=r"needs OMPL, which fails to import \(ImportError: libompl\.so: "
                                                  r"cannot open shared object file\): pip install 'simbench\[ompl\]'"):
        extras.require("ompl", "the search")


BLOCKER = """
import importlib.abc, runpy, sys

BLOCKED = set(sys.argv.pop(1).split(","))

class Blocker(importlib.abc.MetaPathFinder):  # as if none of them were installed
    def find_spec(self, name, path=None, target=None):
        if name.partition(".")[0] in BLOCKED:
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None

sys.meta_path.insert(0, Blocker())
runpy.run_module("simbench", run_name="__main__", alter_sys=True)
"""
OPTIONAL = ("ompl", "mink", "ray", "pyarrow", "shimmy", "gymnasium", "sklearn", "mkdocs")


def test_the_demo_runs_with_video_and_with_no_optional_package_importable(tmp_path):
    """The core suffices: every optional package refused to the import system, MUJOCO_GL unset."""
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    done = subprocess.run([sys.executable, "-c", BLOCKER, ",".join(OPTIONAL), "run",
                           str(scenario_file("spherical_arm", "demo")), "--out", str(tmp_path / "demo"), "--quiet"],
                          capture_output=True, text=True, timeout=300, env=env, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    report = json.loads((tmp_path / "demo" / "report.json").read_text())
    assert report["status"] == "ok"
    video = tmp_path / "demo" / "video.mp4"
    assert video.stat().st_size > 10_000 and b"ftyp" in video.read_bytes()[:16]
