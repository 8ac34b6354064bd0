"""``fidlearn plan``: predicted position error over a room, before printing, and what to add."""

from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path

import numpy as np

from ..camera import Camera
from ..errors import FidlearnError
from ..images import load_image
from ..io import atomic_write
from ..markermap import MarkerMap
from ..planning import MAX_NOISE_PX
from ..planning.noise import noise_from_photo
from ..planning.room import AREA_MET, default_area, plan_room
from ..planning.suggest import suggest_markers
from ._common import _add_image_size_option, _check_output, _commit, _floats, _load_camera, _refuse_clobber

HELP = "predicted position error over a room seen from above, and where to add markers"
DESCRIPTION = "Predicted position error over a room, before printing, and what to add to reach a target."


def add(sub) -> None:
    """Register the command on the ``fidlearn`` parser's subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``fidlearn`` parser's subcommands (``parser.add_subparsers()``).
    """
    p = sub.add_parser("plan", help=HELP, description=DESCRIPTION)
    add_arguments(p)
    p.set_defaults(run=run)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The command's options, on ``p``.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The parser to add the options to.
    """
    p.add_argument(
        "map", type=Path, metavar="MAP.json", help="world map JSON (full layout, or give --units and --marker-size-mm)"
    )
    p.add_argument("--camera", type=Path, required=True, help="camera file (fidlearn JSON or OpenCV YAML)")
    _add_image_size_option(p)
    p.add_argument("--units", choices=["mm", "cm", "m", "in", "ft"], help="units of a map that does not declare them")
    p.add_argument("--marker-size-mm", type=float, metavar="MM", help="black square side, if the map does not say")
    p.add_argument(
        "--dictionary", help="ArUco dictionary, if the map does not say (a WPILib field layout: apriltag_36h11)"
    )
    p.add_argument(
        "--height-mm", type=float, default=300.0, metavar="MM", help="camera height above the floor (default 300)"
    )
    p.add_argument(
        "--area", metavar="X0,Y0,X1,Y1", help="floor area to plan, mm (default: 3 m in front of the markers)"
    )
    p.add_argument("--look-at", metavar="X,Y,Z", help="point the camera looks at (default: the markers' centre)")
    p.add_argument("--step-mm", type=float, default=250.0, metavar="MM", help="grid spacing (default 250)")
    p.add_argument(
        "--headings", type=int, default=16, metavar="N", help="level headings tried per place (default 16; 0: skip)"
    )
    p.add_argument(
        "--corner-sigma-px",
        type=float,
        metavar="PX",
        help="your camera's corner noise (default: measured on fidlearn's renders, by marker size)",
    )
    p.add_argument(
        "--marker-shift-px",
        type=float,
        metavar="PX",
        help="a shift common to each marker's four corners, px per axis (default 0; real photos: 0.1-0.2)",
    )
    p.add_argument(
        "--marker-size-rel-std",
        type=float,
        metavar="FRACTION",
        help="the printed markers' size error common to all, as a fraction (default 0; 0.01 for 1 %%)",
    )
    p.add_argument(
        "--noise-from",
        type=Path,
        metavar="PHOTO",
        help="measure the corner noise, marker shift and the markers' size errors on a photo of the map's markers "
        "(four or more, at the camera's resolution) instead of giving them",
    )
    p.add_argument(
        "--target-mm", type=float, metavar="MM", help="error to reach; drawn as a line, and the goal of --suggest"
    )
    p.add_argument(
        "--suggest", action="store_true", help="say which marker size and where to add markers to reach --target-mm"
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="picture to write (.png)")


def _check(args) -> None:
    """The output (a .png in a folder that exists, not an input) and the target, before any work."""
    out = _check_output(args.output, (".png",))
    _refuse_clobber([("-o", out)], [args.map, args.camera, args.noise_from])
    if args.suggest and args.target_mm is None:
        raise FidlearnError("--suggest needs --target-mm, the error to reach (e.g. --target-mm 10)")
    _positive(args.target_mm, "--target-mm", "mm")
    _positive(args.step_mm, "--step-mm", "mm")
    _positive(args.corner_sigma_px, "--corner-sigma-px", "pixels", MAX_NOISE_PX)
    _check_noise_options(args)


#: plan_room's arguments that the command line sets, by the option that sets each.
_OPTION_OF = {"height_mm": "--height-mm", "step_mm": "--step-mm", "headings": "--headings", "look_at_mm": "--look-at"}


def _positive(value: float | None, option: str, unit: str, most: float = math.inf) -> None:
    """A given ``option`` must be a positive finite number up to ``most`` (``None``: not given, nothing to check)."""
    if value is not None and not (math.isfinite(value) and 0 < value <= most):
        up_to = f" up to {most:g}" if math.isfinite(most) else ""
        raise FidlearnError(f"{option} {value}: give a positive number of {unit}{up_to}")


def _check_noise_options(args) -> None:
    """--noise-from or the noise given by hand, not both; the values given in range (0 where not given)."""
    given = [
        name
        for name, v in (
            ("--corner-sigma-px", args.corner_sigma_px),
            ("--marker-shift-px", args.marker_shift_px),
            ("--marker-size-rel-std", args.marker_size_rel_std),
        )
        if v is not None
    ]
    if args.noise_from is not None and given:
        raise FidlearnError(f"--noise-from measures the noise on the photo: leave out {', '.join(given)}")
    if args.marker_shift_px is None:
        args.marker_shift_px = 0.0
    if args.marker_size_rel_std is None:
        args.marker_size_rel_std = 0.0
    if not (math.isfinite(args.marker_shift_px) and 0 <= args.marker_shift_px <= MAX_NOISE_PX):
        raise FidlearnError(
            f"--marker-shift-px {args.marker_shift_px}: give a number of pixels, 0 or more, up to {MAX_NOISE_PX:g}"
        )
    if not (math.isfinite(args.marker_size_rel_std) and 0 <= args.marker_size_rel_std < 0.5):
        raise FidlearnError(
            f"--marker-size-rel-std {args.marker_size_rel_std}: give a fraction from 0 to below 0.5 (0.01 for 1 %)"
        )


def run(args) -> int:
    """Plan the room, write the picture, print the figures (and the suggestions with --suggest).

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
        A user error (``UsageError`` for the command line itself); :func:`fidlearn.cli.main` prints it
        as one ``error:`` line and exits with status 2.
    """
    _check(args)
    world = MarkerMap.load(args.map, units=args.units, marker_size_mm=args.marker_size_mm, dictionary=args.dictionary)
    camera = _load_camera(args)
    area = _floats(args.area, 4, "--area", "x0,y0,x1,y1 in mm") if args.area else default_area(world)
    look = _floats(args.look_at, 3, "--look-at", "x,y,z in mm") if args.look_at else None
    side = min(area[2] - area[0], area[3] - area[1])
    if side > 0 and args.step_mm > side:
        raise FidlearnError(
            f"--step-mm {args.step_mm:g}: the area is only {area[2] - area[0]:g} x {area[3] - area[1]:g} mm; "
            f"give a step of {side:g} mm or less"
        )
    noise = _noise(args, world, camera)

    plan = _plan(args, world, camera, area, look, noise)
    from ..planning.figure import plan_figure  # matplotlib only when drawing: the command starts faster

    fig = plan_figure(plan, world, target_mm=args.target_mm)
    atomic_write(args.output, lambda tmp: fig.savefig(tmp, format="png", dpi=110))
    _commit()
    ok = np.isfinite(plan.toward_mm)
    print(
        f"{args.output}: {plan.places()}; a pose is possible at {100 * ok.mean():.0f} % of them looking at the markers"
    )
    if ok.any():
        assert plan.toward_p90_mm is not None, "plan_room fills the 90th percentile"
        print(
            f"  predicted error looking at the markers: median {np.median(plan.toward_mm[ok]):.1f} mm, "
            f"worst {np.max(plan.toward_mm[ok]):.1f} mm; 90th percentile (nine poses in ten within it): "
            f"median {np.median(plan.toward_p90_mm[ok]):.1f} mm, worst {np.max(plan.toward_p90_mm[ok]):.1f} mm"
        )
    if np.any(plan.flip[ok]):
        print(
            f"  the planar flip is likely at {100 * plan.flip[ok].mean():.0f} % of those places: "
            "add a marker off their plane"
        )
    if args.target_mm is not None:
        print(f"  within {args.target_mm:g} mm: {100 * plan.fraction_within(args.target_mm):.0f} % of the area")
    if args.suggest:
        if plan.fraction_within(args.target_mm) >= AREA_MET:
            print(f"  suggestion: none needed; looking at the markers, the whole area is within {args.target_mm:g} mm")
        else:
            _suggest(args, world, camera, area, look, noise)
    return 0


def _noise(args, world: MarkerMap, camera: Camera) -> dict:
    """The noise options of the prediction: measured on ``--noise-from``'s photo (and said), or as given."""
    if args.noise_from is None:
        return {
            "corner_sigma_px": args.corner_sigma_px,
            "marker_shift_px": args.marker_shift_px,
            "marker_size_rel_std": args.marker_size_rel_std,
        }
    image = load_image(args.noise_from)
    try:
        found = noise_from_photo(image, world, camera)
    except FidlearnError as exc:
        raise type(exc)(f"--noise-from {args.noise_from}: {exc}") from None
    measured = found.noise
    err = measured.marker_size_rel_error
    print(
        f"noise measured on {args.noise_from} ({len(found.pose.marker_ids)} markers): corner noise "
        f"{measured.corner_sigma_px:.2f} px, marker shift {measured.marker_shift_px:.2f} px (per axis), marker size "
        f"spread {100 * measured.marker_size_rel_std_each:.1f} %; the markers look {100 * abs(err):.1f} % "
        f"{'smaller' if err < 0 else 'larger'} than the map says"
    )
    return measured.kwargs()


