"""``fidlearn doctor`` names every package fidlearn depends on (pyproject.toml's ``dependencies``)."""

from __future__ import annotations

import importlib.metadata as md
import re
import subprocess
import sys
from pathlib import Path

from fidlearn import doctor

ROOT = Path(__file__).resolve().parent.parent


def pyproject_dependencies() -> list[str]:
    """The names in ``[project] dependencies`` (read as text: tomllib is Python 3.11+)."""
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    block = re.search(r"^dependencies = \[(.*?)^\]", text, re.S | re.M).group(1)
    names = re.findall(r'^\s*"([A-Za-z0-9_.-]+)', block, re.M)
    assert len(names) >= 7, names
    assert "anywidget" in names, names
    return [n.lower().replace("_", "-") for n in names]


def test_the_report_names_every_dependency_with_its_version():
    lines, problems = doctor.report()
    assert problems == []
    for name in pyproject_dependencies():
        if name in doctor.OPENCV_WHEELS:
            wheels = next(line for line in lines if line.startswith("OpenCV wheels installed: "))
            assert f"{name} {md.version(name)}" in wheels
        else:
            assert f"{name} {md.version(name)}" in lines, name


def test_the_command_lists_anywidget():
    proc = subprocess.run([sys.executable, "-m", "fidlearn", "doctor"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert f"anywidget {md.version('anywidget')}" in proc.stdout.splitlines()


def _without(monkeypatch, missing: str) -> None:
    real = md.version

    def version(name):
        if name == missing:
            raise md.PackageNotFoundError(name)
        return real(name)

    monkeypatch.setattr(md, "version", version)


def test_a_missing_anywidget_is_a_problem_with_its_pip_line(monkeypatch):
    _without(monkeypatch, "anywidget")
    lines, problems = doctor.report()
    assert not [line for line in lines if line.startswith("anywidget")]
    [problem] = problems
    assert problem.startswith("anywidget is not installed (used by the webcam widget (notebook 12")
    assert problem.endswith(f"pip install '{doctor._requirement('anywidget')}'")
    assert re.search(r"pip install 'anywidget>=[\d.]+,<\d+'$", problem)


def test_a_dependency_added_later_is_listed_too(monkeypatch):
    """A requirement the report has no line of its own for is still listed, and extras are not."""
    real = md.requires

    def requires(name):
        extra = ["shapely>=2.0", 'pytest>=7; extra == "test"'] if name == "fidlearn" else []
        return (real(name) or []) + extra

    monkeypatch.setattr(md, "requires", requires)
    _without(monkeypatch, "shapely")
    lines, problems = doctor.report()
    assert problems == ["shapely is not installed (a dependency of fidlearn): pip install 'shapely>=2.0'"]
    assert not [line for line in lines if line.startswith("pytest")]
