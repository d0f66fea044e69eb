"""The package's import graph has no cycles. Every ``import`` and ``from … import`` of a
thermonet module counts, at module level or inside a function (imports placed in functions to
dodge a cycle still make one), except those under ``if TYPE_CHECKING:`` (never executed). An
edge goes to the module named, or to the submodule a ``from package import name`` names; a
package's ``__init__`` is an edge only where it is imported by name. Any cycle fails: break it by
moving the shared piece into the lower module (or by passing it in), not by moving the import
into a function."""

import ast
import os

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE = "thermonet"


def _modules() -> dict:
    out = {}
    for base, dirs, files in os.walk(os.path.join(ROOT, PACKAGE)):
        dirs[:] = [d for d in dirs if d != "__pycache__"]
        for f in files:
            if f.endswith(".py"):
                name = os.path.relpath(os.path.join(base, f), ROOT)[:-3].replace(os.sep, ".")
                out[name.removesuffix(".__init__")] = os.path.join(base, f)
    return out


def _type_checking_only(tree) -> set:
    """ids of the import nodes under ``if TYPE_CHECKING:``."""
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for child in node.body:
                skip |= {id(n) for n in ast.walk(child)}
    return skip


def _imports(name: str, path: str, modules: dict) -> set:
    def known(target):
        while target not in modules and "." in target:
            target = target.rsplit(".", 1)[0]
        return target

    with open(path, encoding="utf-8") as f:
        tree = ast.parse(f.read())
    skip = _type_checking_only(tree)
    here = name if path.endswith("__init__.py") else name.rsplit(".", 1)[0]
    out = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            out |= {known(a.name) for a in node.names if a.name.split(".")[0] == PACKAGE}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = here.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1])
                target = f"{base}.{node.module}" if node.module else base
            else:
                target = node.module or ""
            if target.split(".")[0] != PACKAGE:
                continue
            for a in node.names:
                sub = f"{target}.{a.name}"
                out.add(sub if sub in modules else known(target))
    out.discard(name)
    return out


def import_graph() -> dict:
    modules = _modules()
    return {name: _imports(name, path, modules) for name, path in modules.items()}


def cycles(graph: dict) -> list:
    """The strongly connected components of more than one module (Tarjan), each a set."""
    index, low, stack, on, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in graph:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(component)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_package_has_no_import_cycle():
    graph = import_graph()
    found = [sorted(c) for c in cycles(graph)]
    assert not found, "import cycles: " + "; ".join(
        " ↔ ".join(c) + " (" + ", ".join(f"{v} → {w}" for v in c for w in sorted(graph[v]) if w in c) + ")"
        for c in found)


def test_the_graph_sees_function_level_imports_and_cycles():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert cycles(graph) == [{"a", "b", "c"}]
    assert "thermonet.io.convert" in import_graph()["thermonet.net"]  # inside Net.to_meshio
    assert "thermonet.stability" in import_graph()["thermonet.blowup"]  # inside remedy
