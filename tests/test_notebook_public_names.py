"""No notebook reaches into fidlearn's private parts.

The course teaches the public API and plain OpenCV: a learner who copies a cell into their own
robot's code must get something that keeps working. Every code cell of every notebook (the
course, the exercises and their answer keys) and of every notebook source is parsed, and any
``fidlearn._x`` module or ``_name`` imported from fidlearn, or an attribute ``_x`` read from a
fidlearn module, fails the test with the notebook and the line.
"""

from __future__ import annotations

import ast
import json
from pathlib import Path

import pytest

from fidlearn.data import repo_dir

NOTEBOOKS = sorted((repo_dir() / "notebooks").rglob("*.ipynb"))
SOURCES = sorted((repo_dir() / "notebooks" / "src").glob("*.py"))


def _code_cells(path: Path) -> list[str]:
    if path.suffix == ".py":
        return [path.read_text(encoding="utf-8")]
    nb = json.loads(path.read_text(encoding="utf-8"))
    return ["".join(c["source"]) for c in nb["cells"] if c["cell_type"] == "code"]


def _private(part: str) -> bool:
    return part.startswith("_") and not (part.startswith("__") and part.endswith("__"))


def private_uses(code: str) -> list[str]:
    """Each use of a private fidlearn name in ``code``, as ``"line N: what"``."""
    code = "\n".join("pass" if line.lstrip().startswith(("%", "!")) else line for line in code.splitlines())
    tree = ast.parse(code)
    modules: set[str] = set()  # local names bound to fidlearn or one of its modules
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "fidlearn":
                    if any(_private(p) for p in alias.name.split(".")):
                        found.append(f"line {node.lineno}: import {alias.name}")
                    modules.add(alias.asname or "fidlearn")
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "fidlearn":
            if any(_private(p) for p in node.module.split(".")):
                found.append(f"line {node.lineno}: from {node.module} import ...")
            for alias in node.names:
                if _private(alias.name):
                    found.append(f"line {node.lineno}: from {node.module} import {alias.name}")
                modules.add(alias.asname or alias.name)
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Attribute)
            and _private(node.attr)
            and isinstance(node.value, ast.Name)
            and node.value.id in modules
        ):
            found.append(f"line {node.lineno}: {node.value.id}.{node.attr}")
    return found


def test_the_check_sees_private_names():
    assert private_uses("from fidlearn import _cv, plotting\nplotting._helper()\n") == [
        "line 1: from fidlearn import _cv",
        "line 2: plotting._helper",
    ]
    assert private_uses("import fidlearn._cv as c\n")
    assert private_uses("from fidlearn._io import x\n")
    assert not private_uses("%matplotlib inline\nimport fidlearn\nprint(fidlearn.__version__)\nx._y\n")


def test_notebooks_are_found():
    assert len(NOTEBOOKS) >= 20
    assert len(SOURCES) >= 10


@pytest.mark.parametrize("path", NOTEBOOKS + SOURCES, ids=lambda p: p.relative_to(repo_dir()).as_posix())
def test_notebook_uses_public_names_only(path):
    found = [f"cell {i}: {use}" for i, code in enumerate(_code_cells(path)) for use in private_uses(code)]
    assert not found, f"{path.name} uses fidlearn's private names: " + "; ".join(found)
