"""The documentation site: it builds with warnings as errors, its API reference lists every public name of
simbench.api, and nothing the repository holds points at a file outside it."""

import html
import importlib.util
import inspect
import re
import subprocess
import sys
from pathlib import Path

import pytest

import simbench
import simbench.api

ROOT = Path(__file__).resolve().parents[2]
# Where the repository once pointed outside itself (the project's shared design notes and paper notes): what they
# said that users need is now in docs/ (a paper's errata: docs/papers/<paper>.md, section "Errata").
OUTSIDE = re.compile(r"\.\./shared|NOTES\.md|DESIGN\.md")


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> tuple[Path, subprocess.CompletedProcess]:
    """The site built once, as a user or CI builds it (mkdocs.yml's `strict: true`, and --strict besides)."""
    if importlib.util.find_spec("mkdocs") is None or importlib.util.find_spec("mkdocstrings_handlers") is None:
        pytest.skip("mkdocs and mkdocstrings-python are not installed (pip install -e '.[docs]')")
    out = tmp_path_factory.mktemp("site")
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(out)], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)
    return out, done


def test_the_site_builds_without_a_warning(site):
    _, done = site
    output = done.stdout + done.stderr
    assert done.returncode == 0, output
    assert "WARNING" not in output, output


def test_the_api_reference_lists_every_public_name_of_simbench_api(site):
    out, done = site
    assert done.returncode == 0, done.stdout + done.stderr
    page = (out / "reference" / "api" / "index.html").read_text(encoding="utf-8")
    missing = [name for name in simbench.api.__all__ if f'id="simbench.api.{name}"' not in page]
    assert not missing, f"simbench.api names without an entry in the reference: {missing}"


def test_a_long_signature_is_shown_a_parameter_a_line(site):
    """mkdocstrings formats signatures with ruff (the docs extra): simbench.run's seven parameters each on a line of
    its own, as `inspect.signature` names them, not one line too long to read."""
    out, done = site
    assert done.returncode == 0, done.stdout + done.stderr
    page = (out / "reference" / "simbench" / "index.html").read_text(encoding="utf-8")
    signatures = [html.unescape(re.sub(r"<[^>]+>", "", block))
                  for block in re.findall(r'<div class="doc-signature[^>]*>(.*?)</div>', page, re.S)]
    run = next(text for text in signatures if text.startswith("run("))
    names = list(inspect.signature(simbench.run).parameters)
    lines = run.strip().splitlines()
    assert [line.strip().split(":")[0] for line in lines[1:-1]] == names, run


def _tracked_text_files() -> list[tuple[Path, str]]:
    """The repository's tracked files that are text, with their text (one that is not UTF-8 is data)."""
    names = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, text=True, check=True)
    found = []
    for name in filter(None, names.stdout.split("\0")):
        path = ROOT / name
        try:
            found.append((path, path.read_text(encoding="utf-8")))
        except (UnicodeDecodeError, FileNotFoundError, IsADirectoryError):
            continue
    return found


def test_nothing_tracked_refers_to_a_file_outside_the_repository():
    if not (ROOT / ".git").exists():
        pytest.skip("not a git checkout: the tracked files are not known")
    this = Path(__file__).resolve()
    found = [f"{path.relative_to(ROOT)}:{n}: {line.strip()}"
             for path, text in _tracked_text_files() if path.resolve() != this
             for n, line in enumerate(text.splitlines(), 1) if OUTSIDE.search(line)]
    assert not found, "references to files outside the repository:\n" + "\n".join(found)
