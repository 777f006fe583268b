"""A robot's model file is read as bad input is read (issue 45): a model too large for the machine refused at once,
one that MuJoCo takes long to read stopped by SIGTERM at once, a FIFO or a symlink loop it names refused, NaN and
absurd numbers refused naming the element, XML simbench does not read refused in one line, no MUJOCO_LOG.TXT left
behind, and an edited model read anew by the same process."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import simbench_planar3r

import simbench
from simbench.cli import main
from simbench.core.plant import compiled_scene
from simbench.scenario.robot_mapping import anchored
from tests.conftest import interrupt

PLANAR3R = Path(simbench_planar3r.__file__).parent / "models" / "planar3r.xml"


def _planar3r(folder: Path, extra: str = "", name: str = "arm.xml", text: str | None = None) -> Path:
    """The planar 3R arm's MJCF in `folder`, `extra` added to its worldbody."""
    path = folder / name
    path.write_text((text or PLANAR3R.read_text()).replace("</worldbody>", f"{extra}</worldbody>"))
    return path


def _scenario(folder: Path, model: str, extra: str = "") -> Path:
    """A joint_move scenario on the arm of `model` (its tool site `tool`), the robot mapping's further lines
    `extra`."""
    path = folder / "move.yaml"
    path.write_text(f"robot:\n  model: {model}\n  tool: {{site: tool}}\n  speed_limits: [180, 360, 360]\n{extra}"
                    "planner: joint_move\nunits: {angle: deg}\ntask: {start: [90, -90, -60], goal: [30, -60, -30]}\n"
                    "timing: {duration: 1.0, hold: 0.1}\n")
    return path


def _bodies(outer: int, inner: int) -> str:
    """outer x inner bodies, each with a geom colliding with nothing of the arm, by two nested replicates."""
    return (f'<replicate count="{outer}" offset="0.001 0 0"><replicate count="{inner}" offset="0 0.001 0"><body>'
            '<geom contype="0" conaffinity="0" size="0.01"/></body></replicate></replicate>')


def _refused(capsys, args: list[str]) -> str:
    """The one line a command prints refusing its input (exit 2)."""
    assert main(args) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and len(captured.err.strip().splitlines()) == 1, captured.err
    return captured.err.strip()


def _command(args: list[str], cwd: Path, timeout: float = 60) -> tuple[subprocess.CompletedProcess, float]:
    """`python -m simbench ARGS` in `cwd`, and how long it took (s)."""
    start = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "simbench", *args], capture_output=True, text=True, cwd=cwd,
                          check=False, timeout=timeout)
    return proc, time.monotonic() - start


# --- size and interruption -----------------------------------------------------------------------------------------

_LOAD = max(1.0, os.getloadavg()[0] / (os.cpu_count() or 1))  # the bounds below stretched on a busy machine

def test_a_million_bodies_is_refused_within_five_seconds(tmp_path):
    """Before: `inspect` ran past 600 s at 2.5 GB and answered neither SIGTERM nor Ctrl-C."""
    _planar3r(tmp_path, _bodies(1000, 1000))
    proc, took = _command(["inspect", str(_scenario(tmp_path, "arm.xml"))], tmp_path)
    assert proc.returncode == 2 and took < 5 * _LOAD, (took, proc.stderr)
    assert proc.stderr.count("\n") == 1 and "robot.model: arm.xml: loading it would need about" in proc.stderr
    assert "1,000,005 bodies" in proc.stderr and "more than the" in proc.stderr


