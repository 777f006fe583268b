"""Bad scenarios: exit 2 with one line naming the file, the field and what is expected; a path the method
cannot repair: exit 1 with the reason. Neither leaves an output folder behind.

The corpus in bad_scenarios/ holds one file per way to get a scenario wrong, and EXPECTED.txt the exact line
each must give; hypothesis then fuzzes the loader with random text and with shipped scenarios broken at random.
"""

import math
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from simbench.cli import main
from simbench.core.resources import sweeps_dir
from tests.conftest import SHIPPED

CORPUS = Path(__file__).parents[1] / "bad_scenarios"
EXPECTED = dict(line.split(": ", 1) for line in (CORPUS / "EXPECTED.txt").read_text().splitlines()
                if line and not line.startswith("#"))

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


PUMA = {
    "robot": "puma600",
    "planner": "decoupled_path",
    "units": {"angle": "deg", "length": "mm"},
    "task": {"path": [{"line": {"start": [450, -350, -300], "end": [650, 150, -300]}}],
             "orientation": {"convention": "zyx", "value": [0, 180, 0]},
             "configuration": {"wrist": "flip"}},
    "timing": {"law": "quintic", "duration": 1.0},
}
def puma(**task):
    doc = yaml.safe_load(yaml.safe_dump(PUMA))
    doc["task"].update(task)
    return yaml.safe_dump(doc)


def run_cli(args, capsys):
    code = main(args)
    captured = capsys.readouterr()
    return code, captured.err.strip().splitlines()


def test_missing_file(tmp_path, capsys):
    code, lines = run_cli(["validate", str(tmp_path / "nope.yaml")], capsys)
    assert code == 2 and lines == [f"error: {tmp_path / 'nope.yaml'}: no such file"]


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


def test_validate_checks_every_file_after_a_bad_one(tmp_path, capsys):
    """validate FILE ... checks each file: one bad file is its line and the next files are still checked; the
    exit code is 2 if any file is bad input, else 1 if any plan is refused."""
    unrepairable = tmp_path / "unrepairable.yaml"
    unrepairable.write_text(variant(task={"start": [300, 0, 80, 30], "goal": [47, 400, -75, 100]}))
    good, nan, huge = SHIPPED[0], CORPUS / "nan.yaml", CORPUS / "huge.yaml"
    code = main(["validate", str(nan), str(unrepairable), str(good), str(huge)])
    out, err = capsys.readouterr()
    assert code == 2
    assert [line.split(": ")[:2] for line in err.strip().splitlines()] == [
        ["error", str(nan)], ["run failed", "the straight path leaves the workspace and the new initial q3 of Fig. 8 "
                                            "cannot repair it"], ["error", str(huge)]]
    assert out.startswith(f"{good}: valid")
    assert main(["validate", "--no-plan", str(good), str(unrepairable)]) == 0
    assert main(["validate", str(unrepairable), str(good)]) == 1


def test_real_command_line_prints_no_traceback(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text(variant(task__start=[120, 500, 120, 5]))
    proc = subprocess.run([sys.executable, "-m", "simbench", "run", str(path)], capture_output=True, text=True,
                          cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert proc.stdout == ""


def test_corpus_has_a_message_for_every_file():
    assert sorted(p.stem for p in CORPUS.glob("*.yaml")) == sorted(EXPECTED)
    assert len(EXPECTED) >= 40


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_corpus_file_gives_its_one_line_and_exit_2(name, tmp_path, capsys):
    path = CORPUS / f"{name}.yaml"
    for command in (["validate", str(path)], ["run", str(path), "--out", str(tmp_path / "out"), "--quiet"]):
        code, lines = run_cli(command, capsys)
        assert (code, lines) == (2, [f"error: {path}: {EXPECTED[name]}"])
        assert not (tmp_path / "out").exists()


_leaf = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6), st.floats(allow_nan=True),
                  st.text(max_size=12), st.sampled_from(["deg", "mm", "zyx", "quat", "line", "arc", "1e5", ".nan"]))
_value = st.recursive(_leaf, lambda inner: st.one_of(st.lists(inner, max_size=5),
                                                    st.dictionaries(st.text(max_size=8), inner, max_size=4)),
                      max_leaves=12)


def _paths(node, here=()):
    """Every place in a document: (path, value)."""
    yield here, node
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, here + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, here + (i,))


def _validate_text(text: str, capsys, command=("validate", "--no-plan")) -> tuple[int, list[str], str]:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzz.yaml"
        path.write_text(text)
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # a warning would be a second line on stderr
            code, lines = run_cli([command[0], str(path), *command[1:]], capsys)
        return code, lines, str(path)


def _assert_clean(code: int, lines: list[str], path: str) -> None:
    """Valid (exit 0, nothing on stderr) or bad input (exit 2, one line naming the file); never a traceback."""
    assert code in (0, 2), lines
    if code == 2:
        assert len(lines) == 1 and lines[0].startswith(f"error: {path}: "), lines
    else:
        assert lines == []


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.text(max_size=300))
def test_fuzz_random_text_never_escapes(text, capsys):
    code, lines, path = _validate_text(text, capsys)
    _assert_clean(code, lines, path)
    assert code == 2  # no random text is a scenario


def _break(doc, data, value, action):
    """The document with one place replaced by `value`, deleted, or given `value` as an extra field or item."""
    places = [p for p, _ in _paths(doc)]
    where = data.draw(st.sampled_from(places[1:]))
    parent = doc
    for part in where[:-1]:
        parent = parent[part]
    if action == "replace":
        parent[where[-1]] = value
    elif action == "delete":
        del parent[where[-1]]
    elif isinstance(parent, dict):
        parent[data.draw(st.text(min_size=1, max_size=8))] = value
    else:
        parent.append(value)
    return doc


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(base=st.sampled_from(sorted(sweeps_dir().glob("*.yaml"))), data=st.data(), value=_value,
       action=st.sampled_from(["replace", "delete", "add"]))
def test_fuzz_broken_shipped_sweeps_never_escape(base, data, value, action, capsys):
    doc = _break(yaml.safe_load(base.read_text()), data, value, action)
    code, lines, path = _validate_text(yaml.safe_dump(doc, allow_unicode=True), capsys, ("sweep", "--dry-run"))
    _assert_clean(code, lines, path)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(base=st.sampled_from(SHIPPED), data=st.data(), value=_value,
       action=st.sampled_from(["replace", "delete", "add"]))
def test_fuzz_broken_shipped_scenarios_never_escape(base, data, value, action, capsys):
    """A shipped scenario with one place replaced by a random value, deleted, or given a random extra field:
    still valid, or refused with one line; never a traceback."""
    doc = _break(yaml.safe_load(base.read_text()), data, value, action)
    text = yaml.safe_dump(doc, allow_unicode=True)
    code, lines, path = _validate_text(text, capsys)
    _assert_clean(code, lines, path)
    if action == "replace" and isinstance(value, float) and not math.isfinite(value) and code == 2:
        assert "finite" in lines[0] or "expected" in lines[0]
