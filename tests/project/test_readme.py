"""The README's set-up commands are what CI runs, and they name things that exist."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def commands() -> list[str]:
    lines = (ROOT / "README.md").read_text().splitlines()
    return [line.strip() for line in lines[:14] if line.startswith(("    python3 -m venv", "    (command -v"))]


def test_readme_starts_with_the_two_setup_commands():
    run, test = commands()
    assert "-m simbench run scenarios/" in run
    assert "-m pytest" in test


def test_the_readme_test_command_installs_the_pinned_test_environment():
    """The tests (and CI) run on the exact versions constraints.txt pins."""
    test = commands()[1]
    assert "pip install -q -c constraints.txt -e '.[test]' -e examples/planar3r" in test
    assert (ROOT / "constraints.txt").is_file()


def test_ci_runs_the_readme_test_command_verbatim():
    assert commands()[1] in (ROOT / ".ci" / "run").read_text().splitlines()


def test_readme_run_command_names_a_shipped_scenario():
    scenario = commands()[0].split("simbench run ")[1].split()[0]
    assert (ROOT / scenario).is_file()
