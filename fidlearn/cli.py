"""The ``fidlearn`` command line.

Every command reports a user error as one line ``error: ...`` on stderr and
exits with status 2: never a traceback, never a half-written output file
(outputs go to a temporary file that is renamed when complete).
"""

from __future__ import annotations

import argparse
import importlib.metadata as md
import platform
import sys
import warnings
from pathlib import Path
from typing import Callable, Sequence

from . import __version__
from .errors import FidlearnError, FidlearnWarning

__all__ = ["main", "build_parser"]

#: Every OpenCV wheel on PyPI installs a package called ``cv2``; two of them break each other.
OPENCV_WHEELS = (
    "opencv-python",
    "opencv-contrib-python",
    "opencv-python-headless",
    "opencv-contrib-python-headless",
)
WANTED_WHEEL = "opencv-contrib-python-headless"


class UsageError(FidlearnError):
    """The command line itself is wrong (unknown option, missing argument)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, status 2, no usage dump
        raise UsageError(f"{self.prog}: {message} (see '{self.prog} --help')")


# -- fidlearn corners ----------------------------------------------------------------
def _add_corners(sub) -> None:
    p = sub.add_parser(
        "corners",
        help="turn a world map (marker placements) into marker corners in mm",
        description="Turn a world map into the 3D corners of each marker (TL, TR, BR, BL, mm).",
    )
    p.add_argument("map", type=Path, help="world map JSON (bare seed layout or full layout)")
    p.add_argument("--units", choices=["mm", "cm", "m", "in", "ft"], help="units of a map that does not declare them")
    p.add_argument("--marker-size-mm", type=float, help="side of the black square in mm, if the map does not say")
    p.add_argument("--dictionary", help="ArUco dictionary, if the map does not say (default ARUCO_ORIGINAL)")
    p.add_argument("-o", "--output", type=Path, required=True, help="corner file to write (JSON)")
    p.set_defaults(run=_run_corners)


def _run_corners(args) -> int:
    from .markermap import MarkerMap

    m = MarkerMap.load(args.map, units=args.units, marker_size_mm=args.marker_size_mm, dictionary=args.dictionary)
    m.save_corners(args.output)
    plane = f"coplanar (within {m.planarity_mm():.2f} mm)" if m.is_coplanar() else f"not coplanar ({m.planarity_mm():.1f} mm off a plane)"
    print(f"{args.output}: corners of {len(m)} markers {m.ids}, {m.marker_size_mm:g} mm, {plane}")
    return 0


# -- fidlearn doctor -----------------------------------------------------------------
def _installed_opencv_wheels() -> list[tuple[str, str]]:
    found = {}
    for dist in md.distributions():
        name = (dist.metadata.get("Name") or "").lower().replace("_", "-")
        if name in OPENCV_WHEELS:
            found[name] = dist.version
    return sorted(found.items())


def doctor_report() -> tuple[list[str], list[str]]:
    """Lines describing the environment, and the problems found (empty when healthy)."""
    lines = [
        f"fidlearn {__version__}",
        f"Python {platform.python_version()} ({sys.executable})",
    ]
    problems: list[str] = []
    try:
        import numpy

        lines.append(f"numpy {numpy.__version__}")
    except ImportError:
        problems.append("numpy is not installed: pip install -e . (or make test) installs it")
    wheels = _installed_opencv_wheels()
    lines.append("OpenCV wheels installed: " + (", ".join(f"{n} {v}" for n, v in wheels) or "none"))
    if len(wheels) > 1:
        extra = [n for n, _ in wheels if n != WANTED_WHEEL]
        keep = WANTED_WHEEL if any(n == WANTED_WHEEL for n, _ in wheels) else wheels[0][0]
        extra = [n for n, _ in wheels if n != keep]
        problems.append(
            f"{len(wheels)} OpenCV wheels share the cv2 name and break each other; keep {keep}: "
            f"pip uninstall -y {' '.join(extra)} && pip install --force-reinstall {keep}"
        )
    try:
        import cv2

        lines.append(f"OpenCV {cv2.__version__} ({Path(cv2.__file__).parent})")
        has_aruco = hasattr(cv2, "aruco") and hasattr(cv2.aruco, "ArucoDetector")
        lines.append(f"cv2.aruco.ArucoDetector: {'yes' if has_aruco else 'no'}")
        if not has_aruco:
            problems.append(
                "cv2.aruco.ArucoDetector is missing: install opencv-contrib-python-headless>=4.8 "
                "and uninstall the other OpenCV wheels"
            )
    except ImportError as exc:
        problems.append(f"OpenCV does not import ({exc}): pip install 'opencv-contrib-python-headless>=4.8,<6'")
    for mod in ("matplotlib", "ipywidgets", "jupyterlab"):
        try:
            lines.append(f"{mod} {md.version(mod)}")
        except md.PackageNotFoundError:
            problems.append(f"{mod} is not installed; the notebooks need it: pip install -e .")
    return lines, problems


def _add_doctor(sub) -> None:
    p = sub.add_parser("doctor", help="check the Python, numpy and OpenCV installation", description="Check the installation.")
    p.set_defaults(run=_run_doctor)


def _run_doctor(args) -> int:
    lines, problems = doctor_report()
    for line in lines:
        print(line)
    if problems:
        for p in problems:
            print(f"problem: {p}")
        return 1
    print("all good")
    return 0


#: Subcommand builders, in the order ``fidlearn --help`` lists them.
COMMANDS: list[Callable] = [_add_corners, _add_doctor]


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="fidlearn",
        description="Camera localization from ArUco fiducials: calibrate, map, detect, locate.",
    )
    parser.add_argument("--version", action="version", version=f"fidlearn {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for add in COMMANDS:
        add(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 ok, 1 problem found, 2 user error)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        if not getattr(args, "run", None):
            parser.print_help()
            return 2
        with warnings.catch_warnings():
            warnings.simplefilter("always", FidlearnWarning)
            warnings.showwarning = _show_warning
            return int(args.run(args) or 0)
    except FidlearnError as exc:
        print(f"error: {_one_line(str(exc))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130


def _one_line(text: str) -> str:
    return " ".join(text.split())


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"warning: {_one_line(str(message))}", file=sys.stderr)
