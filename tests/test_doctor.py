"""``fidlearn doctor`` finds two OpenCV wheels installed side by side and says which to remove.

Every OpenCV wheel on PyPI installs a package called ``cv2``; with two of them the last one
installed wins file by file and ``cv2`` breaks in odd ways. The tests fake a second wheel the
way pip leaves it behind (a ``*.dist-info`` folder with a METADATA file on ``sys.path``), so
the doctor reads it through ``importlib.metadata`` exactly as it reads a real one.
"""

from __future__ import annotations

import importlib.metadata as md
import os
import subprocess
import sys
from pathlib import Path

import pytest

from fidlearn import doctor
from fidlearn.cli.doctor import doctor_report

WANTED = "opencv-contrib-python-headless"


def fake_wheel(site: Path, name: str, version: str) -> Path:
    """A dist-info folder as pip writes it: ``opencv_python-4.10.0.84.dist-info/METADATA``."""
    info = site / f"{name.replace('-', '_')}-{version}.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n")
    (info / "top_level.txt").write_text("cv2\n")
    return info


def opencv_problems(problems: list[str]) -> list[str]:
    return [p for p in problems if "OpenCV wheels" in p]


def test_the_test_environment_has_one_opencv_wheel():
    """The baseline the fakes are added to: exactly fidlearn's own wheel, and no OpenCV problem."""
    lines, problems = doctor_report()
    wheel_line = next(line for line in lines if line.startswith("OpenCV wheels installed: "))
    assert wheel_line == f"OpenCV wheels installed: {WANTED} {md.version(WANTED)}"
    assert opencv_problems(problems) == []


@pytest.mark.parametrize("other", ["opencv-python", "opencv-python-headless", "opencv-contrib-python"])
def test_a_second_wheel_is_named_for_removal(tmp_path, monkeypatch, other):
    fake_wheel(tmp_path, other, "4.10.0.84")
    monkeypatch.syspath_prepend(str(tmp_path))
    lines, problems = doctor_report()
    assert f"{other} 4.10.0.84" in next(line for line in lines if line.startswith("OpenCV wheels installed"))
    [problem] = opencv_problems(problems)
    assert problem.startswith("2 OpenCV wheels share the cv2 name and break each other")
    assert f"keep {WANTED}" in problem
    assert f"pip uninstall -y {other} && pip install --force-reinstall {WANTED}" in problem


def test_every_extra_wheel_is_named(tmp_path, monkeypatch):
    fake_wheel(tmp_path, "opencv-python", "4.10.0.84")
    fake_wheel(tmp_path, "opencv-contrib-python", "4.9.0.80")
    monkeypatch.syspath_prepend(str(tmp_path))
    [problem] = opencv_problems(doctor_report()[1])
    assert problem.startswith("3 OpenCV wheels")
    assert f"pip uninstall -y opencv-contrib-python opencv-python && pip install --force-reinstall {WANTED}" in problem


def test_metadata_name_spelling_does_not_hide_a_wheel(tmp_path, monkeypatch):
    """Older pips wrote ``Name: opencv_python``; name normalisation must still see it."""
    info = fake_wheel(tmp_path, "opencv-python", "4.5.5.64")
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: OpenCV_Python\nVersion: 4.5.5.64\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    [problem] = opencv_problems(doctor_report()[1])
    assert "pip uninstall -y opencv-python " in problem


def test_fidlearns_wheel_is_kept_even_when_it_is_not_installed(monkeypatch):
    """Two wrong wheels and not fidlearn's: keep (install) fidlearn's, remove both others."""

    class FakeDist:
        def __init__(self, name: str, version: str):
            self.metadata = {"Name": name}
            self.version = version

    fakes = [
        FakeDist("opencv-python", "4.10.0.84"),
        FakeDist("opencv-python-headless", "4.10.0.84"),
        FakeDist("numpy", "2.0.0"),
    ]
    monkeypatch.setattr(doctor.md, "distributions", lambda: iter(fakes))
    [problem] = opencv_problems(doctor_report()[1])
    assert f"pip uninstall -y opencv-python opencv-python-headless && pip install --force-reinstall {WANTED}" in problem


def test_unrelated_packages_are_not_counted(tmp_path, monkeypatch):
    fake_wheel(tmp_path, "opencv-python-stubs", "0.1")
    fake_wheel(tmp_path, "python-opencv-helpers", "1.0")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert opencv_problems(doctor_report()[1]) == []


def test_doctor_command_reports_the_problem_and_fails(tmp_path):
    """The real command in a real process: status 1 and a ``problem:`` line naming the wheel to remove."""
    fake_wheel(tmp_path, "opencv-python", "4.10.0.84")
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    proc = subprocess.run(
        [sys.executable, "-m", "fidlearn", "doctor"], capture_output=True, text=True, env=env, timeout=60
    )
    assert proc.returncode == 1, proc.stdout + proc.stderr
    problems = [line for line in proc.stdout.splitlines() if line.startswith("problem: ")]
    assert any("pip uninstall -y opencv-python " in p for p in problems), proc.stdout
    assert "all good" not in proc.stdout


def test_doctor_command_is_happy_in_a_healthy_environment():
    proc = subprocess.run([sys.executable, "-m", "fidlearn", "doctor"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.rstrip().endswith("all good")
    assert f"OpenCV wheels installed: {WANTED} " in proc.stdout


def broken_opencv(tmp_path: Path, version: str = "4.8.1.78") -> dict:
    """An environment whose OpenCV was built for numpy 1: ``import cv2`` fails as it does beside numpy 2."""
    stub = tmp_path / "site"
    (stub / "cv2").mkdir(parents=True)
    (stub / "cv2" / "__init__.py").write_text("raise ImportError('numpy.core.multiarray failed to import')\n")
    fake_wheel(stub, WANTED, version)
    env = dict(os.environ, PYTHONPATH=str(stub))
    return env


def test_doctor_names_the_broken_pair_and_the_pip_line_when_opencv_cannot_import(tmp_path):
    env = broken_opencv(tmp_path)
    out = subprocess.run(
        [sys.executable, "-m", "fidlearn", "doctor"], env=env, capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 1, out.stderr
    assert "Traceback" not in out.stderr + out.stdout
    [problem] = [line for line in out.stdout.splitlines() if line.startswith("problem:")]
    assert f"{WANTED} 4.8.1.78 was built for numpy 1 and cannot import beside numpy" in problem
    assert "pip install --upgrade 'opencv-contrib-python-headless>=" in problem


def test_other_commands_say_in_one_line_to_run_the_doctor(tmp_path):
    env = broken_opencv(tmp_path)
    out = subprocess.run(
        [sys.executable, "-m", "fidlearn", "corners", "map.json", "-o", "c.json"],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert out.returncode == 2
    assert out.stdout == ""
    [line] = out.stderr.splitlines()
    assert line.startswith("error: fidlearn cannot start (ImportError: numpy.core.multiarray failed to import)")
    assert "run 'fidlearn doctor'" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["site"]


def test_importing_fidlearn_with_a_broken_opencv_says_what_to_run(tmp_path):
    env = broken_opencv(tmp_path)
    code = "import fidlearn\ntry:\n    fidlearn.Camera\nexcept ImportError as e:\n    print(e)\n"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "fidlearn cannot load (ImportError: numpy.core.multiarray failed to import)" in out.stdout
    assert "python -m fidlearn doctor" in out.stdout
