"""The private file helpers' rules that no command shows whole: which paths name one file."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from fidlearn import _files
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


def test_a_folder_lists_its_pictures_without_hidden_names(tmp_path):
    """macOS leaves ``._scene.png`` beside a copied photo (not a picture), and fidlearn stages its own outputs
    under hidden names: neither is a photo of the user's, so a folder of photos does not fail on them."""
    from fidlearn import images

    cv2.imwrite(str(tmp_path / "scene.png"), np.zeros((8, 8), np.uint8))
    (tmp_path / "._scene.png").write_bytes(b"\x00\x05\x16\x07 AppleDouble")
    (tmp_path / ".scene.png.abc123.png").write_bytes(b"")
    assert _files.folder_images(tmp_path) == [tmp_path / "scene.png"]
    assert [p.name for _, p in images.expand_inputs([tmp_path], videos=False)] == ["scene.png"]


def test_heic_photos_are_named_with_how_to_get_jpegs(tmp_path):
    from fidlearn import calibrate_checkerboard, images
    from fidlearn.errors import CalibrationError, UsageError

    for name in ("IMG_0001.HEIC", "IMG_0002.heic"):
        (tmp_path / name).write_bytes(b"\x00\x00\x00\x18ftypheic")
    with pytest.raises(UsageError, match=r"2 HEIC photos and no other pictures; OpenCV cannot read HEIC.*JPEG"):
        images.expand_inputs([tmp_path], videos=False)
    with pytest.raises(CalibrationError, match=r"2 HEIC photos and no other pictures"):
        calibrate_checkerboard(tmp_path, (9, 6), 25)
    with pytest.raises(UsageError, match=r"IMG_0001.HEIC: OpenCV cannot read HEIC photos: export them as JPEG"):
        images.expand_inputs([tmp_path / "IMG_0001.HEIC"], videos=False)


@pytest.mark.parametrize(
    ("text", "hint"),
    [
        ('{"units": "mm", "markers": {"0": [[0, 0, 0], [0, 0, 0]],}}', "a comma after the last item"),
        ('{"units": "mm", // measured with a tape\\n "markers": {}}', "JSON has no comments"),
        ("{'units': 'mm'}", "JSON takes double quotes: write \"units\" for 'units'"),
        ('{"units": "mm" "markers": {}}', "a missing comma or bracket is the usual cause"),
    ],
)
def test_json_syntax_errors_say_what_json_does_not_take(tmp_path, text, hint):
    from fidlearn import MarkerMap
    from fidlearn.errors import MapError

    path = tmp_path / "map.json"
    path.write_text(text.replace("\\n", "\n"))
    with pytest.raises(MapError, match="invalid JSON at line") as info:
        MarkerMap.load(path)
    assert hint in str(info.value)
