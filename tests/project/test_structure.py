"""Small modules (project issue 34): no module of simbench is over 500 lines; a module that grows past it holds
several things, and becomes a package split by what it holds (as simbench.analysis did)."""

from pathlib import Path

import simbench

PACKAGE = Path(simbench.__file__).parent
MOST_LINES = 500


def test_no_simbench_module_is_over_500_lines():
    long = {str(path.relative_to(PACKAGE)): n for path in sorted(PACKAGE.rglob("*.py"))
            if (n := len(path.read_text(encoding="utf-8").splitlines())) > MOST_LINES}
    assert not long, f"modules over {MOST_LINES} lines: {long}"
