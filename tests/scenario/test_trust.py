"""Small leaks of trust (project issue 33, finding 7): what a file or a name holds cannot recolour the terminal,
name a folder outside the rule, follow a symlinked --out into a stray link, or leave folders behind a refused
run; an unknown field always says what the mapping takes."""

import copy
import os

import pytest
import yaml

from simbench.cli import main
from simbench.core.errors import ScenarioError
from simbench.scenario import parse_scenario
from tests.conftest import SHIPPED, scenario_file

ESCAPES = "\x1b[31mRED\x1b[0m\x07\x1b]0;title\x07"


def _scenario(tmp_path, name="line.yaml", **changes):
    doc = yaml.safe_load(scenario_file("puma600", "line").read_text())
    doc.update(changes)
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.mark.parametrize("command", ["run", "compare", "validate"])
def test_control_characters_from_a_file_are_printed_escaped(tmp_path, capsys, command):
    path = _scenario(tmp_path, description=f"a seam {ESCAPES} here")
    out = tmp_path / f"o{ESCAPES}ut"
    args = {"run": ["run", str(path), "--no-video", "--out", str(out)],
            "compare": ["compare", str(path), "--planners", "decoupled_path", "--quiet", "--out", str(out)],
            "validate": ["validate", str(path)]}[command]
    assert main(args) == 0
    printed = capsys.readouterr()
    assert not any(c in printed.out + printed.err for c in "\x1b\x07")
    if command != "validate":
        assert "\\x1b[31m" in printed.out  # shown, escaped


@pytest.mark.parametrize("stem", ["..", ".", "<b>bold", "a b", "-rf", "x" * 101])
@pytest.mark.parametrize("command", ["run", "sweep", "compare"])
def test_a_name_taken_from_the_file_is_held_to_the_name_rule(tmp_path, monkeypatch, capsys, stem, command):
    monkeypatch.chdir(tmp_path)
    path = _scenario(tmp_path, name=f"{stem}.yaml")
    if command == "sweep":
        (tmp_path / "s.yaml").write_text(yaml.safe_dump({"base": path.name, "grid": {"timing.duration": [2, 3]}}))
        args = ["sweep", "s.yaml", "--workers", "1"]
    else:
        args = {"run": ["run", f"./{path.name}", "--no-video"],
                "compare": ["compare", f"./{path.name}", "--planners", "decoupled_path"]}[command]
    before = sorted(tmp_path.rglob("*"))
    assert main(args + ["--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and ": name: not given, and the file's name cannot stand in for it" in err[0]
    assert sorted(tmp_path.rglob("*")) == before  # nothing written, renders/ itself included


def test_a_sweep_files_own_name_is_held_to_the_rule(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    _scenario(tmp_path)
    (tmp_path / "..yaml").write_text(yaml.safe_dump({"base": "line.yaml", "grid": {"timing.duration": [2, 3]}}))
    assert main(["sweep", "..yaml", "--workers", "1", "--quiet"]) == 2
    assert "name: not given" in capsys.readouterr().err
    assert not (tmp_path / "renders").exists()


def test_a_name_field_lets_any_file_name_run(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = _scenario(tmp_path, name="..yaml", name_field=None)
    doc = yaml.safe_load(path.read_text())
    doc.pop("name_field")
    doc["name"] = "seam"
    path.write_text(yaml.safe_dump(doc))
    assert main(["run", "..yaml", "--no-video", "--quiet"]) == 0
    assert (tmp_path / "renders" / "seam" / "report.json").is_file()
    assert not (tmp_path / "renders" / "report.json").exists()


@pytest.mark.parametrize("force", [False, True])
def test_an_out_that_is_a_symlink_to_a_folder_writes_into_that_folder(tmp_path, capsys, force):
    target = tmp_path / "target"
    target.mkdir()
    link = tmp_path / "link"
    link.symlink_to(target)
    args = ["run", str(scenario_file("spherical_arm", "case1")), "--out", str(link), "--no-video", "--quiet"]
    assert main(args) == 0
    if force:
        assert main(args + ["--force"]) == 0
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert (target / "report.json").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link", "target"]  # no stray .link.old-<pid>


def test_a_refused_run_leaves_no_folder_it_made(tmp_path, capsys):
    path = tmp_path / "case4_printed.yaml"
    doc = yaml.safe_load(scenario_file("spherical_arm", "case1").read_text())
    doc["task"].update({"start": [300, 0, 80, 30], "goal": [47, 400, -75, 100]})
    doc.pop("expect", None)
    path.write_text(yaml.safe_dump(doc))
    assert main(["run", str(path), "--out", str(tmp_path / "a" / "b" / "out"), "--no-video", "--quiet"]) == 1
    assert "run failed" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == [path]


def _mappings(node, where=()):
    """Every mapping in a document, with where it is."""
    if isinstance(node, dict):
        yield where, node
        for key, value in node.items():
            yield from _mappings(value, (*where, key))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from _mappings(value, (*where, i))


@pytest.mark.parametrize("path", SHIPPED, ids=[f"{p.parent.name}/{p.stem}" for p in SHIPPED])
def test_an_unknown_field_anywhere_in_a_shipped_scenario_says_what_the_mapping_takes(path):
    document = yaml.safe_load(path.read_text())
    for where, _ in list(_mappings(document)):
        doc = copy.deepcopy(document)
        node = doc
        for key in where:
            node = node[key]
        node["lnie"] = 1
        with pytest.raises(ScenarioError) as caught:
            parse_scenario(doc, str(path))
        if caught.value.message.startswith("unknown field"):
            assert "expected one of: )" not in caught.value.message
            assert "expected one of: " in caught.value.message, (where, caught.value.message)


@pytest.mark.parametrize("raised", [SystemExit(0), SystemExit(3), SystemExit("bye"), KeyboardInterrupt()],
                         ids=["exit0", "exit3", "exit-text", "KeyboardInterrupt"])
def test_an_exit_raised_by_outside_code_simbench_calls_is_a_failed_run(monkeypatch, capsys, raised):
    """An outside planner, robot or controller calling sys.exit (or raising KeyboardInterrupt) where no policy
    guard stands: exit 1 and one line, never exit 0 with nothing said, nor 'interrupted'."""
    from simbench.commands import pipeline

    def plan_that_exits(*args, **kwargs):
        raise raised

    monkeypatch.setattr(pipeline, "check_plan", plan_that_exits)
    assert main(["validate", str(scenario_file("puma600", "line"))]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"run failed: outside code simbench called raised "
                                               f"{type(raised).__name__}")


def test_comparison_csv_quotes_text_a_spreadsheet_would_run_and_leaves_numbers():
    """comparison.csv as results.csv: a method's error text starting '=' is written after a single quote (OWASP's
    advice on CSV injection), a negative figure stays a number; Python's csv module reads both back."""
    import csv
    import io

    from simbench.commands.compare import table_csv

    rows = ({"method": "a", "status": "run_failed", "error": '=HYPERLINK("http://127.0.0.1:1","x")'},
            {"method": "b", "status": "ok", "error": "", "tool_error_max_m": -0.5})
    table = list(csv.DictReader(io.StringIO(table_csv(rows))))
    assert table[0]["error"] == "'" + rows[0]["error"]
    assert table[1]["tool_error_max_m"] == "-0.5" and float(table[1]["tool_error_max_m"]) == -0.5
