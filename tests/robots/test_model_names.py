"""Names from a model reach the outputs as text, never as markup or terminal control (issue 45, item 7): a planar
arm whose model and joint names hold ESC, BEL, CR, a line break, `<script>`, '|' and a mathtext formula is run,
inspected and compared through the command line; every SVG parses as XML, stderr holds no control byte, stdout
no forged line, comparison.md no raw HTML and no split row, and each name is still there, escaped."""

import csv
import re
import subprocess
import sys
from xml.etree import ElementTree

import pytest

MODEL_NAME = "arm&#10;error: fake model line"  # as MJCF writes a line break
# Each joint's name as MJCF writes it (character references) and as MuJoCo reads it.
JOINTS = [("a&#27;[31mred", "a\x1b[31mred"),
          ("b&#7;bell&#13;cr $\\frac$", "b\x07bell\rcr $\\frac$"),
          ("c&#10;error: fake second line &lt;script&gt;alert(1)&lt;/script&gt; |x|",
           "c\nerror: fake second line <script>alert(1)</script> |x|")]
CONTROL = re.compile(r"[\x00-\x09\x0b-\x1f\x7f-\x9f]")  # every C0 and C1 control character but the line feed
FORGED = re.compile(r"^\s*error:", re.MULTILINE)


def _arm(folder):
    """A planar 3R arm (the planar3r example's links) with the hazardous names, and a joint_move scenario on it."""
    (a, _), (b, _), (c, _) = JOINTS
    body = """<inertial pos="{com} 0 0" mass="0.5" diaginertia="1e-4 5e-3 5e-3"/>
        <joint name="{name}" type="hinge" axis="0 0 1" range="-3 3" damping="0.05" armature="0.01"/>"""
    (folder / "arm.xml").write_text(f"""<mujoco model="{MODEL_NAME}">
  <compiler angle="radian" autolimits="true"/>
  <worldbody>
    <body name="link1" pos="0 0 0.3">{body.format(com=0.2, name=a)}
      <body name="link2" pos="0.4 0 0">{body.format(com=0.15, name=b)}
        <body name="link3" pos="0.3 0 0">{body.format(com=0.1, name=c)}
          <site name="tool" pos="0.2 0 0"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
""")
    path = folder / "move.yaml"
    path.write_text("robot: {model: arm.xml, tool: {site: tool}, speed_limits: [180, 360, 360]}\n"
                    "planner: joint_move\nunits: {angle: deg}\n"
                    "task: {start: [90, -90, -60], goal: [80, -80, -50]}\ntiming: {duration: 0.2, hold: 0.05}\n")
    return path


def _simbench(*args, cwd):
    return subprocess.run([sys.executable, "-P", "-m", "simbench", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300, check=False)


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    """run (--quiet), compare (two methods, with progress) and inspect of the arm: their processes and folder."""
    folder = tmp_path_factory.mktemp("names")
    scenario = _arm(folder)
    run = _simbench("run", str(scenario), "--out", "run", "--no-video", "--plot-format", "svg", "--quiet", cwd=folder)
    compared = _simbench("compare", str(scenario), "--planners", "joint_move", "--controllers",
                         "servo,computed_torque", "--out", "compare", "--plot-format", "svg", cwd=folder)
    inspected = _simbench("inspect", str(scenario), cwd=folder)
    for done in (run, compared, inspected):
        assert done.returncode == 0, done.stderr
    return {"run": run, "compare": compared, "inspect": inspected}, folder


def test_every_svg_plot_is_well_formed_xml(outputs):
    _, folder = outputs
    plots = sorted(folder.glob("*/plots/*.svg"))
    assert {p.parent.parent.name for p in plots} == {"run", "compare"} and len(plots) >= 7
    for plot in plots:
        ElementTree.parse(plot)  # raises ParseError on a raw control character


def test_stderr_holds_no_control_byte(outputs):
    done, _ = outputs
    for command in ("run", "compare", "inspect"):
        assert not CONTROL.search(done[command].stderr), (command, done[command].stderr)
        assert "Glyph" not in done[command].stderr


def test_stdout_of_inspect_and_compare_forges_no_line_and_shows_each_name_escaped(outputs):
    done, _ = outputs
    for command in ("inspect", "compare"):
        out = done[command].stdout
        assert not CONTROL.search(out) and not FORGED.search(out), out
        assert "a\\x1b[31mred" in out and "b\\x07bell\\rcr" in out and "c\\nerror: fake second line" in out
    assert done["inspect"].stdout.startswith("arm\\nerror: fake model line: 3 joints from ")


def _cells(row: str) -> list[str]:
    """A Markdown table row's cells, split at each '|' that no backslash escapes (GitHub's rule)."""
    cells, cell, escaped = [], "", False
    for c in row.strip()[1:-1]:
        if c == "|" and not escaped:
            cells.append(cell)
            cell = ""
        else:
            cell += c
        escaped = c == "\\" and not escaped
    return [*cells, cell]


def test_comparison_md_holds_names_as_text_in_whole_rows(outputs):
    _, folder = outputs
    text = (folder / "compare" / "comparison.md").read_text()
    assert "<script" not in text and not CONTROL.search(text)
    rows = [line for line in text.splitlines() if line.startswith("|")]
    header = len(_cells(rows[0]))
    assert header == 3 and all(len(_cells(row)) == header for row in rows), rows
    joint_rows = [row for row in rows if "speed peak (deg/s)" in row]
    assert [_cells(row)[0].strip() for row in joint_rows] == [
        "a\\x1b[31mred speed peak (deg/s)", "b\\x07bell\\rcr $\\\\frac$ speed peak (deg/s)",
        "c\\nerror: fake second line &lt;script&gt;alert(1)&lt;/script&gt; \\|x\\| speed peak (deg/s)"]
    assert "Robot arm\\nerror: fake model line." in text


def test_comparison_csv_keeps_the_names_exact(outputs):
    """CSV is data: each name exact (quoted where it holds a line break), every row as long as the header."""
    _, folder = outputs
    with open(folder / "compare" / "comparison.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert len(rows) == 3 and {len(row) for row in rows} == {len(rows[0])}
    assert [c for c in rows[0] if c.startswith("qd_peak_")] == [f"qd_peak_{name}" for _, name in JOINTS]
