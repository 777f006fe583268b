"""Bad scenarios: exit 2 with one line naming the file, the field and what is expected; a path the method
cannot repair: exit 1 with the reason. Neither leaves an output folder behind."""

import subprocess
import sys

import pytest
import yaml

from simbench.cli import main

GOOD = {
    "robot": "spherical_arm",
    "planner": "safe_straight_path",
    "units": {"angle": "deg", "length": "mm"},
    "task": {"start": [120, 10, 120, 5], "goal": [120, 75, 5, 90], "nd": 11},
    "timing": {"law": "quintic", "duration": 1.0},
}


def variant(**changes):
    """GOOD with top-level or dotted fields replaced (value None deletes)."""
    doc = yaml.safe_load(yaml.safe_dump(GOOD))
    for dotted, value in changes.items():
        *parents, leaf = dotted.split("__")
        node = doc
        for p in parents:
            node = node[p]
        if value is None:
            node.pop(leaf)
        else:
            node[leaf] = value
    return yaml.safe_dump(doc)


CASES = [
    ("unknown robot", variant(robot="puma9000"), "robot", "unknown robot 'puma9000'"),
    ("unknown planner", variant(planner="rrt"), "planner", "unknown planner 'rrt'"),
    ("missing field", variant(timing__duration=None), "timing.duration", "missing"),
    ("missing start", variant(task__start=None), "task.start", "missing"),
    ("extra field", variant(colour="red"), "colour", "unknown field"),
    ("misspelt field", variant(timing={"law": "quintic", "duraton": 1.0}), "timing.duraton",
     "did you mean 'duration'"),
    ("list too short", variant(task__start=[120, 10, 120]), "task.start", "expected 4 values"),
    ("list too long", variant(task__goal=[120, 75, 5, 90, 1]), "task.goal", "expected 4 values"),
    ("outside joint limits", variant(task__start=[120, 500, 120, 5]), "task.start",
     "q2 = 500 mm is outside the joint range"),
    ("q3 beyond its limit", variant(task__goal=[120, 75, -80, 90]), "task.goal", "q3 = -80 deg is outside"),
    ("string for a number", variant(timing__duration="fast"), "timing.duration", "expected a valid number"),
    ("string in a list", variant(task__start=[120, "ten", 120, 5]), "task.start[1]", "expected a valid number"),
    ("NaN", variant(timing__duration=float("nan")), "timing.duration", "finite number"),
    ("infinity in a list", variant(task__start=[120, 10, float("inf"), 5]), "task.start[2]", "finite number"),
    ("negative duration", variant(timing__duration=-1), "timing.duration", "greater than 0"),
    ("unknown time law", variant(timing__law="sine"), "timing.law", "expected 'cubic'"),
    ("unknown unit", variant(units={"angle": "grad"}), "units.angle", "expected 'rad' or 'deg'"),
    ("nd not an integer", variant(task__nd=11.5), "task.nd", "valid integer"),
    ("zero-length path", variant(task__goal=[120, 10, 120, 5]), "task.goal", "zero-length path"),
    ("same tool point from the twin", variant(task__goal=[300, 10, 60, 5]), "task.goal", "zero-length path"),
    ("unknown camera", variant(render={"camera": "overhead"}), "render.camera", "no camera 'overhead'"),
    ("odd video width", variant(render={"width": 641}), "render.width", "multiple of 2"),
    ("not a mapping", "- 1\n- 2\n", None, "expected a mapping of scenario fields, got a list"),
    ("not YAML", "robot: [spherical_arm\nplanner: x\n", None, "not valid YAML at line"),
    ("empty file", "", None, "empty file"),
]


PUMA = {
    "robot": "puma600",
    "planner": "decoupled_path",
    "units": {"angle": "deg", "length": "mm"},
    "task": {"path": [{"line": {"start": [450, -350, -300], "end": [650, 150, -300]}}],
             "orientation": {"convention": "zyx", "value": [0, 180, 0]},
             "configuration": {"wrist": "flip"}},
    "timing": {"law": "quintic", "duration": 1.0},
}
ARC = {"center": [550, -100, -250], "radius": 100, "normal": [0, 0, 1], "start": 0, "end": 360}


