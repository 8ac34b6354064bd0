"""Every package of fidlearn hands on its public names only, and says which in ``__all__``.

A package's ``__init__.py`` is its face: what ``from fidlearn.pose import ...`` offers. A private
helper (a name starting with ``_``) lives in the module that defines it, and whoever needs it
imports it from there (``from fidlearn.pose._stats import ...``), so that no face keeps a private
name alive for code that reached through it. Every ``__init__.py`` is read with :mod:`ast` (nothing
is imported for the rules on names): no name bound by an import may start with ``_`` (dunder names
such as ``__version__`` are fine; a name deleted again with ``del`` is not handed on), ``__all__`` is
a literal list of public names, each of them exists, and each public name imported is listed in it
(a submodule of the package itself excepted).
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

import fidlearn

ROOT = Path(fidlearn.__file__).resolve().parent
INITS = sorted(ROOT.rglob("__init__.py"))


def _dotted(init: Path) -> str:
    return ".".join(("fidlearn",) + init.parent.relative_to(ROOT).parts)


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _module_level(tree: ast.Module):
    """The statements run at import time: the module's own, and those inside its ``if``/``try`` blocks."""
    todo = list(tree.body)
    while todo:
        node = todo.pop(0)
        yield node
        if isinstance(node, (ast.If, ast.Try, ast.With, ast.For)):
            todo.extend(node.body)
            todo.extend(getattr(node, "orelse", []))
            todo.extend(getattr(node, "finalbody", []))
            for handler in getattr(node, "handlers", []):
                todo.extend(handler.body)


def _face(init: Path) -> dict:
    """What ``init`` binds: imported names (with the module they come from), other names, ``__all__``."""
    tree = ast.parse(init.read_text(encoding="utf-8"))
    imported: dict[str, str] = {}
    defined: set[str] = set()
    deleted: set[str] = set()
    all_names = None
    for node in _module_level(tree):
        if isinstance(node, ast.ImportFrom) and node.module != "__future__":
            for alias in node.names:
                imported[alias.asname or alias.name] = "." * node.level + (node.module or "")
        elif isinstance(node, ast.Import):
            for alias in node.names:
                imported[alias.asname or alias.name.split(".")[0]] = alias.name
        elif isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            defined.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.For)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                defined.update(n.id for n in ast.walk(target) if isinstance(n, ast.Name))
                if isinstance(target, ast.Name) and target.id == "__all__":
                    all_names = ast.literal_eval(node.value)
        elif isinstance(node, ast.Delete):
            deleted.update(t.id for t in node.targets if isinstance(t, ast.Name))
    return {"imported": imported, "defined": defined, "deleted": deleted, "all": all_names}


def _submodules(init: Path) -> set[str]:
    here = init.parent
    return {p.stem for p in here.glob("*.py")} | {p.name for p in here.iterdir() if (p / "__init__.py").is_file()}


def test_every_package_is_checked():
    names = {_dotted(p) for p in INITS}
    assert {"fidlearn", "fidlearn.pose", "fidlearn.cli", "fidlearn.calibration", "fidlearn.grading"} <= names


@pytest.mark.parametrize("init", INITS, ids=_dotted)
def test_no_private_name_is_handed_on(init):
    face = _face(init)
    private = sorted(n for n in face["imported"] if _private(n) and n not in face["deleted"])
    assert not private, f"{_dotted(init)} imports private names into its face: {private}"


@pytest.mark.parametrize("init", INITS, ids=_dotted)
def test_all_lists_the_public_names_and_they_exist(init):
    face = _face(init)
    name = _dotted(init)
    assert isinstance(face["all"], list), f"{name} has no literal __all__ list"
    assert len(set(face["all"])) == len(face["all"]), f"{name}.__all__ lists a name twice"
    private = [n for n in face["all"] if _private(n)]
    assert not private, f"{name}.__all__ lists private names: {private}"
    bound = (set(face["imported"]) | face["defined"]) - face["deleted"]
    missing = [n for n in face["all"] if n not in bound]
    assert not missing, f"{name}.__all__ lists names it does not bind: {missing}"
    module = importlib.import_module(name)
    assert all(hasattr(module, n) for n in face["all"])
    unlisted = sorted(
        n
        for n, source in face["imported"].items()
        if not _private(n)
        and n not in face["all"]
        and n not in face["deleted"]
        and not (source == "." and n in _submodules(init))
    )
    assert not unlisted, f"{name} imports public names that its __all__ does not list: {unlisted}"


def test_the_rules_catch_a_private_face(tmp_path):
    init = tmp_path / "__init__.py"
    init.write_text(
        "from ._a import _helper as _helper\nfrom ._a import shown, hidden\nimport inspect as _inspect\n"
        "__all__ = ['shown', '_helper', 'absent']\ndel _inspect\n",
        encoding="utf-8",
    )
    face = _face(init)
    assert sorted(n for n in face["imported"] if _private(n) and n not in face["deleted"]) == ["_helper"]
    assert face["all"] == ["shown", "_helper", "absent"]
    assert "absent" not in set(face["imported"]) | face["defined"]
    assert "hidden" in face["imported"]
    assert "hidden" not in face["all"]
