"""Every trial of the fault list has a test that holds it (marked ``@trial("ID")``)."""

from __future__ import annotations

import ast
from pathlib import Path

SECTIONS = {"1": 18, "2": 29, "3": 4, "4": 9, "5": 5, "N": 15}
TRIALS = {f"{section}.{i}" for section, count in SECTIONS.items() for i in range(1, count + 1)}


def marked_trials() -> dict[str, list[str]]:
    """Trial id -> the tests marked with it, read from the test files' decorators."""
    found: dict[str, list[str]] = {}
    for path in Path(__file__).parents[1].rglob("test_*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.FunctionDef) or not node.name.startswith("test"):
                continue
            for decorator in node.decorator_list:
                call = decorator if isinstance(decorator, ast.Call) else None
                name = call and (call.func.attr if isinstance(call.func, ast.Attribute)
                                 else getattr(call.func, "id", None))
                if call and name == "trial":
                    for arg in call.args:
                        if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
                            found.setdefault(arg.value, []).append(f"{path.name}::{node.name}")
    return found


def test_every_fault_trial_has_a_test():
    marked = marked_trials()
    assert len(TRIALS) == 80
    assert sorted(TRIALS - set(marked)) == []
    assert sorted(set(marked) - TRIALS) == []  # no mark names a trial that is not on the list
