"""The ways to install fidlearn agree with each other and with the README.

``pyproject.toml`` is the one list of dependencies. ``environment.yml`` (conda) repeats it
with the same ranges, and Binder installs the package itself (``-e .``) so it cannot drift.
The README's quick start is exactly two commands, ``make lab`` and ``make test``, and CI
runs ``make test`` first, as a user would.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest
import yaml
from packaging.requirements import Requirement
from packaging.specifiers import SpecifierSet
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).resolve().parent.parent


def _read_pyproject(text: str, use_tomllib: bool = sys.version_info >= (3, 11)) -> dict:
    """pyproject.toml as a dict: tomllib on 3.11+, on 3.10 the few fields these tests read."""
    if use_tomllib:
        import tomllib

        return tomllib.loads(text)

    def array(body: str) -> list[str]:
        return re.findall(r'"([^"]+)"', re.sub(r"#.*", "", body))

    project = text.split("[project]", 1)[1]
    extras_text = text.split("[project.optional-dependencies]", 1)[1].split("\n[", 1)[0]
    return {
        "project": {
            "requires-python": re.search(r'^requires-python\s*=\s*"([^"]+)"', project, re.M).group(1),
            "dependencies": array(re.search(r"^dependencies\s*=\s*\[(.*?)\]", project, re.S | re.M).group(1)),
            "optional-dependencies": {
                name: array(body) for name, body in re.findall(r"^([\w-]+)\s*=\s*\[(.*?)\]", extras_text, re.S | re.M)
            },
        }
    }


PYPROJECT = _read_pyproject((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
ENV = yaml.safe_load((ROOT / "environment.yml").read_text(encoding="utf-8"))


def requirements(lines) -> dict[str, SpecifierSet]:
    out: dict[str, SpecifierSet] = {}
    for line in lines:
        req = Requirement(line)
        name = canonicalize_name(req.name)
        assert name not in out, f"{name} is listed twice"
        out[name] = req.specifier
    return out


def runtime_deps() -> dict[str, SpecifierSet]:
    return requirements(PYPROJECT["project"]["dependencies"])


def extra(name: str) -> dict[str, SpecifierSet]:
    return requirements(PYPROJECT["project"]["optional-dependencies"][name])


def conda_env() -> tuple[dict[str, SpecifierSet], dict[str, SpecifierSet], list[str]]:
    """(conda packages, pip packages, pip's local installs such as ``-e .``) of environment.yml."""
    conda, pip_lines = [], []
    for dep in ENV["dependencies"]:
        if isinstance(dep, dict):
            pip_lines += dep["pip"]
        else:
            conda.append(dep)
    local = [line for line in pip_lines if line.startswith(("-e", "."))]
    return requirements(conda), requirements([line for line in pip_lines if line not in local]), local


def test_the_310_reader_agrees_with_tomllib():
    """The fallback that Python 3.10 uses reads the same fields as tomllib does."""
    if sys.version_info < (3, 11):
        pytest.skip("tomllib is new in Python 3.11; this compares the fallback with it")
    import tomllib

    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    real = tomllib.loads(text)["project"]
    fallback = _read_pyproject(text, use_tomllib=False)["project"]
    for key in ("requires-python", "dependencies", "optional-dependencies"):
        assert fallback[key] == real[key]


def test_every_dependency_has_a_bounded_range():
    """An unbounded dependency breaks the course the day its next major release comes out."""
    groups = {"dependencies": runtime_deps(), **{k: extra(k) for k in PYPROJECT["project"]["optional-dependencies"]}}
    for group, deps in groups.items():
        for name, spec in deps.items():
            ops = {s.operator for s in spec}
            assert ">=" in ops, f"pyproject.toml [{group}] {name}{spec}: give a lower and an upper bound"
            assert "<" in ops, f"pyproject.toml [{group}] {name}{spec}: give a lower and an upper bound"


def test_opencv_spans_4_14_to_5():
    spec = runtime_deps()["opencv-contrib-python-headless"]
    for ok in ("4.14.0.94", "5.0.0.93"):
        assert Version(ok) in spec
    # 4.13 and older differ (ChArUco corners, false markers in the whole dictionary); CI proves 4.14 (floors)
    assert Version("4.13.0.92") not in spec


def test_the_floors_are_the_lower_bounds_and_ci_runs_them():
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        from floor_constraints import floors
    finally:
        sys.path.pop(0)
    pins = dict(line.split("==") for line in floors())
    for name, spec in {**runtime_deps(), **extra("test")}.items():
        low = [s.version for s in spec if s.operator == ">="]
        assert low, f"{name} has no lower bound: the floors job cannot pin it"
        assert pins[name] == low[0]
    assert re.search(r"^test-floor:", (ROOT / "Makefile").read_text(), re.M)


def test_conda_environment_matches_pyproject():
    conda, pip, local = conda_env()
    wanted = {**runtime_deps(), **extra("test")}
    python = conda.pop("python")
    assert python == SpecifierSet(PYPROJECT["project"]["requires-python"])
    conda.pop("pip")
    listed = {**conda, **pip}
    assert set(listed) == set(wanted), (
        f"environment.yml lacks {sorted(set(wanted) - set(listed))}, has extra {sorted(set(listed) - set(wanted))}"
    )
    for name, spec in wanted.items():
        assert listed[name] == spec, f"environment.yml has {name}{listed[name]}, pyproject.toml {name}{spec}"
    assert local == ["-e ."], "environment.yml must install fidlearn itself with pip: - -e ."


def test_conda_environment_takes_opencv_from_pip_only():
    """conda-forge's opencv and the PyPI wheel both install cv2 and break each other."""
    conda, pip, _ = conda_env()
    assert "opencv-contrib-python-headless" in pip
    assert not {"opencv", "py-opencv", "libopencv"} & set(conda)


def test_binder_installs_the_package_itself():
    lines = [
        line.strip()
        for line in (ROOT / "binder" / "requirements.txt").read_text().splitlines()
        if line.strip() and not line.lstrip().startswith("#")
    ]
    local = [line for line in lines if line.startswith(("-e", "."))]
    assert local == ["-e ."], "binder/requirements.txt must install fidlearn (-e .) so the notebooks import it"
    # Anything Binder pins besides the package must agree with pyproject.toml.
    wanted = {**runtime_deps(), **extra("test")}
    for name, spec in requirements([line for line in lines if line not in local]).items():
        assert name in wanted, f"binder/requirements.txt: {name}{spec} disagrees with pyproject.toml"
        assert spec == wanted[name], f"binder/requirements.txt: {name}{spec} disagrees with pyproject.toml"
    runtime = (ROOT / "binder" / "runtime.txt").read_text().strip()
    match = re.fullmatch(r"python-(\d+\.\d+)", runtime)
    assert match, f"binder/runtime.txt should read python-3.X, got {runtime!r}"
    assert Version(match.group(1)) in SpecifierSet(PYPROJECT["project"]["requires-python"])


def test_readme_quick_start_is_exactly_make_lab_and_make_test():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    section = re.search(r"^## Quick start\n(.*?)(?=^## )", readme, re.S | re.M)
    assert section, "README.md has no '## Quick start' section"
    blocks = re.findall(r"```[a-z]*\n(.*?)```", section.group(1), re.S)
    commands = [line.split("#")[0].strip() for block in blocks for line in block.splitlines()]
    assert [c for c in commands if c] == ["make lab", "make test"]


def test_makefile_has_the_two_commands_and_the_ci_targets():
    makefile = (ROOT / "Makefile").read_text()
    for target in ("lab", "test", "test-slow", "test-cv4", "test-floor", "test-browser"):
        assert re.search(rf"^{re.escape(target)}:", makefile, re.M), f"Makefile has no '{target}' target"
    assert re.search(r'"opencv-contrib-python-headless<5"', makefile), "make test-cv4 must install the newest 4.x"


def test_ci_runs_make_test_first_then_the_slow_tests_opencv_4_the_floors_and_the_browser():
    lines = [
        line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines() if not line.strip().startswith("#")
    ]
    make_calls = [m.group(1) for line in lines for m in [re.search(r"\bmake (test[\w-]*)\s*$", line)] if m]
    assert make_calls == ["test", "test-slow", "test-cv4", "test-floor", "test-browser"]


def _existing_environment_commands() -> list[str]:
    """The pytest commands of the README's "An existing environment" bullet, as written."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    bullet = re.search(r"^- \*\*An existing environment\*\*(.*?)(?=^- |^$)", readme, re.S | re.M)
    assert bullet, "README.md has no '- **An existing environment**' bullet"
    spans = re.findall(r"`([^`]*\bpytest [^`]*)`", bullet.group(1))
    return [span.split("&&")[-1].strip() for span in spans]


def test_the_readme_pytest_commands_collect_as_written():
    """The bare ``pytest`` commands of the README collect every test (``benchmarks`` imports too) from the
    checkout's top folder, with nothing but the installed package on ``sys.path``."""
    import glob
    import os
    import shlex
    import subprocess

    commands = _existing_environment_commands()
    assert len(commands) == 2, commands
    assert all(c.startswith("pytest ") for c in commands), commands
    pytest_exe = Path(sys.executable).with_name("pytest")
    assert pytest_exe.exists(), f"{pytest_exe}: pytest's script is installed beside the Python that runs the tests"
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONDONTWRITEBYTECODE"] = "1"  # nothing written into the checkout
    selected = {}
    for command in commands:
        args = [a for word in shlex.split(command)[1:] for a in (sorted(glob.glob(word, root_dir=ROOT)) or [word])]
        run = subprocess.run(
            [str(pytest_exe), *args, "--collect-only", "-q", "-p", "no:cacheprovider"],
            cwd=ROOT,
            env=env,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert run.returncode == 0, f"{command}\n{run.stdout[-3000:]}\n{run.stderr[-3000:]}"
        ids = [line for line in run.stdout.splitlines() if "::" in line]
        selected[command] = ids
    fast, slow = selected.values()
    assert any(i.startswith("tests/test_planning_real.py::") for i in fast)  # imports benchmarks
    assert any(i.startswith("notebooks/00_welcome.ipynb::") for i in fast)
    assert any(i.startswith("fidlearn/") for i in fast)  # the docstring examples
    assert slow
    assert not set(fast) & set(slow)
