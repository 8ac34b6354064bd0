"""``fidlearn doctor``: is this Python able to run fidlearn, and if not, the one command that mends it.

This module imports nothing that can fail to import: numpy, OpenCV and matplotlib are tried one
by one, and what is installed is read from the package metadata (``importlib.metadata``), so the
report works precisely when the rest of fidlearn does not, e.g. an OpenCV built for numpy 1 beside
numpy 2 (OpenCV before 4.10).
"""

from __future__ import annotations

import importlib
import importlib.metadata as md
import platform
import re
import sys
from pathlib import Path
from types import ModuleType

#: Every wheel on PyPI that installs a ``cv2`` package; two of them break each other.
OPENCV_WHEELS = (
    "opencv-python",
    "opencv-python-headless",
    "opencv-contrib-python",
    "opencv-contrib-python-headless",
)
#: The one fidlearn depends on (the ArUco module is in contrib; headless: no GUI libraries).
WANTED_WHEEL = "opencv-contrib-python-headless"
#: Packages the notebooks need (checked by their metadata, never imported), and what needs each.
NOTEBOOK_PACKAGES = {
    "ipywidgets": "the notebooks' sliders and buttons",
    "jupyterlab": "the notebooks (make lab)",
    "anywidget": "the webcam widget (notebook 12, fidlearn.widgets.Webcam)",
}


def _requirement(name: str) -> str:
    """fidlearn's own requirement for ``name`` (e.g. ``numpy>=1.26,<3``), from its metadata."""
    try:
        for req in md.requires("fidlearn") or []:
            head = req.split(";")[0].strip()
            base = head.split("[")[0]
            for sep in ("<", ">", "=", "!", "~", " "):
                base = base.split(sep)[0]
            if base.strip().lower().replace("_", "-") == name:
                spec = head[len(base) :].replace(" ", "").strip("()")
                return base.strip() + ",".join(sorted(spec.split(","), key=lambda p: not p.startswith(">")))
    except md.PackageNotFoundError:
        pass
    return name


def _version(dist: str) -> str | None:
    try:
        return md.version(dist)
    except md.PackageNotFoundError:
        return None


def installed_opencv_wheels() -> list[tuple[str, str]]:
    """Every OpenCV wheel installed (two or more break each other: they all provide ``cv2``).

    Returns
    -------
    list of (str, str)
        ``(name, version)`` pairs, sorted by name; the version is the one Python imports.
    """
    found: dict[str, str] = {}
    for dist in md.distributions():
        # typeshed's PackageMetadata omits get(), which the email Message behind it has
        name = (dist.metadata.get("Name") or "").lower().replace("_", "-")  # type: ignore[attr-defined]
        if name in OPENCV_WHEELS:
            found.setdefault(name, dist.version)  # the first on sys.path: the one Python uses
    return sorted(found.items())


def _major_minor(version: str | None) -> tuple[int, int]:
    try:
        parts = (version or "").split(".")
        return int(parts[0]), int(parts[1])
    except (ValueError, IndexError):
        return (0, 0)


def _import(module: str) -> tuple[ModuleType | None, str]:
    """The module, or None and why it does not import (one line)."""
    try:
        return importlib.import_module(module), ""
    except Exception as exc:  # noqa: BLE001 - any failure of a broken binary module is reported, never raised
        return None, " ".join(f"{type(exc).__name__}: {exc}".split())


def _numpy_pair_problem(package: str, module_error: str, numpy_version: str | None) -> str | None:
    """Say which pair is incompatible when a package built for numpy 1 meets numpy 2."""
    if not numpy_version or _major_minor(numpy_version)[0] < 2:
        return None
    name = WANTED_WHEEL if package == "opencv" else package
    version = _version(name)
    if (
        package == "opencv"
        and _major_minor(version) < (4, 10)
        or "numpy" in module_error.lower()
        or "_ARRAY_API" in module_error
    ):
        return (
            f"{name} {version or '?'} was built for numpy 1 and cannot import beside numpy {numpy_version}: "
            f"pip install --upgrade '{_requirement(name)}'"
        )
    return None