def puma(**task):
    doc = yaml.safe_load(yaml.safe_dump(PUMA))
    doc["task"].update(task)
    return yaml.safe_dump(doc)


CASES += [
    ("circle of zero radius", puma(path=[{"arc": {**ARC, "radius": 0}}]), "task.path[0].arc.radius",
     "greater than 0"),
    ("zero normal", puma(path=[{"arc": {**ARC, "normal": [0, 0, 0]}}]), "task.path[0].arc.normal", "zero vector"),
    ("arc with equal start and end", puma(path=[{"arc": {**ARC, "end": 0}}]), "task.path[0].arc",
     "different start and end angles"),
    ("line of one point", puma(path=[{"line": {"start": [500, 0, -300], "end": [500, 0, -300]}}]),
     "task.path[0].line", "start equals end"),
    ("segment neither line nor arc", puma(path=[{}]), "task.path[0]", "exactly one of 'line' or 'arc'"),
    ("point outside the workspace", puma(path=[{"line": {"start": [450, 0, -300], "end": [1500, 0, -300]}}]),
     "task.path[0].line", "its end [1.5000, 0.0000, -0.3000] m is outside the workspace"),
    ("segments that do not join", puma(path=[{"line": {"start": [450, -300, -300], "end": [450, 0, -300]}},
                                             {"line": {"start": [460, 0, -300], "end": [600, 0, -300]}}]),
     "task.path[1]", "starts 10.000 mm from where task.path[0] ends"),
    ("unknown orientation convention", puma(orientation={"convention": "xyz", "value": [0, 180, 0]}),
     "task.orientation.convention", "expected 'zyx', 'quat' or 'rotvec'"),
    ("zero quaternion", puma(orientation={"convention": "quat", "value": [0, 0, 0, 0]}), "task.orientation",
     "zero length"),
    ("point with two coordinates", puma(path=[{"line": {"start": [450, -300], "end": [450, 0, -300]}}]),
     "task.path[0].line.start", "expected a point [x, y, z]"),
    ("unknown arm configuration", puma(configuration={"arm": "left"}), "task.configuration.arm",
     "expected 'righty' or 'lefty'"),
    ("planner for another robot", puma() .replace("robot: puma600", "robot: spherical_arm"), "planner",
     "works with puma600, not 'spherical_arm'"),
]


EYE = {
    "robot": "agile_eye",
    "planner": "avoidance_4567",
    "units": {"angle": "deg", "length": "m"},
    "task": {"start": {"convention": "zyx", "value": [0, 0, 0]},
             "goal": {"convention": "zyx", "value": [30, 10, 5]},
             "obstacles": [{"center": {"convention": "zyx", "value": [15, 5, 2]}, "radius": 5}]},
    "timing": {"law": "4567", "duration": 2.0},
}


def eye(timing=None, **task):
    doc = yaml.safe_load(yaml.safe_dump(EYE))
    doc["task"].update(task)
    doc["timing"].update(timing or {})
    return yaml.safe_dump(doc)


CASES += [
    ("eye: unknown orientation convention", eye(start={"convention": "euler", "value": [0, 0, 0]}),
     "task.start.convention", "expected 'zyx', 'quat' or 'rotvec'"),
    ("eye: obstacle of negative size",
     eye(obstacles=[{"center": {"convention": "zyx", "value": [15, 5, 2]}, "radius": -5}]),
     "task.obstacles[0].radius", "greater than 0"),
    ("eye: T* longer than T", eye(avoidance={"window": 3.0}), "task.avoidance.window",
     "T* = 3 s is longer than the motion (timing.duration = 2 s)"),
    ("eye: zyx with two angles", eye(goal={"convention": "zyx", "value": [30, 10]}), "task.goal",
     "zyx expects 3 values, got 2"),
    ("eye: start on a singular curve", eye(start={"convention": "zyx", "value": [0, -90, 0]}), "task.start",
     "lies on a singular curve"),
    ("eye: working mode out of range", eye(working_mode=8), "task.working_mode", "less than or equal to 7"),
]


