"""One direction of imports (project issues 34 and 49): no simbench module imports another that imports it back, and
no stage folder imports a later stage, counting imports inside functions and by name (`importlib.import_module`:
every literal naming a module), not counting those under `typing.TYPE_CHECKING` (annotations only, never run);
simbench's own plugins load through entry points, as an outside package's do; the module paths before the stage
folders still import, with a warning."""

import ast
import importlib
import importlib.metadata
import sys
import warnings
from pathlib import Path

import pytest

import simbench
from simbench.api import registry
from simbench.core.moved import MOVED

PACKAGE = Path(simbench.__file__).parent


def _modules() -> dict[str, Path]:
    """Every module of the package by dotted name (a package by its own name)."""
    found = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        found[".".join(parts)] = path
    return found


MODULES = _modules()


def _module_of(name: str) -> str | None:
    """The module a dotted name lies in (a name inside a module: the module)."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def _type_checking_only(tree: ast.AST) -> set[ast.AST]:
    """The nodes under `if TYPE_CHECKING:` (or typing.TYPE_CHECKING)."""
    skipped = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for inner in node.body:
                skipped.update(ast.walk(inner))
    return skipped


def _imported(name: str, path: Path) -> set[str]:
    """The simbench modules module `name` (at `path`) imports, anywhere in its code."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skipped = _type_checking_only(tree)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    targets = []
    for node in ast.walk(tree):
        if node in skipped:
            continue
        if isinstance(node, ast.Import):
            targets += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(parent + ([base] if base else []))
            # `from simbench import api` imports the module simbench.api; `from simbench.api import Robot` that module
            targets += [f"{base}.{alias.name}" if f"{base}.{alias.name}" in MODULES else base for alias in node.names]
    if "import_module" in ast.unparse(tree):  # imports by name: every literal that names a simbench module
        targets += [node.value for node in ast.walk(tree) if isinstance(node, ast.Constant)
                    and isinstance(node.value, str) and node.value in MODULES and node.value != "simbench"]
    return {m for t in targets if t.startswith("simbench") and (m := _module_of(t)) and m != name}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    return found


def test_the_graph_sees_imports_inside_functions_and_by_name():
    """The finder itself: a function-level import and an import by name both count."""
    graph = {name: _imported(name, path) for name, path in MODULES.items()}
    assert "simbench.api" in graph["simbench.planners.joint_move"]
    assert "simbench.commands.pipeline" in graph["simbench"]  # the package's lazy names, by import_module
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_simbench_module_imports_another_that_imports_it_back():
    graph = {name: _imported(name, path) for name, path in MODULES.items()}
    assert _cycles(graph) == []


def test_the_public_api_is_a_leaf_of_simbench_s_own_modules():
    """simbench.api imports no plugin and nothing that imports it."""
    graph = {name: _imported(name, path) for name, path in MODULES.items()}
    closure: set[str] = set()
    todo = list(graph["simbench.api"])
    while todo:
        m = todo.pop()
        if m not in closure:
            closure.add(m)
            todo += graph[m]
    assert not any(m.startswith(("simbench.robots", "simbench.planners", "simbench.api.registry")) for m in closure)
    assert "simbench.api" not in closure


def test_simbench_s_own_plugins_load_through_its_entry_points():
    """Each shipped robot, planner and controller is an entry point of the simbench distribution, and the
    registry's object by that name is the one the entry point loads."""
    kinds = {"simbench.robots": registry.robots(), "simbench.planners": registry.planners(),
             "simbench.controllers": registry.controllers(), "simbench.metrics": registry.metrics()}
    for group, objects in kinds.items():
        own = [ep for ep in importlib.metadata.entry_points(group=group) if ep.dist and ep.dist.name == "simbench"]
        assert own, group
        for ep in own:
            assert objects[ep.name] is ep.load()
            assert registry.origin(group.split(".")[1].rstrip("s"), ep.name) == "simbench"
    assert {"spherical_arm", "puma600", "agile_eye", "rsmg"} <= set(kinds["simbench.robots"])
    assert {"servo", "computed_torque", "policy"} <= set(kinds["simbench.controllers"])
    assert "tracking" in kinds["simbench.metrics"]


STAGES = ("core", "maths", "api", "robots", "scenario", "planners", "physics", "analysis", "outputs", "commands")
"""simbench's folders in the pipeline's order (docs/architecture.md): a module imports its own folder's modules and
those of the folders before it, never a later one's. What a user imports stands above them all: TOP."""
TOP = ("simbench", "simbench.__main__", "simbench.cli", "simbench.env")


def _stage(module: str) -> int:
    """A module's place in the order: its folder's index in STAGES, or past them all for TOP."""
    if module in TOP or module.startswith("simbench.env."):
        return len(STAGES)
    return STAGES.index(module.split(".")[1])


def test_every_module_lies_in_a_stage_folder_or_is_what_a_user_imports():
    """A new module or folder must be given its place (outside the stages only the package's face, the CLI and
    simbench.env)."""
    unplaced = [m for m in MODULES if not (m in TOP or m.startswith("simbench.env.") or m.split(".")[1] in STAGES)]
    assert not unplaced


def test_each_stage_imports_only_itself_and_the_stages_before_it():
    graph = {name: _imported(name, path) for name, path in MODULES.items()}
    against = sorted(f"{m} -> {t}" for m, targets in graph.items() for t in targets if _stage(t) > _stage(m))
    assert not against, "imports against the stages' order: " + "; ".join(against)


def test_the_direction_test_sees_a_later_stage_imported_inside_a_function(tmp_path):
    """The check itself: a physics module importing the outputs inside a function is against the order."""
    module = tmp_path / "late.py"
    module.write_text("def f():\n    from simbench.outputs import plots\n", encoding="utf-8")
    imported = _imported("simbench.physics.late", module)
    assert imported == {"simbench.outputs.plots"}
    assert _stage("simbench.outputs.plots") > _stage("simbench.physics.late")


@pytest.mark.parametrize("old", sorted(MOVED))
def test_a_module_path_from_before_the_stage_folders_imports_with_a_warning(old):
    """The old path gives the very module at its new path, and a DeprecationWarning naming that path."""
    new = importlib.import_module(f"simbench.{MOVED[old]}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sys.modules.pop(f"simbench.{old}", None)
        assert importlib.import_module(f"simbench.{old}") is new
    assert any(issubclass(w.category, DeprecationWarning) and f"simbench.{MOVED[old]}" in str(w.message)
               for w in caught)
