"""The private file helpers' rules that no command shows whole: which paths name one file."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from fidlearn._files import repeated_paths


def test_one_file_by_two_names_or_a_link_is_one_photo(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.png").write_bytes(b"a")
    (tmp_path / "b.png").write_bytes(b"b")
    (tmp_path / "sub").mkdir()
    os.symlink(tmp_path / "a.png", tmp_path / "link.png")
    given = ["a.png", "b.png", "./a.png", Path("sub/../a.png"), "link.png", str(tmp_path / "b.png")]
    assert repeated_paths(given) == [(0, 2), (0, 3), (0, 4), (1, 5)]
    assert repeated_paths(["a.png", "b.png", "sub/a.png"]) == []  # a file of that name elsewhere is another


def test_only_paths_are_compared_and_every_entry_is_counted():
    image = np.zeros((4, 4), np.uint8)
    assert repeated_paths([image, "x.png", image, [], "x.png"]) == [(1, 4)]  # the same array twice is no file
    assert repeated_paths(iter(["x.png", "y.png", "x.png"])) == [(0, 2)]  # any iterable, read once


def test_a_path_that_cannot_be_resolved_is_compared_as_written():
    """A NUL character: the read that follows refuses it with a message, so comparing it never raises."""
    assert repeated_paths(["a\0.png", "b.png", "a\0.png"]) == [(0, 2)]
    assert repeated_paths(["missing.png", "./missing.png"]) == [(0, 1)]  # no file needed to compare
