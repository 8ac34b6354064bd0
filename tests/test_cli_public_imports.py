"""The ``fidlearn`` command and the repository's scripts use only the library's public names.

A command is parsing, one library call and printing: whatever it needs from the library is
public (documented, kept), so a program can do what the command does. Every module of
``fidlearn/cli/`` and every script of ``tools/`` is read with :mod:`ast` (nothing is imported)
and each of its imports from fidlearn is checked: no module and no name starting with ``_``
outside ``fidlearn.cli`` itself (dunder names such as ``__version__`` are public).
"""

from __future__ import annotations

import ast
from pathlib import Path

import fidlearn

ROOT = Path(fidlearn.__file__).resolve().parent
REPO = ROOT.parent


def _private(part: str) -> bool:
    return part.startswith("_") and not (part.startswith("__") and part.endswith("__"))


def _absolute(node: ast.ImportFrom, module: str) -> str:
    """The dotted module a ``from ... import`` reads from, for a module named ``module``."""
    if not node.level:
        return node.module or ""
    base = module.split(".")[: -node.level]
    return ".".join(base + ([node.module] if node.module else []))


def private_imports(source: str, module: str) -> list[str]:
    """The private fidlearn names that ``source`` (the module named ``module``) imports, as written.

    A package's ``__init__.py`` is named ``package.__init__`` so that its relative imports start
    at the package.
    """
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            pairs = [(alias.name, None) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            pairs = [(_absolute(node, module), alias.name) for alias in node.names]
        else:
            continue
        for target, name in pairs:
            parts = target.split(".")
            if parts[0] != "fidlearn":
                continue
            whole = parts + ([name] if name is not None else [])
            if target == "fidlearn.cli" or target.startswith("fidlearn.cli."):
                continue  # the command's own modules
            if name is not None and f"{target}.{name}".startswith("fidlearn.cli"):
                continue
            if any(_private(p) for p in whole[1:]):
                found.append(".".join(whole))
    return found


def _sources() -> list[tuple[str, Path]]:
    out = []
    for path in sorted((ROOT / "cli").glob("*.py")):
        out.append((f"fidlearn.cli.{path.stem}", path))  # __init__: relative imports start at the package
    for path in sorted((REPO / "tools").glob("*.py")):
        out.append((f"tools.{path.stem}", path))
    return out


def test_the_check_finds_private_imports():
    src = (
        "from .. import _staged\n"
        "from .._io import atomic_write\n"
        "from ..pose._locate import locate\n"
        "from ..grading import _learners\n"
        "from ..io import _hidden\n"
        "import fidlearn._files\n"
        "from fidlearn._io import write_json_atomic\n"
        "from ..io import atomic_write\n"
        "from .. import __version__\n"
        "from ._common import _commit\n"
        "from . import _track\n"
        "from ..drawing import draw_pose as _draw_pose\n"
        "import numpy._core\n"
    )
    assert private_imports(src, "fidlearn.cli.plan") == [
        "fidlearn._staged",
        "fidlearn._io.atomic_write",
        "fidlearn.pose._locate.locate",
        "fidlearn.grading._learners",
        "fidlearn.io._hidden",
        "fidlearn._files",
        "fidlearn._io.write_json_atomic",
    ]


def test_cli_and_tools_import_only_public_library_names():
    sources = _sources()
    assert len(sources) >= 18  # the command's modules and the scripts were found
    bad = {}
    for module, path in sources:
        found = private_imports(path.read_text(encoding="utf-8"), module)
        if found:
            bad[str(path.relative_to(REPO))] = found
    assert bad == {}, f"private library names imported (make them public, in the library): {bad}"