def report() -> tuple[list[str], list[str]]:
    """Describe the environment and find what is broken in it.

    Returns
    -------
    lines : list of str
        One line per package or fact (versions, paths).
    problems : list of str
        Empty when healthy; each problem says what is wrong and ends with the one ``pip``
        command that mends it.
    """
    from . import __version__

    lines = [f"fidlearn {__version__}", f"Python {platform.python_version()} ({sys.executable})"]
    problems: list[str] = []
    numpy, err = _import("numpy")
    numpy_version = _version("numpy")
    if numpy is None:
        problems.append(f"numpy does not import ({err}): pip install --force-reinstall '{_requirement('numpy')}'")
    else:
        lines.append(f"numpy {numpy.__version__}")
    wheels = installed_opencv_wheels()
    lines.append("OpenCV wheels installed: " + (", ".join(f"{n} {v}" for n, v in wheels) or "none"))
    if len(wheels) > 1:
        # fidlearn depends on WANTED_WHEEL: keeping another one would let the next `pip install -e .` bring it back.
        extra = [n for n, _ in wheels if n != WANTED_WHEEL]
        problems.append(
            f"{len(wheels)} OpenCV wheels share the cv2 name and break each other; keep {WANTED_WHEEL}: "
            f"pip uninstall -y {' '.join(extra)} && pip install --force-reinstall {WANTED_WHEEL}"
        )
    cv2, err = _import("cv2")
    if cv2 is None:
        pair = _numpy_pair_problem("opencv", err, numpy_version)
        problems.append(
            pair or f"OpenCV does not import ({err}): pip install --force-reinstall '{_requirement(WANTED_WHEEL)}'"
        )
    else:
        lines.append(f"OpenCV {cv2.__version__} ({Path(cv2.__file__ or '?').parent})")
        has_aruco = hasattr(cv2, "aruco") and hasattr(cv2.aruco, "ArucoDetector")
        lines.append(f"cv2.aruco.ArucoDetector: {'yes' if has_aruco else 'no'}")
        if not has_aruco:
            problems.append(
                f"cv2.aruco.ArucoDetector is missing: uninstall the other OpenCV wheels, then "
                f"pip install --force-reinstall '{_requirement(WANTED_WHEEL)}'"
            )
    mpl, err = _import("matplotlib")
    if mpl is None:
        pair = _numpy_pair_problem("matplotlib", err, numpy_version) if _version("matplotlib") else None
        problems.append(pair or f"matplotlib does not import ({err}): pip install '{_requirement('matplotlib')}'")
    else:
        lines.append(f"matplotlib {mpl.__version__}")
    scipy, err = _import("scipy")
    if scipy is None:
        pair = _numpy_pair_problem("scipy", err, numpy_version) if _version("scipy") else None
        problems.append(
            pair or f"scipy does not import ({err}); fidlearn.survey needs it: pip install '{_requirement('scipy')}'"
        )
    else:
        lines.append(f"scipy {scipy.__version__}")
    _check_packages(lines, problems)
    return lines, problems


def _check_packages(lines: list[str], problems: list[str]) -> None:
    """Append the notebooks' packages and every other requirement of fidlearn: a version line, or a problem."""
    for dist, needed_by in NOTEBOOK_PACKAGES.items():
        version = _version(dist)
        if version is None:
            problems.append(f"{dist} is not installed (used by {needed_by}): pip install '{_requirement(dist)}'")
        else:
            lines.append(f"{dist} {version}")
    for dist in _other_requirements():
        version = _version(dist)
        if version is None:
            problems.append(f"{dist} is not installed (a dependency of fidlearn): pip install '{_requirement(dist)}'")
        else:
            lines.append(f"{dist} {version}")


def _requirement_names() -> list[str]:
    """The names of fidlearn's installed requirements (no extras such as ``[test]``), normalised."""
    try:
        requires = md.requires("fidlearn") or []
    except md.PackageNotFoundError:
        return []
    names = []
    for req in requires:
        if "extra" in req.partition(";")[2]:
            continue
        name = re.split(r"[\s\[<>=!~;(]", req.strip(), maxsplit=1)[0]
        names.append(name.lower().replace("_", "-"))
    return names


def _other_requirements() -> list[str]:
    """Requirements of fidlearn that :func:`report` does not check by name (a dependency added later)."""
    checked = {"numpy", "matplotlib", "scipy", *OPENCV_WHEELS, *NOTEBOOK_PACKAGES}
    return [name for name in _requirement_names() if name not in checked]


def run() -> int:
    """Print :func:`report` on standard output.

    Returns
    -------
    int
        The exit status: 0 when healthy, 1 when a problem was found.
    """
    lines, problems = report()
    for line in lines:
        print(line)
    for p in problems:
        print(f"problem: {p}")
    if not problems:
        print("all good")
    return 1 if problems else 0
