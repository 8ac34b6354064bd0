"""``make data`` writes back what the repository holds: no ``-0.0`` where the repository has ``0.0``.

A rotation's entries that are zero come out of the arithmetic as -1e-17 or +1e-17 depending on
the processor; rounded, the negative ones became ``-0.0`` in the JSON files, so regenerating the
data changed files that had not changed. ``tools/make_data.py`` writes every zero as ``0.0``.
"""

from __future__ import annotations

import json
import math
import re
import runpy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
NEGATIVE_ZERO = re.compile(r"(?<![\w.])-0\.0(?![\d.eE])")


@pytest.fixture(scope="module")
def make_data():
    """The script's functions (``runpy``: the script is not a package module)."""
    return runpy.run_path(str(ROOT / "tools" / "make_data.py"), run_name="make_data")


def test_rounding_never_keeps_a_negative_zero(make_data):
    plain, matrix = make_data["plain"], make_data["matrix"]
    assert math.copysign(1.0, plain(-1e-17, 12)) == 1.0
    assert plain(-0.0, 6) == 0.0
    assert math.copysign(1.0, plain(-0.0, 6)) == 1.0
    assert plain(-0.25, 1) == -0.2
    assert plain(-1.5e-7, 6) == 0.0
    assert plain(-2e-6, 6) == -2e-6
    rotation = np.array([[0.0, -1e-17, 1.0], [-1.0, 0.0, -3e-18], [0.0, -1.0, 0.0]])
    assert NEGATIVE_ZERO.findall(json.dumps(matrix(rotation))) == []
    assert json.dumps(matrix(rotation)) == "[[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]"
    # the guard itself sees a negative zero, and only that
    assert NEGATIVE_ZERO.findall(json.dumps([-0.0, -0.05, 10.0, -10.0, 1e-10, "a-0.05"])) == ["-0.0"]


def test_every_json_writer_drops_negative_zeros(make_data, tmp_path):
    path = tmp_path / "x.json"
    make_data["write_json"](path, {"a": [-0.0, {"b": (-0.0, 1)}], "c": -0.0, "d": "x-0.0", "e": 0})
    text = path.read_text()
    assert json.loads(text) == {"a": [0.0, {"b": [0.0, 1]}], "c": 0.0, "d": "x-0.0", "e": 0}
    assert NEGATIVE_ZERO.findall(text) == []


def _zeros_agree(made, kept, where: str) -> list[str]:
    """Where the repository holds a float zero, the regenerated file holds the same zero (same sign)."""
    if isinstance(kept, dict):
        return [w for k in kept.keys() & made.keys() for w in _zeros_agree(made[k], kept[k], f"{where}.{k}")]
    if isinstance(kept, list) and isinstance(made, list):
        return [w for i, (m, k) in enumerate(zip(made, kept)) for w in _zeros_agree(m, k, f"{where}[{i}]")]
    if isinstance(kept, float) and kept == 0.0 and isinstance(made, float):
        return [] if math.copysign(1.0, made) == math.copysign(1.0, kept) else [where]
    return []


@pytest.mark.slow
def test_make_data_writes_the_repositorys_zeros(tmp_path):
    """The scenes (where -0.0 came from): regenerated, every JSON file has the repository's zeros, none negative.

    On the OpenCV and NumPy that made the files (their ``provenance``), the files are the same byte for byte.
    """
    out = tmp_path / "data"
    subprocess.run(
        [sys.executable, str(ROOT / "tools" / "make_data.py"), "--only", "scenes", "--data-dir", str(out)],
        check=True,
        capture_output=True,
        text=True,
        timeout=300,
    )
    written = sorted(p.relative_to(out) for p in out.rglob("*.json"))
    assert Path("scenes/poses.json") in written
    assert Path("two_walls_map.json") in written
    kept_poses = json.loads((ROOT / "data" / "scenes" / "poses.json").read_text())
    same_build = kept_poses["provenance"] == json.loads((out / "scenes" / "poses.json").read_text())["provenance"]
    for rel in written:
        made_text, kept_text = (out / rel).read_text(), (ROOT / "data" / rel).read_text()
        assert NEGATIVE_ZERO.findall(kept_text) == [], rel
        assert NEGATIVE_ZERO.findall(made_text) == [], rel
        assert _zeros_agree(json.loads(made_text), json.loads(kept_text), str(rel)) == []
        if same_build:
            assert made_text == kept_text, rel
    if same_build:
        for png in sorted((out / "scenes").glob("*.png")):
            assert png.read_bytes() == (ROOT / "data" / "scenes" / png.name).read_bytes(), png.name


def test_the_zero_comparison_sees_a_flipped_sign():
    kept = {"T": [[0.0, 1.0], [-1.0, 0.0]], "n": 0}
    assert _zeros_agree({"T": [[0.0, 1.0], [-1.0, 0.0]], "n": 0}, kept, "x") == []
    assert _zeros_agree({"T": [[0.0, 1.0], [-1.0, -0.0]], "n": 0}, kept, "x") == ["x.T[1][1]"]