RSMG = {
    "robot": "rsmg",
    "planner": "round_robin",
    "units": {"angle": "deg", "length": "m"},
    "task": {"motion": {"kind": "turns", "axis": [0.3, 0.2, 0.93], "turns": 1}},
    "timing": {"law": "quintic", "duration": 5.0},
}


def rsmg(**task):
    doc = yaml.safe_load(yaml.safe_dump(RSMG))
    doc["task"].update(task)
    return yaml.safe_dump(doc)


CASES += [
    ("rsmg: unknown motion", rsmg(motion={"kind": "wobble"}), "task.motion.kind", "expected 'turns' or 'tumble'"),
    ("rsmg: zero rotation axis", rsmg(motion={"kind": "turns", "axis": [0, 0, 0]}), "task.motion.axis",
     "zero vector"),
    ("rsmg: negative swing time", rsmg(swing_time=-0.5), "task.swing_time", "greater than 0"),
    ("rsmg: turns as text", rsmg(motion={"kind": "turns", "turns": "three"}), "task.motion.turns",
     "valid number"),
]


def run_cli(args, capsys):
    code = main(args)
    captured = capsys.readouterr()
    return code, captured.err.strip().splitlines()


@pytest.mark.parametrize("label, text, field, expected", CASES, ids=[c[0] for c in CASES])
def test_bad_scenario_exits_2_with_one_line(tmp_path, capsys, label, text, field, expected):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    for command in (["validate", str(path)], ["run", str(path), "--out", str(tmp_path / "out"), "--quiet"]):
        code, lines = run_cli(command, capsys)
        assert code == 2
        assert len(lines) == 1, lines
        assert lines[0].startswith(f"error: {path}: " + (f"{field}: " if field else ""))
        assert expected in lines[0]
        assert not (tmp_path / "out").exists()


def test_missing_file_and_binary_file(tmp_path, capsys):
    code, lines = run_cli(["validate", str(tmp_path / "nope.yaml")], capsys)
    assert code == 2 and lines == [f"error: {tmp_path / 'nope.yaml'}: no such file"]
    binary = tmp_path / "blob.yaml"
    binary.write_bytes(bytes(range(256)) * 4)
    code, lines = run_cli(["validate", str(binary)], capsys)
    assert code == 2 and len(lines) == 1 and "not a text file" in lines[0]


def test_unrepairable_path_exits_1_with_the_reason_and_writes_nothing(tmp_path, capsys):
    path = tmp_path / "case4_printed.yaml"
    path.write_text(variant(task={"start": [300, 0, 80, 30], "goal": [47, 400, -75, 100]}))
    code, lines = run_cli(["run", str(path), "--out", str(tmp_path / "out"), "--no-video"], capsys)
    assert code == 1
    assert len(lines) == 1 and lines[0].startswith("run failed: the straight path leaves the workspace")
    assert "tangent triangle of Fig. 8 has no solution" in lines[0]
    assert not (tmp_path / "out").exists()
    assert list(tmp_path.iterdir()) == [path]


def test_path_leaving_the_reach_between_its_ends_exits_1_naming_where(tmp_path, capsys):
    path = tmp_path / "through_the_base.yaml"
    path.write_text(puma(path=[{"line": {"start": [450, 0, -300], "end": [-450, 0, -300]}}]))
    code, lines = run_cli(["run", str(path), "--out", str(tmp_path / "out"), "--no-video"], capsys)
    assert code == 1 and len(lines) == 1
    assert lines[0].startswith("run failed: the path leaves the arm's reach at s = 0.")
    assert "tool point [" in lines[0]
    assert not (tmp_path / "out").exists()


def test_real_command_line_prints_no_traceback(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text(variant(task__start=[120, 500, 120, 5]))
    proc = subprocess.run([sys.executable, "-m", "simbench", "run", str(path)], capture_output=True, text=True,
                          cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert proc.stdout == ""
