"""Every concrete simbench command the README and the docs show runs as written, from the root of a fresh copy of
the repository, with its default output folders (project issue 33: `sweep` and `reproduce` once failed on the
relative paths they chose themselves, while every test passed absolute ones)."""

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from importlib.metadata import distribution
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
PREFIXES = ("python -m simbench ", "python -P -m simbench ", "simbench ")
# A synopsis, not a command: placeholders in capitals, optional or alternative parts, an ellipsis.
PLACEHOLDER = re.compile(r"\b[A-Z][A-Z_]+\b|[\[\]{}|<>]|\.\.\.|\bA,B\b")
# What a command writes by default, from the root, found in its words: where to look for it.
WRITES = {"run": "renders/{name}/report.json", "sweep": "renders/sweeps/{name}/results.csv",
          "compare": "renders/compare/{name}/comparison.csv", "reproduce": "renders/reproduce/{name}/summary.md",
          "bench": "renders/bench/{name}/leaderboard.csv"}


def shown_commands() -> list[str]:
    """The commands of the docs' code blocks (indented or fenced lines) and inline code that are concrete."""
    found = []
    for doc in DOCS:
        text = doc.read_text(encoding="utf-8")
        candidates = [line.strip() for line in text.splitlines() if line.startswith("    ")]
        candidates += [line.strip() for line in _shell_fenced_lines(text)]
        candidates += re.findall(r"`([^`\n]+)`", text)
        for command in candidates:
            if command.startswith(PREFIXES) and not PLACEHOLDER.search(command) and command not in found \
                    and _complete(command):
                found.append(command)
    return found


def _shell_fenced_lines(text: str) -> list[str]:
    """The lines inside fenced blocks of shell (or unnamed) language: fences are paired in order, so the prose
    between a closing fence and the next opening one is never taken for a block."""
    lines, shell, inside = [], False, False
    for line in text.splitlines():
        fence = re.match(r"\s*```(\w*)", line)
        if fence:
            inside = not inside
            shell = inside and fence.group(1) in ("", "sh", "bash", "shell", "console")
        elif inside and shell:
            lines.append(line)
    return lines


def _complete(command: str) -> bool:
    """Whether the command says what to act on (`simbench run` named in the prose is not a command to run)."""
    words = command.split("simbench ", 1)[1].split()
    return words[0] == "list" or len(words) > 1


COMMANDS = shown_commands()


def test_the_readme_shows_each_command_concretely():
    verbs = {c.split("simbench ", 1)[1].split()[0] for c in COMMANDS}
    assert {"run", "sweep", "validate", "reproduce", "compare", "list"} <= verbs, COMMANDS


@pytest.fixture(scope="module")
def fresh_root(tmp_path_factory) -> Path:
    """A copy of the repository's tracked data (what a fresh clone holds that a command reads) with no outputs, and
    the link `erd` to example-robot-data's share folder that docs/tutorial-your-urdf.md has the reader make."""
    root = tmp_path_factory.mktemp("clone")
    for folder in ("scenarios", "sweeps", "models", "examples", "docs/tutorial"):
        shutil.copytree(ROOT / folder, root / folder, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    (root / "erd").symlink_to(distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data"))
    return root


def _argv(command: str) -> list[str]:
    """The command's words, with `python` this interpreter and `simbench` the console script installed beside it."""
    words = shlex.split(command)
    if words[0] == "python":
        return [sys.executable, *words[1:]]
    script = Path(sys.executable).with_name("simbench")
    return [str(script), *words[1:]] if script.exists() else [sys.executable, "-P", "-m", "simbench", *words[1:]]


@pytest.mark.parametrize("command", COMMANDS)
def test_a_shown_command_runs_as_written_from_the_root(fresh_root, command):
    words = command.split("simbench ", 1)[1].split()
    verb = words[0]
    done = subprocess.run(_argv(command), cwd=fresh_root, capture_output=True, text=True, timeout=300,
                          env={**os.environ, "MUJOCO_GL": "egl"})
    assert done.returncode == 0, (command, done.stdout[-2000:], done.stderr[-2000:])
    assert "Traceback" not in done.stderr and "internal error" not in done.stderr
    if verb in WRITES and "--out" not in words:
        target = words[1]
        name = target if verb == "reproduce" else Path(target).stem
        if verb == "run":
            name = _scenario_name(fresh_root / target)
        written = fresh_root / WRITES[verb].format(name=name)
        assert written.is_file(), (command, sorted(p.relative_to(fresh_root).as_posix()
                                                   for p in (fresh_root / "renders").rglob("*")))
        if verb == "run":
            assert json.loads(written.read_text())["status"] in ("ok", "limits")


def _scenario_name(path: Path) -> str:
    """The name a run's default folder takes: the scenario's `name:` if it has one, else the file's stem."""
    import yaml

    document = yaml.safe_load(path.read_text())
    return document.get("name") or path.stem


@pytest.mark.parametrize("command, written", [
    ("python -m simbench reproduce 000 --out mine/papers", "mine/papers/000/index.html"),
    ("python -m simbench sweep sweeps/spherical_arm_timestep.yaml --out mine/sweep --workers 1",
     "mine/sweep/index.html"),
    ("python -m simbench compare scenarios/puma600/line.yaml --planners decoupled_path,mink_baseline "
     "--out mine/compare", "mine/compare/index.html"),
])
def test_a_relative_out_folder_is_relative_to_the_working_folder(fresh_root, command, written):
    done = subprocess.run(_argv(command), cwd=fresh_root, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, (command, done.stderr[-2000:])
    assert (fresh_root / written).is_file()
    assert not list((fresh_root / "mine").rglob("mine")), "the output folder was joined onto itself"