@pytest.mark.parametrize("signum, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_model_mujoco_reads_long_stops_within_a_second_of_a_signal(tmp_path, signum, code):
    """12,000 bodies side by side, which MuJoCo's reader takes tens of seconds over (and passes the size check):
    SIGTERM or Ctrl-C while it reads ends the command at once. Before: only when MuJoCo was done."""
    bodies = "".join(f'<body pos="{i * 0.001} 0 1"><geom contype="0" conaffinity="0" size="0.01"/></body>'
                     for i in range(12000))
    _planar3r(tmp_path, bodies)
    started = time.monotonic()
    sent = []

    def ready() -> bool:  # imports done and the model surveyed: MuJoCo is reading it
        if time.monotonic() - started < 5:
            return False
        sent.append(time.monotonic())
        return True

    proc = interrupt([sys.executable, "-m", "simbench", "inspect", str(_scenario(tmp_path, "arm.xml"))], ready,
                     tmp_path, signum=signum)
    assert proc.returncode == code and proc.stderr.strip() == "interrupted", proc.stderr
    assert time.monotonic() - sent[0] < 1.0 * _LOAD


def test_bodies_past_mujocos_arena_are_given_room(tmp_path, capsys):
    """3,000 bodies: MuJoCo's collision buffers (an int per body pair) overflow the arena it sizes itself. Before:
    `internal error: FatalError: mj_stackAlloc: out of memory`."""
    _planar3r(tmp_path, _bodies(3, 1000))
    assert main(["inspect", str(_scenario(tmp_path, "arm.xml"))]) == 0
    assert "planar3r: 3 joints" in capsys.readouterr().out


def test_a_sparse_mesh_file_is_refused_before_mujoco_reads_it(tmp_path, capsys):
    """A 2,047 MiB STL of no bytes on disk (its header says no triangle). Before: 2.1 GB and up to 22 s."""
    mesh = tmp_path / "huge.stl"
    with open(mesh, "wb") as file:
        file.truncate(2047 * 2**20)
    text = PLANAR3R.read_text().replace("<asset>", '<asset>\n    <mesh name="huge" file="huge.stl"/>')
    _planar3r(tmp_path, '<geom type="mesh" mesh="huge" contype="0" conaffinity="0"/>', text=text)
    started = time.monotonic()
    err = _refused(capsys, ["inspect", str(_scenario(tmp_path, "arm.xml"))])
    assert time.monotonic() - started < 2
    assert "robot.model: arm.xml: mesh 'huge.stl': a binary STL of 0 triangles is 84 bytes" in err


# --- files a model names ------------------------------------------------------------------------------------------

def _in_subprocess(tmp_path: Path, args: list[str]) -> str:
    """The one line a refusing command prints, run where a hang would not hang the suite."""
    proc, _ = _command(args, tmp_path, timeout=60)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and not proc.stdout, proc.stderr
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    return proc.stderr.strip()


def test_an_included_fifo_is_refused_not_waited_on(tmp_path):
    """Before: `inspect` blocked for ever in MuJoCo's read."""
    os.mkfifo(tmp_path / "part.xml")
    text = PLANAR3R.read_text().replace("<worldbody>", '<worldbody>\n    <include file="part.xml"/>')
    _planar3r(tmp_path, text=text)
    err = _in_subprocess(tmp_path, ["inspect", str(_scenario(tmp_path, "arm.xml"))])
    assert "robot.model: arm.xml: <include> file='part.xml': not a regular file (a FIFO)" in err


def test_a_fifo_mesh_is_refused_not_waited_on(tmp_path):
    os.mkfifo(tmp_path / "part.stl")
    text = PLANAR3R.read_text().replace("<asset>", '<asset>\n    <mesh name="part" file="part.stl"/>')
    _planar3r(tmp_path, '<geom type="mesh" mesh="part" contype="0" conaffinity="0"/>', text=text)
    err = _in_subprocess(tmp_path, ["inspect", str(_scenario(tmp_path, "arm.xml"))])
    assert "robot.model: arm.xml: mesh 'part.stl': not a regular file (a FIFO)" in err


def test_a_model_that_is_a_fifo_is_not_a_regular_file(tmp_path):
    """Before: 'no such file'."""
    os.mkfifo(tmp_path / "arm.xml")
    err = _in_subprocess(tmp_path, ["validate", str(_scenario(tmp_path, "arm.xml"))])
    assert "robot.model: not a regular file (a FIFO)" in err


def test_an_included_folder_is_refused_in_one_line_and_no_mujoco_log(tmp_path):
    """Before: two lines on stderr, and MUJOCO_LOG.TXT in the working folder."""
    (tmp_path / "parts").mkdir()
    text = PLANAR3R.read_text().replace("<worldbody>", '<worldbody>\n    <include file="parts"/>')
    _planar3r(tmp_path, text=text)
    err = _in_subprocess(tmp_path, ["inspect", str(_scenario(tmp_path, "arm.xml"))])
    assert "<include> file='parts': not a regular file (a folder)" in err


def test_symlink_loops_and_nul_bytes_are_bad_input(tmp_path, capsys):
    """Before: `RuntimeError: Symlink loop` and `ValueError: embedded null byte`, internal errors (exit 1)."""
    _planar3r(tmp_path)
    (tmp_path / "loop.xml").symlink_to(tmp_path / "loop.xml")
    assert "robot.model: a symlink loop" in _refused(capsys, ["inspect", str(_scenario(tmp_path, "loop.xml"))])
    nul = _scenario(tmp_path, '"arm\\0.xml"')
    assert "robot.model: expected a path without a NUL byte" in _refused(capsys, ["validate", str(nul)])
    packages = _scenario(tmp_path, "arm.xml", '  packages: {toy: "to\\0y"}\n')
    assert "robot.packages: toy: expected a path without a NUL byte" in _refused(capsys, ["validate", str(packages)])
    robot_file = tmp_path / "robot.yaml"
    robot_file.write_text('robot: "robot\\0.yaml"\nplanner: joint_move\ntask: {start: [0, 0, 0], goal: [1, 1, 1]}\n')
    assert "robot: expected a path without a NUL byte" in _refused(capsys, ["validate", str(robot_file)])
    # a sweep's variants name their models through anchored, which no longer raises for a loop
    assert anchored({"model": "loop.xml"}, tmp_path)["model"] == str(tmp_path / "loop.xml")


def test_units_a_robot_file_states_are_checked(tmp_path, capsys):
    """Before: a pydantic ValidationError, an internal error."""
    _planar3r(tmp_path)
    (tmp_path / "arm.yaml").write_text("model: arm.xml\ntool: {site: tool}\nspeed_limits: [180, 360, 360]\n"
                                       "units: {angle: furlong}\n")
    scenario = tmp_path / "move.yaml"
    scenario.write_text("robot: arm.yaml\nplanner: joint_move\nunits: {angle: deg}\n"
                        "task: {start: [90, -90, -60], goal: [30, -60, -30]}\ntiming: {duration: 1.0}\n")
    err = _refused(capsys, ["validate", str(scenario)])
    assert err.startswith(f"error: {tmp_path / 'arm.yaml'}: units.angle:") and "furlong" in err


def test_inspect_refuses_a_symlink_loop_and_bad_units_in_one_line(tmp_path, capsys):
    """`inspect MODEL` on a symlink loop, and on a robot file or scenario whose units are no units."""
    (tmp_path / "loop.xml").symlink_to(tmp_path / "loop.xml")
    assert "symlink loop" in _refused(capsys, ["inspect", str(tmp_path / "loop.xml")])
    _planar3r(tmp_path)
    for name, text in (("arm.yaml", "model: arm.xml\ntool: {site: tool}\n"),
                       ("move.yaml", "robot: {model: arm.xml, tool: {site: tool}}\nplanner: joint_move\n")):
        (tmp_path / name).write_text(text + "units: {angle: furlong}\n")
        assert "units.angle:" in _refused(capsys, ["inspect", str(tmp_path / name)])


# --- numbers and XML ----------------------------------------------------------------------------------------------

def _urdf(folder: Path, lower="-2", upper="2", effort="5", velocity="2", xyz="0 0 0.3", axis="0 1 0", mass="1",
          joint="j", head="") -> Path:
    """A 2-link URDF, its numbers as given."""
    links = ""
    for i in (1, 2):
        links += f"""
  <joint name="{joint}{i}" type="revolute"><parent link="l{i - 1}"/><child link="l{i}"/>
    <origin xyz="{xyz if i == 2 else '0 0 0.5'}"/><axis xyz="{axis}"/>
    <limit lower="{lower}" upper="{upper}" effort="{effort}" velocity="{velocity}"/></joint>
  <link name="l{i}">
    <inertial><mass value="{mass}"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 0.15"/><geometry><box size="0.05 0.05 0.2"/></geometry></collision>
  </link>"""
    path = folder / "toy.urdf"
    path.write_text(f'{head}<robot name="toy"><link name="l0"/>{links}\n</robot>\n')
    return path


def _urdf_scenario(folder: Path, goal: str = "[40, 30]") -> Path:
    path = folder / "move.yaml"
    path.write_text("robot: {model: toy.urdf, tool: {body: l2, offset: [0, 0, 0.3]}}\nplanner: joint_move\n"
                    f"units: {{angle: deg}}\ntask: {{start: [0, 0], goal: {goal}}}\ntiming: {{duration: 1.0}}\n")
    return path


@pytest.mark.parametrize("numbers, expected", [
    ({"lower": "nan", "upper": "0.1"}, "<joint name='j1'> <limit> lower='nan': expected finite numbers"),
    ({"effort": "nan"}, "<joint name='j1'> <limit> effort='nan': expected finite numbers"),
    ({"velocity": "inf"}, "<joint name='j1'> <limit> velocity='inf': expected finite numbers"),
    ({"velocity": "1e308"}, "joint 'j1' <limit velocity>: expected a number from 0 to 1e+06, got '1e308'"),
    ({"effort": "-5"}, "joint 'j1' <limit effort>: expected a number from 0 to 1e+06, got '-5'"),
    ({"lower": "1", "upper": "-1"}, "joint 'j1' <limit>: lower 1 is above upper -1: expected lower <= upper"),
    ({"xyz": "nan 0 0.3"}, "<joint name='j2'> <origin> xyz='nan 0 0.3': expected finite numbers"),
    ({"xyz": "1e20 0 0.3"}, "<origin> xyz='1e20 0 0.3': expected numbers of at most 1e+06 in magnitude"),
    ({"axis": "0 inf 0"}, "<joint name='j1'> <axis> xyz='0 inf 0': expected finite numbers"),
    ({"mass": "1e308"}, "<link name='l1'> <mass> value='1e308': expected numbers of at most 1e+06 in magnitude"),
    ({"joint": "a&b"}, "toy.urdf: not well-formed XML: not well-formed (invalid token) (line 2, column 20)"),
    ({"head": '<!DOCTYPE r [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">]>'},
     "toy.urdf line 1: a document type declaration (<!DOCTYPE ...>): simbench reads no DTD or entities"),
    ({"head": '<!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]>'}, "a document type declaration"),
])
def test_urdf_numbers_are_checked_naming_the_element(tmp_path, capsys, monkeypatch, numbers, expected):
    """Before: NaN made a joint continuous or its force unlimited, inf or 1e308 a speed limit, a NaN or huge origin
    an exit 1 after MuJoCo's and Python's warnings, and XML MuJoCo reads an internal error (exit 1)."""
    monkeypatch.chdir(tmp_path)
    _urdf(tmp_path, **numbers)
    err = _refused(capsys, ["validate", str(_urdf_scenario(tmp_path))])
    assert "move.yaml: robot.model: toy.urdf" in err and expected in err
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_a_nan_in_an_mjcf_is_refused_naming_the_element(tmp_path, capsys, monkeypatch):
    """Before: MuJoCo's warning on stdout and MUJOCO_LOG.TXT left in the working folder."""
    monkeypatch.chdir(tmp_path)
    _planar3r(tmp_path, text=PLANAR3R.read_text().replace('<body name="link2" pos="0.4 0 0.04">',
                                                          '<body name="link2" pos="0.4 nan 0.04">'))
    err = _refused(capsys, ["inspect", str(_scenario(tmp_path, "arm.xml"))])
    assert err.endswith("robot.model: arm.xml: <body name='link2'> pos='0.4 nan 0.04': expected finite numbers")
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_mujocos_errors_are_said_whole(tmp_path, capsys):
    """Before: the line ended at MuJoCo's colon ('URDF body has multiple parents:')."""
    (tmp_path / "toy.urdf").write_text(
        '<robot name="toy"><link name="a"/><link name="b"/><link name="c"/>'
        '<joint name="j1" type="revolute"><parent link="a"/><child link="c"/><axis xyz="0 0 1"/></joint>\n'
        '<joint name="j2" type="revolute"><parent link="b"/><child link="c"/><axis xyz="0 0 1"/></joint></robot>')
    err = _refused(capsys, ["validate", str(_urdf_scenario(tmp_path))])
    assert err.endswith("URDF body has multiple parents: Element 'joint', line 2")


def test_a_good_urdf_still_runs(tmp_path, capsys):
    _urdf(tmp_path)
    assert main(["validate", str(_urdf_scenario(tmp_path))]) == 0


# --- caches -------------------------------------------------------------------------------------------------------

def test_an_edited_model_is_read_anew_by_the_same_process(tmp_path):
    """The upper arm 0.4 -> 0.2 m (the file's size unchanged) between two loads. Before: the second load ran the
    first model (the derived arm and its compiled scene were cached by the path)."""
    model = _planar3r(tmp_path)
    scenario = _scenario(tmp_path, "arm.xml")
    reaches = []
    for length in ("0.4", "0.2"):
        model.write_text(PLANAR3R.read_text().replace('<body name="link2" pos="0.4 0 0.04">',
                                                      f'<body name="link2" pos="{length} 0 0.04">'))
        robot = simbench.load_scenario(scenario).robot_def
        compiled = compiled_scene(str(robot.scene))
        reaches.append((robot.fk(np.zeros((1, 3)))[0, 0], compiled.body("link2").pos[0]))
    np.testing.assert_allclose(reaches, [(0.9, 0.4), (0.7, 0.2)], atol=1e-12)


def test_a_sweep_over_robot_model_names_a_loop_and_a_nul_byte_as_bad_input_rows(tmp_path, capsys):
    """Before: `RuntimeError: Symlink loop` (or `ValueError: embedded null byte`) aborted the whole sweep."""
    _planar3r(tmp_path)
    (tmp_path / "loop.xml").symlink_to(tmp_path / "loop.xml")
    _scenario(tmp_path, "arm.xml")
    sweep = tmp_path / "models.yaml"
    sweep.write_text('base: move.yaml\ngrid:\n  robot.model: [arm.xml, loop.xml, "a\\0.xml"]\n')
    assert main(["sweep", str(sweep), "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "-> bad_input: robot.model: a symlink loop" in out
    assert "-> bad_input: robot.model: expected a path without a NUL byte" in out
    assert out.count("bad_input") == 2


def test_a_bench_suite_naming_a_symlink_loop_is_bad_input(tmp_path, capsys):
    """Before: `internal error: RuntimeError: Symlink loop` (exit 1)."""
    (tmp_path / "loop.xml").symlink_to(tmp_path / "loop.xml")
    suite = tmp_path / "suite.yaml"
    suite.write_text("robots:\n  - {name: mine, model: loop.xml, tool: {site: tool}, speed_limits: [3, 3, 3]}\n"
                     "tasks: 2\n")
    err = _refused(capsys, ["bench", str(suite), "--out", str(tmp_path / "out")])
    assert err.endswith("suite.yaml: robots[0].model: a symlink loop (too many levels of symbolic links)")


def test_xml_nested_past_mujocos_depth_and_a_file_included_twice_are_one_line(tmp_path, capsys):
    """Before: 'XML parse error 18:' and 'XML Error: File ... already included', each cut at its colon."""
    _planar3r(tmp_path, "<body>" * 600 + "</body>" * 600)
    err = _refused(capsys, ["validate", str(_scenario(tmp_path, "arm.xml"))])
    assert "robot.model: arm.xml line " in err and "elements nested more than 500 deep" in err
    (tmp_path / "part.xml").write_text("<mujoco><body/></mujoco>")
    _planar3r(tmp_path, '<include file="part.xml"/><include file="part.xml"/>')
    err = _refused(capsys, ["validate", str(_scenario(tmp_path, "arm.xml"))])
    assert err.endswith("robot.model: arm.xml: <include> file='part.xml': already included")
