"""simbench's optional parts and the extra that installs each (`pip install 'simbench[ompl]'`). What needs one that
is not installed is refused in one line naming the extra, as bad input (exit 2), before it runs where that can be
known: the core (a run, validate, a sweep on processes, compare, reproduce, the dm_control environments) needs none.
"""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType

from simbench.core.errors import ScenarioError

# The module simbench imports -> (the extra that installs it, the package's name as its users know it).
EXTRAS: dict[str, tuple[str, str]] = {
    "ompl": ("ompl", "OMPL"),
    "mink": ("mink", "mink"),
    "ray": ("ray", "Ray"),
    "pyarrow": ("pyarrow", "pyarrow"),
    "sklearn": ("train", "scikit-learn"),
    "gymnasium": ("rl", "Gymnasium"),
    "shimmy": ("rl", "Shimmy"),
}

# simbench's own planners that need an extra, for `simbench list`: planner -> (the module, the part of the planner
# that needs it; None: the planner itself). Each refuses without it where it plans (tests/core/test_extras.py); the
# table
# is held to the planners' calls of require and missing by tests/commands/test_reliability_round4.py.
PLANNERS: dict[str, tuple[str, str | None]] = {
    "avoidance_4567": ("ompl", "its global search in SO(3)"),
    "cartesian_path": ("mink", "its mink method"),
    "mink_baseline": ("mink", None),
}


class MissingExtra(ScenarioError):
    """An optional package not installed (or failing to import): what needs it, and the extra that installs it."""

    def __init__(self, source: str, field: str | None, module: str, needs: str, problem: str = "is not installed"):
        self.module = module
        super().__init__(source, field, words(module, needs, problem))


def words(module: str, needs: str, problem: str = "is not installed") -> str:
    """'<needs> needs OMPL, which is not installed: pip install 'simbench[ompl]''."""
    extra, package = EXTRAS[module]
    return f"{needs} needs {package}, which {problem}: pip install 'simbench[{extra}]'"


def installed(module: str) -> bool:
    """Whether `module` can be found, without importing it (an import of it may still fail: `require`)."""
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):  # blocked (None in sys.modules, or an import hook's refusal)
        return False


def missing(module: str, needs: str) -> str | None:
    """What to say where `module` is not installed (`words`), or None where it is; imports nothing."""
    return None if installed(module) else words(module, needs)


def require(module: str, needs: str, source: str = "simbench", field: str | None = None) -> ModuleType:
    """`module`, imported; MissingExtra (a ScenarioError naming `source` and `field`) where it cannot be."""
    try:
        return importlib.import_module(module)
    except ImportError as err:
        absent = isinstance(err, ModuleNotFoundError) and (err.name or module).partition(".")[0] == module
        problem = "is not installed" if absent else f"fails to import ({type(err).__name__}: {err})"
        raise MissingExtra(source, field, module, needs, problem) from None


def mark(planner: str) -> str | None:
    """What `simbench list` says of a planner that needs an extra (PLANNERS): 'its mink method needs mink,
    installed' or '..., not installed: pip install 'simbench[mink]''; None for one that needs none."""
    if planner not in PLANNERS:
        return None
    module, part = PLANNERS[planner]
    extra, package = EXTRAS[module]
    state = "installed" if installed(module) else f"not installed: pip install 'simbench[{extra}]'"
    return f"{part + ' ' if part else ''}needs {package}, {state}"
