"""The package's shape: no import circle between its modules, counting the imports inside
functions too (``lint-imports`` checks the layers; a circle within a layer passes it)."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = SRC / "efficienteqa"


def _module(path: Path, src: Path) -> str:
    return ".".join(path.relative_to(src).with_suffix("").parts).removesuffix(".__init__")


def _imports(path: Path, known: set[str]) -> set[str]:
    """The package's modules ``path`` imports anywhere in it (``from a import b`` counts as
    ``a.b`` where that is a module, else ``a``)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for alias in node.names:
                full = f"{node.module}.{alias.name}"
                out.add(full if full in known else node.module)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return out & known


def import_circles(package: Path = PACKAGE) -> list[list[str]]:
    """Each set of modules that import one another round a circle (Tarjan's strongly
    connected components of more than one module, or a module importing itself)."""
    files = {_module(p, package.parent): p for p in package.rglob("*.py")}
    known = set(files)
    graph = {m: _imports(p, known) - {m} for m, p in files.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    circles: list[list[str]] = []

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
                circles.append(sorted(component))

    for module in sorted(graph):
        if module not in index:
            visit(module)
    return circles


def test_no_module_imports_its_way_back_to_itself():
    assert import_circles() == []


def test_the_circle_finder_finds_a_circle_through_a_function_level_import(tmp_path):
    package = tmp_path / "efficienteqa"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("from efficienteqa import b\n")
    (package / "b.py").write_text("def f():\n    from efficienteqa import a\n")
    (package / "c.py").write_text("from efficienteqa import a\n")
    assert import_circles(package) == [["efficienteqa.a", "efficienteqa.b"]]
