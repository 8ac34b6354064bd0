"""The size budgets of fidlearn's code, kept true by a test (CONTRIBUTING.md, "Budgets").

One concept per file and functions a newcomer can read in one screen: no module over
``MAX_MODULE_LINES`` lines, no function body over ``MAX_FUNCTION_LINES`` lines (its docstring not
counted: numpydoc sections are wanted, not penalised), and no function above radon's rank C
(cyclomatic complexity over ``MAX_COMPLEXITY``). A file or function that outgrows them is split by
concept, never exempted here.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from radon.complexity import cc_visit

PACKAGE = Path(__file__).resolve().parents[1] / "fidlearn"
MAX_MODULE_LINES = 500
MAX_FUNCTION_LINES = 60
MAX_COMPLEXITY = 20  # radon's rank C is 11-20

MODULES = sorted(PACKAGE.rglob("*.py"))


def _rel(path: Path) -> str:
    return path.relative_to(PACKAGE.parent).as_posix()


def _functions(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node


def _docstring_lines(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    first = node.body[0]
    if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
        return first.end_lineno - first.lineno + 1
    return 0


def function_lines(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Lines from ``def`` (decorators excluded) to the function's last line, less its docstring."""
    return node.end_lineno - node.lineno + 1 - _docstring_lines(node)


def test_the_budget_counts_what_it_says():
    src = 'def f(x):\n    """Doc.\n\n    More.\n    """\n    y = x\n    return y\n'
    (node,) = _functions(ast.parse(src))
    assert function_lines(node) == 3  # def, y = x, return y
    (block,) = cc_visit("def g(a, b):\n    if a and b:\n        return 1\n    for _ in a:\n        pass\n")
    assert block.complexity == 4  # 1 + if + and + for: radon's count


def test_modules_are_found():
    assert len(MODULES) > 20
    assert PACKAGE / "__init__.py" in MODULES


@pytest.mark.parametrize("path", MODULES, ids=_rel)
def test_module_within_budget(path):
    n = len(path.read_text(encoding="utf-8").splitlines())
    assert n <= MAX_MODULE_LINES, f"{_rel(path)} has {n} lines (budget {MAX_MODULE_LINES}): split it by concept"


@pytest.mark.parametrize("path", MODULES, ids=_rel)
def test_functions_within_budget(path):
    source = path.read_text(encoding="utf-8")
    too_long = [
        f"{node.name} (line {node.lineno}): {function_lines(node)} lines"
        for node in _functions(ast.parse(source))
        if function_lines(node) > MAX_FUNCTION_LINES
    ]
    too_complex = [
        f"{block.fullname} (line {block.lineno}): complexity {block.complexity}"
        for block in cc_visit(source)
        if block.complexity > MAX_COMPLEXITY
    ]
    assert not too_long, f"{_rel(path)}: over {MAX_FUNCTION_LINES} lines: {'; '.join(too_long)}"
    assert not too_complex, f"{_rel(path)}: over radon rank C ({MAX_COMPLEXITY}): {'; '.join(too_complex)}"