def _plan(args, world: MarkerMap, camera: Camera, area, look, noise: dict):
    """``plan_room`` with the command's options, a row counter on a terminal, and its errors in the options' names."""

    def progress(done: int, total: int) -> None:
        if sys.stderr.isatty():
            print(f"\rplanning: row {done}/{total}", end="" if done < total else "\n", file=sys.stderr)

    try:
        return plan_room(
            world,
            camera,
            height_mm=args.height_mm,
            area=area,
            look_at_mm=look,
            step_mm=args.step_mm,
            headings=args.headings,
            progress=progress,
            **noise,
        )
    except FidlearnError as exc:  # the library's argument names, as the options that set them
        said = str(exc)
        for name, option in _OPTION_OF.items():
            said = re.sub(rf"\b{name}\b", option, said)
        raise type(exc)(said) from None


def _suggest(args, world: MarkerMap, camera: Camera, area, look, noise: dict) -> None:
    """Print what to change to bring more of ``area`` within ``--target-mm``, scored on the plan's own grid."""
    steps = suggest_markers(
        world,
        camera,
        args.target_mm,
        height_mm=args.height_mm,
        area=area,
        look_at_mm=look,
        step_mm=args.step_mm,
        **noise,
    )
    if not steps:
        print("  suggestion: nothing tried helps; move the area closer to the markers or use a better camera")
        return
    for s in steps:
        print(
            f"  suggestion: {s.text}: {100 * s.fraction_before:.0f} % -> {100 * s.fraction_after:.0f} % "
            f"within {args.target_mm:g} mm"
        )
    same = (
        f"--area {','.join(f'{v:.10g}' for v in area)} --step-mm {args.step_mm:.10g} --height-mm {args.height_mm:.10g}"
    )
    if look is not None:
        same += f" --look-at {','.join(f'{v:.10g}' for v in look)}"
    print(f"  to check: plan the changed map on the same places, {same}")
