"""Every trial of the fault list (docs/fault-trials.md) has a test that holds it (marked
``@trial("ID")``), and every mark names a trial of that list."""

from __future__ import annotations

import ast
import re
from pathlib import Path

SECTIONS = {"1": 18, "2": 29, "3": 4, "4": 9, "5": 5, "N": 15, "R6": 61}
TRIALS = {f"{section}.{i}" for section, count in SECTIONS.items() for i in range(1, count + 1)}
LIST = Path(__file__).parents[2] / "docs" / "fault-trials.md"


def listed_trials() -> list[str]:
    """The ids of the rows of the fault list's tables, in order."""
    return re.findall(r"^\| ((?:R6|[1-5N])\.\d+) \|", LIST.read_text(), flags=re.MULTILINE)


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


def test_the_fault_list_holds_each_trial_once():
    listed = listed_trials()
    assert len(listed) == len(set(listed)) == 141
    assert set(listed) == TRIALS


def test_every_fault_trial_has_a_test():
    marked = marked_trials()
    assert sorted(TRIALS - set(marked)) == []
    assert sorted(set(marked) - TRIALS) == []  # no mark names a trial that is not on the list
