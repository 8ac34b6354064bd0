"""The package map in CONTRIBUTING.md is the one the imports draw, and the drawing is right on known graphs."""

from __future__ import annotations

import pytest

from tools import package_map


def test_contributing_shows_the_current_package_map(capsys):
    assert package_map.main(["--check"]) == 0, capsys.readouterr().err


def test_parts_gather_modules_and_leave_out_entry_points_and_self_uses():
    graph = {
        "pkg": {"pkg.a"},
        "pkg.__main__": {"pkg.c"},
        "pkg.a": {"pkg._b"},
        "pkg.a._x": {"pkg.a", "pkg._b"},
        "pkg._b": set(),
        "pkg.c": {"pkg.a._x", "pkg"},
        "pkg.c.__main__": {"pkg.c"},
    }
    assert package_map.part_graph(graph) == {"a": {"_b"}, "_b": set(), "c": {"a"}}


def test_reduction_drops_uses_a_longer_path_implies_and_layers_stack_them():
    parts = {"top": {"mid", "low", "side"}, "mid": {"low"}, "low": set(), "side": set()}
    assert package_map.reduced(parts) == {"top": {"mid", "side"}, "mid": {"low"}, "low": set(), "side": set()}
    assert package_map.layers(parts) == [["low", "side"], ["mid"], ["top"]]


def test_a_circle_between_parts_is_refused():
    with pytest.raises(ValueError, match="circle"):
        package_map.layers({"a": {"b"}, "b": {"a"}})
