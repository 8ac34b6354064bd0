"""``fidlearn render``: a synthetic picture of a world map seen from a pose, to try the pipeline without hardware."""

from __future__ import annotations

import argparse
import math
import warnings
from pathlib import Path

from .. import frames, synthetic
from ..boards import parse_grid
from ..errors import FidlearnWarning, UsageError
from ..images import write_image
from ._common import (
    _add_image_size_option,
    _add_map_options,
    _check_output,
    _commit,
    _floats,
    _load_camera,
    _load_map,
    _refuse_clobber,
)

_POSE_HELP = """The camera's pose in the world, two ways:
  --pose X,Y,Z,ROLL,PITCH,YAW   the camera's position (mm, world) and the rotation of the
                                camera frame in the world, R_world_camera = Rz(yaw) Ry(pitch)
                                Rx(roll) in degrees: the same numbers 'fidlearn locate' prints.
                                The camera frame is OpenCV's (x right, y down, z forward), so
                                0,0,0 looks straight up (+Z); -90,0,90 looks at the north wall
                                (along -X) upright; -90,0,0 looks along +Y.
  --from X,Y,Z --look-at X,Y,Z  the camera at one point (mm) looking at another, upright
                                (world +Z up in the image); --roll-deg turns it about its axis.
Example: fidlearn render --map world_map.json --camera camera.json \\
           --from 1200,150,250 --look-at 0,150,250 -o scene.png --truth truth.json"""


