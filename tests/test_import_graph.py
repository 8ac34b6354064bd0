"""fidlearn's modules import one another in one direction only: no import circles anywhere.

Every module's source is read with :mod:`ast` (nothing is imported), every ``import`` and
``from ... import`` is followed, also those inside functions (a lazy import still ties two modules
together), and the graph of fidlearn modules is checked for circles.
"""

from __future__ import annotations

import ast
from pathlib import Path

import fidlearn

ROOT = Path(fidlearn.__file__).resolve().parent


def _modules() -> dict[str, Path]:
    """Every module of fidlearn by dotted name (a package by its own name, for its ``__init__.py``)."""
    found = {}
    for path in sorted(ROOT.rglob("*.py")):
        parts = ("fidlearn",) + path.relative_to(ROOT).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join(parts)] = path
    return found


def _targets(name: str, path: Path, known: dict) -> set[str]:
    """The fidlearn modules that ``name`` (at ``path``) imports, lazily or not."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    wanted = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            wanted.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(base + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            for alias in node.names:  # a submodule by its own name, any other name from the module
                sub = f"{base}.{alias.name}"
                wanted.add(sub if sub in known else base)
    out = set()
    for target in wanted:
        if target not in known:
            continue
        out.add(target)
        # the packages on the way are run too, except fidlearn itself and the importer's own packages
        parts = target.split(".")
        for i in range(2, len(parts)):
            parent = ".".join(parts[:i])
            if not (name == parent or name.startswith(parent + ".")):
                out.add(parent)
    out.discard(name)
    return out


def _graph() -> dict[str, set[str]]:
    known = _modules()
    return {name: _targets(name, path, known) for name, path in known.items()}


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected parts of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            part = []
            while True:
                w = stack.pop()
                on.discard(w)
                part.append(w)
                if w == v:
                    break
            if len(part) > 1:
                found.append(sorted(part))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_graph_sees_lazy_and_relative_imports():
    graph = _graph()
    # a module-level relative import, a lazy one inside a function, a package's own submodule
    assert "fidlearn.errors" in graph["fidlearn.grading._learners"]
    assert "fidlearn._files" in graph["fidlearn.grading._learners"]  # inside read_secret
    assert "fidlearn.exercises" in graph["fidlearn.grading._grader"]  # inside functions only
    assert "fidlearn.grading._selfstudy" in graph["fidlearn.grading"]
    # the finder finds a circle when there is one
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _circles({"a": {"b"}, "b": set()}) == []


def test_no_import_circles_in_fidlearn():
    circles = _circles(_graph())
    assert circles == [], "modules that import each other: " + "; ".join(" <-> ".join(c) for c in circles)


def test_exercises_never_imports_grading():
    graph = _graph()
    above = {
        (name, target)
        for name, targets in graph.items()
        if name.startswith("fidlearn.exercises") and name != "fidlearn.exercises.__main__"
        for target in targets
        if target == "fidlearn.grading" or target.startswith("fidlearn.grading.")
    }
    assert above == set()
