"""One direction of imports (project issue 34): no simbench module imports another that imports it back, counting
imports inside functions and by name (`importlib.import_module`: every literal naming a module), not counting
those under `typing.TYPE_CHECKING` (annotations only, never run); and simbench's own plugins load through entry
points, as an outside package's do."""

import ast
import importlib.metadata
from pathlib import Path

import simbench
from simbench import registry

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
                    and isinstance(node.value, str) and node.value in MODULES]
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
    assert "simbench.pipeline" in graph["simbench"]  # the package's lazy names, by import_module
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
    assert not any(m.startswith(("simbench.robots", "simbench.planners", "simbench.registry")) for m in closure)
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