def add(sub) -> None:
    """Register the command on the ``fidlearn`` parser's subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``fidlearn`` parser's subcommands (``parser.add_subparsers()``).
    """
    p = sub.add_parser(
        "render",
        help="synthetic picture of a world map seen from a pose",
        description="Render a synthetic picture of the markers of a world map as a calibrated camera\n"
        "at a given pose would see them, to try the pipeline without hardware.",
        epilog=_POSE_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _add_map_options(p)
    p.add_argument(
        "--camera", type=Path, required=True, metavar="CAMERA", help="camera file (fidlearn JSON or OpenCV YAML)"
    )
    _add_image_size_option(p)
    pose = p.add_mutually_exclusive_group(required=True)
    pose.add_argument(
        "--pose", metavar="X,Y,Z,ROLL,PITCH,YAW", help="camera position (mm) and roll,pitch,yaw (deg), see below"
    )
    pose.add_argument("--look-at", metavar="X,Y,Z", help="point the camera looks at (mm); needs --from")
    p.add_argument("--from", dest="eye", metavar="X,Y,Z", help="camera position (mm) for --look-at")
    p.add_argument("--roll-deg", type=float, metavar="DEG", help="with --look-at: turn about the optical axis (deg)")
    p.add_argument("--size", metavar="WxH", help="render at another resolution of the same aspect ratio")
    p.add_argument("--seed", type=int, default=0, help="random seed of the wall texture and noise (default 0)")
    p.add_argument("--noise", type=float, default=0.0, metavar="STD", help="sensor noise, gray levels (default 0)")
    p.add_argument("--blur", type=float, default=0.0, metavar="PX", help="defocus blur sigma, px (default 0)")
    p.add_argument("--truth", type=Path, metavar="TRUTH.json", help="also write the true pose and pixel corners")
    p.add_argument("-o", "--output", type=Path, required=True, help="image to write (.png)")
    p.set_defaults(run=run)


#: Largest picture ``fidlearn render`` draws (pixels); rendering supersamples it 16 times, so this is
#: ``synthetic.MAX_RENDER_SAMPLES`` / 16: 1920x1080 takes about 5 s. 40 megapixels took minutes.
MAX_RENDER_PIXELS = 2_500_000
#: Largest coordinate (mm) a pose on the command line may have: 100 km.
MAX_COORD_MM = 1e8


def _check_coords(option: str, values) -> None:
    if max(abs(v) for v in values) > MAX_COORD_MM:
        raise UsageError(
            f"{option}: {max(abs(v) for v in values):g} mm is beyond any room ({MAX_COORD_MM:g} mm at most); "
            "positions are in millimetres"
        )


def _pose_from_args(args):
    """T_world_camera (4, 4), mm, from --pose or --from/--look-at/--roll-deg."""
    if args.pose is not None:
        if args.eye is not None:
            raise UsageError("--from goes with --look-at; --pose already gives the position")
        if args.roll_deg is not None:
            raise UsageError("--roll-deg goes with --look-at; --pose already gives the roll")
        x, y, z, roll, pitch, yaw = _floats(args.pose, 6, "--pose", "x,y,z in mm, roll,pitch,yaw in degrees")
        _check_coords("--pose", (x, y, z))
        if max(abs(roll), abs(pitch), abs(yaw)) > 3600:
            raise UsageError(f"--pose {args.pose}: roll, pitch and yaw are degrees, -360 to 360")
        return frames.make_transform(frames.rotation_from_rpy_deg(roll, pitch, yaw), [x, y, z])
    if args.eye is None:
        raise UsageError("--look-at needs --from X,Y,Z, the camera's position in mm")
    eye = _floats(args.eye, 3, "--from", "x,y,z in mm")
    target = _floats(args.look_at, 3, "--look-at", "x,y,z in mm")
    _check_coords("--from", eye)
    _check_coords("--look-at", target)
    roll = 0.0 if args.roll_deg is None else args.roll_deg
    if not abs(roll) <= 3600:
        raise UsageError("--roll-deg is degrees, -360 to 360")
    _check_view(args, eye, target)
    return frames.look_at(eye, target, roll_deg=roll)


def _check_view(args, eye: list[float], target: list[float]) -> None:
    """UsageError for --from and --look-at at one point, or one straight above the other: --look-at keeps the
    world's +Z up in the picture, which has no meaning for a camera looking straight down or up."""
    d = [t - e for t, e in zip(target, eye)]
    length = math.hypot(*d)
    if length == 0:
        raise UsageError(
            f"--from {args.eye} and --look-at {args.look_at} are the same point; the camera must look away"
        )
    if math.hypot(d[0], d[1]) <= 1e-9 * length:
        down = d[2] < 0
        x, y, z = (f"{v:.10g}" for v in eye)
        raise UsageError(
            f"--from {args.eye} --look-at {args.look_at}: the camera looks straight {'down' if down else 'up'}, "
            "where --look-at cannot keep the world's +Z up in the picture; give --pose "
            f"{x},{y},{z},{180 if down else 0},0,YAW instead (YAW in degrees turns the picture)"
        )


def _check_args(args) -> tuple[Path, Path | None]:
    """The output paths (checked), and the numbers that need no file read."""
    out = _check_output(args.output, (".png", ".bmp", ".tif", ".tiff"))
    truth_path = _check_output(args.truth, (".json",), "--truth") if args.truth else None
    _refuse_clobber([("-o", out), ("--truth", truth_path)], [args.map, args.camera])
    if not (0 <= args.noise <= 255) or not (0 <= args.blur <= 100):
        raise UsageError("--noise must be 0 to 255 gray levels and --blur 0 to 100 px")
    if not 0 <= args.seed < 2**32:
        raise UsageError(f"--seed {args.seed}: give a whole number from 0 to {2**32 - 1}")
    return out, truth_path


def _camera(args):
    """The camera file's camera, at --size when given."""
    camera = _load_camera(args)
    if args.size:
        w, h = parse_grid(args.size, "--size")
        if w * h > MAX_RENDER_PIXELS or max(w, h) > 20000:
            raise UsageError(
                f"--size {w}x{h}: at most {MAX_RENDER_PIXELS / 1e6:g} megapixels (1920x1080 fits) and 20000 pixels "
                "a side; a larger picture takes minutes to render"
            )
        camera = camera.scaled((w, h))
    return camera


def run(args) -> int:
    """Render the picture (and its truth file); print what is in view.

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
    out, truth_path = _check_args(args)
    marker_map = _load_map(args)
    camera = _camera(args)
    T_world_camera = _pose_from_args(args)
    scene = synthetic.render_scene(
        marker_map, camera, T_world_camera, seed=args.seed, noise_std_gray=args.noise, blur_px=args.blur
    )
    write_image(out, scene.image)
    if truth_path is not None:
        scene.save_truth(truth_path, out.name, str(args.map))
    _commit()  # the picture and its truth take their names together
    seen = ", ".join(str(i) for i in sorted(scene.truth)) or "none"
    print(
        f"{out}: {camera.width}x{camera.height}, markers seen whole: {seen}"
        + (f"; truth in {truth_path}" if truth_path else "")
    )
    if not scene.truth:
        warnings.warn(
            "no marker of the map is in view; check the pose (see 'fidlearn render --help')",
            FidlearnWarning,
            stacklevel=2,
        )
    return 0
