"""The package's shape: no import circle between its modules, counting the imports inside
functions too (``lint-imports`` checks the layers; a circle within a layer passes it)."""

from __future__ import annotations

import ast
import re
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


# ----- error messages name the flags the help shows --------------------------------------------
# Flags of other programs that the fixes quote (``hf download ... --local-dir``).
OTHER_PROGRAMS = frozenset({"--local-dir"})
_FLAG = re.compile(r"(?<![\w-])--[a-z][a-z0-9.-]*[a-z0-9]")


def shown_flags() -> set[str]:
    """Every option some ``efficienteqa`` command's help shows (``--help``, or ``--help-all``
    for the constants; hidden aliases left out)."""
    import typer

    import efficienteqa.cli  # noqa: F401 - registers the commands
    from efficienteqa.cli.app import app
    from efficienteqa.cli.options import HELP_ALL_PANELS

    shown = {"--help"}

    def walk(command: object) -> None:
        for p in getattr(command, "params", ()):
            panel = str(getattr(p, "rich_help_panel", "") or "")
            if not getattr(p, "hidden", False) or panel.endswith(HELP_ALL_PANELS):
                shown.update(n for n in (*p.opts, *getattr(p, "secondary_opts", ()))
                             if n.startswith("--"))
        for sub in getattr(command, "commands", {}).values():
            walk(sub)

    walk(typer.main.get_command(app))
    return shown


def message_flags(package: Path = PACKAGE) -> dict[str, set[str]]:
    """{flag: {file:line}} of every flag named in what a user reads of an error: the strings of
    ``raise`` statements, of ``EfficientEQAError(...)`` calls, of ``fix=`` and ``flag=``
    arguments, and the defaults of fields and parameters named ``flag``."""
    out: dict[str, set[str]] = {}
    for path in package.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            parts: list[ast.AST] = []
            if isinstance(node, ast.Raise):
                parts.append(node)
            elif isinstance(node, ast.Call):
                name = getattr(node.func, "id", None) or getattr(node.func, "attr", None)
                if name == "EfficientEQAError":
                    parts.append(node)
                parts += [k.value for k in node.keywords if k.arg in ("fix", "flag")]
            elif (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)
                  and node.target.id == "flag" and node.value is not None):
                parts.append(node.value)
            elif isinstance(node, ast.arguments):
                named = [*node.posonlyargs, *node.args][-len(node.defaults):] if node.defaults else []
                parts += [d for a, d in zip(named, node.defaults) if a.arg == "flag"]
                parts += [d for a, d in zip(node.kwonlyargs, node.kw_defaults)
                          if a.arg == "flag" and d is not None]
            for part in parts:
                for s in ast.walk(part):
                    if isinstance(s, ast.Constant) and isinstance(s.value, str):
                        for flag in _FLAG.findall(s.value):
                            out.setdefault(flag, set()).add(
                                f"{path.relative_to(package.parent)}:{s.lineno}")
    return out


def test_error_messages_name_only_flags_the_help_shows():
    """An error's fix must name the dotted flag (``--backends.perception``), never a hidden
    flat alias (``--perception``) or a flag that is gone; a section's name (``--explore.sfe``)
    counts where the help shows flags under it."""
    shown = shown_flags()

    def known(flag: str) -> bool:
        return (flag in shown or flag in OTHER_PROGRAMS
                or any(s.startswith(flag + ".") for s in shown))

    hidden = {flag: sorted(where) for flag, where in message_flags().items() if not known(flag)}
    assert hidden == {}


def test_the_message_scan_sees_a_hidden_flag_in_a_fix(tmp_path):
    package = tmp_path / "efficienteqa"
    package.mkdir()
    (package / "m.py").write_text('raise EfficientEQAError("bad", fix="use --perception rgb")\n'
                                  'class B:\n    flag: str = "--vlm"\n'
                                  'def f(flag="--judge"):\n    pass\n')
    assert message_flags(package) == {"--perception": {"efficienteqa/m.py:1"},
                                      "--vlm": {"efficienteqa/m.py:3"},
                                      "--judge": {"efficienteqa/m.py:4"}}
    assert "--perception" not in shown_flags() and "--backends.perception" in shown_flags()


def test_the_constants_leave_ask_help_for_help_all():
    from typer.testing import CliRunner

    from efficienteqa.cli import app

    runner = CliRunner()
    short = runner.invoke(app, ["ask", "--help"], env={"COLUMNS": "250"})
    full = runner.invoke(app, ["ask", "--help-all"], env={"COLUMNS": "250"})
    assert short.exit_code == full.exit_code == 0
    assert "--stop.z-th" in short.output and "--explore.target.glance" not in short.output
    assert "--explore.target.glance" in full.output and "--explore.sfe." in full.output
    assert "--backends.image-format" not in short.output  # a server's fine print
    assert "--backends.image-format" in full.output
    assert len(short.output.splitlines()) <= 90 < len(full.output.splitlines())
