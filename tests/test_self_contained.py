"""The tools read nothing outside the repository: no ../shared, no home folder.

``tools/make_data.py`` (everything ``make data`` regenerates) and
``tools/make_conventions_figure.py`` run in a subprocess with a fake HOME, writing into a
temporary folder, while a Python audit hook records every file they open. Reading is allowed
only inside the checkout, the temporary folders, the Python installation and the operating
system's own folders; the folder beside the checkout (where ``../shared`` would be) and the
real home folder are exactly what must not appear.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

#: Runs a tool under an audit hook and prints, as JSON, every path it opened.
RUNNER = r"""
import json, os, runpy, sys
opened = set()
def hook(event, args):
    if event == "open" and args and isinstance(args[0], (str, bytes, os.PathLike)):
        opened.add(os.path.realpath(os.fsdecode(args[0])))
sys.addaudithook(hook)
script, out, *argv = sys.argv[1:]
sys.argv = [script, *argv]
try:
    runpy.run_path(script, run_name="__main__")
except SystemExit as exc:
    if exc.code not in (0, None):
        raise
with open(out, "w") as f:
    json.dump(sorted(opened), f)
"""


def allowed_roots(tmp: Path) -> list[str]:
    roots = {ROOT, tmp, Path(sys.prefix), Path(sys.base_prefix), Path(os.path.realpath(sys.executable)).parent.parent}
    roots |= {Path(p) for p in ("/usr", "/lib", "/lib64", "/etc", "/proc", "/sys", "/dev")}
    return [os.path.realpath(r) for r in roots]


def run_tool(tmp_path: Path, script: str, *args: str) -> list[str]:
    home = tmp_path / "home"
    home.mkdir(exist_ok=True)
    env = {k: v for k, v in os.environ.items() if k not in ("MPLCONFIGDIR", "XDG_CONFIG_HOME", "XDG_CACHE_HOME")}
    env.update(HOME=str(home), PYTHONPATH=str(ROOT))
    out = tmp_path / "opened.json"
    subprocess.run(
        [sys.executable, "-c", RUNNER, str(ROOT / script), str(out), *args],
        env=env,
        cwd=tmp_path,
        check=True,
        capture_output=True,
        text=True,
        timeout=300,
    )
    return json.loads(out.read_text())


def outside(paths: list[str], tmp: Path) -> list[str]:
    roots = allowed_roots(tmp)
    return [p for p in paths if not any(p == r or p.startswith(r.rstrip("/") + "/") for r in roots)]


@pytest.mark.parametrize(
    ("script", "args"),
    [
        pytest.param("tools/make_data.py", ["--data-dir", "{tmp}/data"], marks=pytest.mark.slow),
        ("tools/make_conventions_figure.py", ["{tmp}/conventions.png"]),
    ],
)
def test_tools_read_nothing_outside_the_repository(tmp_path, script, args):
    opened = run_tool(tmp_path, script, *[a.format(tmp=tmp_path) for a in args])
    assert opened, "the audit hook saw nothing: the test would prove nothing"
    assert any(p.startswith(str(ROOT)) for p in opened)
    assert outside(opened, tmp_path) == []
    shared = os.path.realpath(ROOT.parent / "shared")
    assert not [p for p in opened if p.startswith(shared + "/")]


def _same(made, kept, where: str) -> None:
    """Equal, numbers to 1e-9 (relative; 1e-9 absolute near 0): the last of a pose's 15 digits differ between
    processors, whose numpy and OpenCV kernels (AVX2, AVX-512) sum in different orders."""
    if isinstance(kept, dict):
        assert isinstance(made, dict), where
        assert made.keys() == kept.keys(), where
        for k in kept:
            _same(made[k], kept[k], f"{where}.{k}")
    elif isinstance(kept, list):
        assert isinstance(made, list), where
        assert len(made) == len(kept), where
        for i, (m, k) in enumerate(zip(made, kept)):
            _same(m, k, f"{where}[{i}]")
    elif isinstance(kept, float) or isinstance(made, float):
        assert made == pytest.approx(kept, rel=1e-9, abs=1e-9), where
    else:
        assert made == kept, where


def test_make_data_writes_what_the_repository_holds(tmp_path):
    run_tool(tmp_path, "tools/make_data.py", "--data-dir", str(tmp_path / "data"), "--only", "calibration")
    made = json.loads((tmp_path / "data" / "calibration" / "views.json").read_text())
    kept = json.loads((ROOT / "data" / "calibration" / "views.json").read_text())
    _same(made["views"], kept["views"], "views")
    moved = json.loads(json.dumps(kept["views"]))
    moved[3]["distance_mm"] += 1e-3  # a micrometre: a real change, which the comparison must see
    with pytest.raises(AssertionError, match=r"views\[3\]\.distance_mm"):
        _same(moved, kept["views"], "views")
