"""The code's shape the trackers are held to: small functions, no silenced type checks.

The dual tracker's functions stay at cyclomatic complexity 10 or below (radon's count, which
adds every boolean operator), every tracker function at 60 lines of code or fewer (docstring,
comments and blank lines aside), and no ``type: ignore`` in the dual tracker.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import pipeline

PACKAGE = Path(pipeline.__file__).parent
TRACKERS = PACKAGE / "trackers"
DUAL = TRACKERS / "dual"


def _functions(path: Path):
    tree = ast.parse(path.read_text())
    lines = path.read_text().splitlines()
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            yield node, lines[node.lineno - 1 : node.end_lineno]


def _code_lines(node: ast.FunctionDef | ast.AsyncFunctionDef, src: list[str]) -> int:
    """Lines of code of a function, its ``def`` line included: not blank, not a comment, not
    its docstring."""
    doc = 0
    first = node.body[0]
    if isinstance(first, ast.Expr) and isinstance(getattr(first, "value", None), ast.Constant):
        if isinstance(first.value.value, str):
            doc = first.end_lineno - first.lineno + 1
    return sum(1 for s in src if s.strip() and not s.strip().startswith("#")) - doc


def test_no_tracker_function_over_60_lines():
    long = [
        f"{p.relative_to(PACKAGE)}:{n.lineno} {n.name} ({_code_lines(n, src)})"
        for p in sorted(TRACKERS.rglob("*.py"))
        for n, src in _functions(p)
        if _code_lines(n, src) > 60
    ]
    assert long == []


def test_the_line_count_sees_a_long_function(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(61))
    f = tmp_path / "m.py"
    f.write_text(f'def f():\n    """Doc."""\n    # note\n\n{body}\n')
    ((node, src),) = _functions(f)
    assert _code_lines(node, src) == 62


def test_the_complexity_count_sees_boolean_operators():
    radon = pytest.importorskip("radon.complexity")
    conds = " and ".join(f"a{i}" for i in range(11))
    (block,) = radon.cc_visit(
        f"def f({', '.join(f'a{i}' for i in range(11))}):\n    return {conds}\n"
    )
    assert block.complexity == 11


def test_dual_tracker_functions_at_complexity_10_or_below():
    radon = pytest.importorskip("radon.complexity")
    over = [
        f"{p.relative_to(PACKAGE)}:{b.lineno} {b.fullname} ({b.complexity})"
        for p in sorted(DUAL.rglob("*.py"))
        for b in radon.cc_visit(p.read_text())
        if b.complexity > 10
    ]
    assert over == []


def test_no_type_ignore_in_the_dual_tracker():
    found = [
        f"{p.relative_to(PACKAGE)}:{k}"
        for p in sorted(DUAL.rglob("*.py"))
        for k, line in enumerate(p.read_text().splitlines(), 1)
        if "type: ignore" in line
    ]
    assert found == []
