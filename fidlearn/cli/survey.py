"""``fidlearn survey``: the marker map from photos, joined with the tape map.

The work is the library's (:func:`fidlearn.survey`); this module reads the photos, prints the
table and the suspects, and writes the surveyed map (and ``--plot``) only when the whole run
succeeds, each through a hidden temporary file renamed at the end.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from ..errors import FidlearnError, UsageError
from ..images import expand_inputs
from ..io import atomic_write
from ..markermap_entries import BundleEntry, id_ranges
from ..survey import MAX_MAP_SIGMA_MM, MAX_PHOTOS, MIN_MAP_SIGMA_MM, Survey, survey
from ._common import (
    _add_image_size_option,
    _add_map_options,
    _check_output,
    _commit,
    _load_camera,
    _load_map,
    _Progress,
    _refuse_clobber,
)

HELP = "the marker map from photos of the markers, joined with the tape-measured map"


def add(sub) -> None:
    """Register the command on the ``fidlearn`` parser's subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``fidlearn`` parser's subcommands (``parser.add_subparsers()``).
    """
    p = sub.add_parser(
        "survey",
        help=HELP,
        description=(
            "Survey the markers from photos: every camera pose and every marker placement in one "
            "least-squares fit of the detected corners, with the tape map as a prior (each top-left "
            "corner within --map-sigma-mm). Prints a table per marker (tape and surveyed top-left "
            "corner, their difference and the surveyed standard deviation, mm), names the markers "
            "whose tape placement disagrees with the photos, and writes the surveyed map in the tape "
            "map's units (from a WPILib field layout: the corrected layout, and a table of how far "
            "each tag is from the official one, naming the tags moved beyond the noise). Take 20 or more photos from "
            "different places, each showing two or more markers, every marker in at least two photos."
        ),
    )
    p.add_argument("photos", nargs="+", type=Path, metavar="PHOTO_OR_FOLDER", help="photos, or folders of photos")
    p.add_argument("--camera", type=Path, required=True, metavar="CAMERA", help="camera file (fidlearn JSON or YAML)")
    _add_image_size_option(p)
    _add_map_options(p)
    p.add_argument(
        "--map-sigma-mm",
        type=float,
        default=None,
        metavar="MM",
        help=(
            "how well the tape placed each top-left corner, mm per coordinate (default: learnt from the tape's "
            "residuals, with the markers' print scale; 'inf' with --fixed)"
        ),
    )
    p.add_argument(
        "--fixed",
        action="append",
        metavar="ID",
        help=(
            "a marker whose placement is exact (repeatable; a board's or bundle's marker holds its whole entry; "
            "a marker of another dictionary than the map's as the map file writes it, e.g. 4X4_50:3)"
        ),
    )
    p.add_argument("-o", "--output", type=Path, required=True, metavar="SURVEYED.json", help="surveyed map to write")
    p.add_argument("--plot", type=Path, metavar="SURVEY.png", help="also draw the markers and the cameras in 3D")
    p.set_defaults(run=run)


def _check(args) -> list[Path]:
    out = _check_output(args.output, (".json",))
    plot = _check_output(args.plot, (".png",), "--plot") if args.plot is not None else None
    photos = [path for _, path in expand_inputs(args.photos, videos=False, once=True)]
    _refuse_clobber([("-o", out), ("--plot", plot)], [*photos, args.map, args.camera])
    sigma = args.map_sigma_mm
    if sigma is not None and not (MIN_MAP_SIGMA_MM <= sigma <= MAX_MAP_SIGMA_MM or sigma == math.inf):
        raise UsageError(
            f"--map-sigma-mm {sigma:g}: give a positive number of mm from {MIN_MAP_SIGMA_MM:g} to "
            f"{MAX_MAP_SIGMA_MM:g} (e.g. 10), or inf with --fixed"
        )
    if len(photos) > MAX_PHOTOS:
        raise UsageError(
            f"{len(photos)} photos: a survey takes at most {MAX_PHOTOS}; keep those that show the most markers "
            "(a room needs 20 to 100)"
        )
    return photos


def _fixed_key(text: str, tape) -> int:
    """The map's key of ``--fixed`` ``text``: an id of the map's dictionary, or ``DICTIONARY:ID``."""
    dictionary, _, number = text.strip().rpartition(":")
    try:
        key = tape.key(int(number), dictionary or None)
    except (ValueError, FidlearnError):
        raise UsageError(
            f"--fixed {text!r}: give a marker id such as 3, or a marker of another dictionary as the map file writes "
            "it, such as 4X4_50:3"
        ) from None
    if key not in tape:
        raise UsageError(f"--fixed {text}: no such marker in the map {tape.source} (its markers: {tape.ids})")
    return key


def run(args) -> int:
    """Survey, print the table and the suspects, write the map (and the figure).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    int
        The exit status: 0 when done.

    Raises
    ------
    FidlearnError
        A user error (too few photos, a map in the wrong units, ...); :func:`fidlearn.cli.main` prints it
        as one ``error:`` line and exits with status 2.
    """
    photos = _check(args)
    tape = _load_map(args)
    fixed = None if args.fixed is None else [_fixed_key(text, tape) for text in args.fixed]
    camera = _load_camera(args)
    progress = _Progress("survey")
    try:
        result = survey(photos, tape, camera, map_sigma_mm=args.map_sigma_mm, fixed_ids=fixed, progress=progress)
    finally:
        progress.clear()
    for label, reason in result.unused:
        print(f"warning: {Path(label).name} left out: {reason}", file=sys.stderr)
    fig = _figure(result, camera) if args.plot is not None else None
    result.save(args.output)
    if fig is not None:
        atomic_write(args.plot, lambda tmp: fig.savefig(tmp, format="png", dpi=110))
    _commit()  # the map and the plot take their names together
    _report(result, args)
    return 0


def _report(s: Survey, args) -> None:
    unseen = f", {len(s.unseen_ids)} in no photo kept the tape's" if s.unseen_ids else ""
    tape = "" if s.map_sigma_learnt else f", tape sigma {s.map_sigma_mm:g} mm"
    print(
        f"{args.output}: {len(s.marker_map) - len(s.unseen_ids)} markers surveyed from {len(s.camera_poses)} photos"
        f"{unseen} (corner noise {s.corner_sigma_px:.2f} px{tape})"
    )
    print(s.table())
    for line in s.learnt():
        print(line)
    for line in suspect_lines(s):
        print(line)
    if not s.suspects:
        print("no marker disagrees with the photos more than the tape's sigma explains")
    if s.layout_format == "wpilib":  # an official field layout: which tags moved, in its format
        print(f"{args.output}: written as a WPILib field layout, as {args.map.name} was")
        for line in s.tag_report(f"the official layout {args.map.name}"):
            print(line)


def sentence(suspect) -> str:
    """A suspect in words: how far from the map, in mm and sigmas, and what to do.

    Parameters
    ----------
    suspect : Suspect
        One of :attr:`Survey.suspects`.

    Returns
    -------
    str
        E.g. ``"marker 7 is 96 mm from where the map says (12 sigma): measure it again"``.
    """
    return (
        f"marker {suspect.id} is {suspect.distance_mm:.0f} mm from where the map says "
        f"({suspect.sigmas:.0f} sigma): measure it again"
    )


def suspect_lines(s: Survey) -> list[str]:
    """The suspects in words, worst first: a marker's :func:`sentence`, a rigid entry's once for all its markers.

    Parameters
    ----------
    s : Survey
        The survey.

    Returns
    -------
    list of str
        E.g. ``"board 'wall' (markers 20-36) is 102 mm from where the map says (11 sigma): measure it again"``.
    """
    lines, said = [], set()
    for sus in s.suspects:
        name = s.tape_map.owner.get(sus.id)
        if name is None:
            lines.append(sentence(sus))
        elif name not in said:
            said.add(name)
            ids = sorted(int(x.id) for x in s.suspects if s.tape_map.owner.get(x.id) == name)
            kind = "bundle" if isinstance(s.tape_map.entries[name], BundleEntry) else "board"
            lines.append(
                f"{kind} {name!r} (markers {id_ranges(ids)}) is {sus.distance_mm:.0f} mm from where the map says "
                f"({sus.sigmas:.0f} sigma): measure it again"
            )
    return lines


def _figure(s: Survey, camera):
    from ..plotting import draw_markers, plot_scene  # matplotlib only when drawing

    poses = list(s.camera_poses.values())
    title = "surveyed markers (dark) and tape (red); cameras of the photos"
    fig = plot_scene(s.marker_map, poses, camera=camera, labels=[None] * len(poses), scale_mm=150.0, title=title)
    draw_markers(fig.axes[0], s.tape_map, color="tab:red", show_ids=False, alpha=0.35)
    return fig
