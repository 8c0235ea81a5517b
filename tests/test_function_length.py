"""No function in ``repro/`` is longer than MAX_LINES lines unless a ``# long:`` comment right above
it (above its decorators) says why: a function a reader takes in at once is one a newcomer can
change in one place."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "repro"
MAX_LINES = 60


def long_functions(path: Path) -> list[str]:
    """``path:line name (lines)`` of each function over MAX_LINES lines (its docstring included)
    without a ``# long:`` line in the comment block right above it."""
    source = path.read_text()
    lines = source.splitlines()
    found = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        length = node.end_lineno - node.lineno + 1
        if length <= MAX_LINES:
            continue
        above = min([node.lineno, *(d.lineno for d in node.decorator_list)]) - 2  # 0-based
        reasons = []
        while above >= 0 and lines[above].strip().startswith("#"):
            reasons.append(lines[above].strip())
            above -= 1
        if not any(r.startswith("# long:") for r in reasons):
            found.append(f"{path.name}:{node.lineno} {node.name} ({length} lines)")
    return found


def test_no_function_is_long_without_saying_why():
    assert [f for path in sorted(ROOT.rglob("*.py")) for f in long_functions(path)] == []


def test_the_check_sees_a_long_function_and_its_reason(tmp_path):
    body = "".join(f"    x = {i}\n" for i in range(MAX_LINES))
    module = tmp_path / "m.py"
    module.write_text(f"@staticmethod\ndef f():\n{body}\n\ndef g():\n{body[:-10]}\n")
    assert [f.split()[1] for f in long_functions(module)] == ["f"]
    module.write_text(f"# a table, row by row\n# long: one row per piece\n@staticmethod\n"
                      f"def f():\n{body}")
    assert long_functions(module) == []
