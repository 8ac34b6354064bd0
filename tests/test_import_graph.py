"""fidlearn's modules import one another in one direction only: no import circles anywhere.

Every module's source is read with :mod:`ast` (nothing is imported), every ``import`` and
``from ... import`` is followed, also those inside functions (a lazy import still ties two modules
together), and the graph of fidlearn modules is checked for circles.
"""

from __future__ import annotations

from tools.package_map import module_graph

# one reader of the imports, shared with the package map in CONTRIBUTING.md
_graph = module_graph


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
