"""``fidlearn camera export|import``: camera files to and from ROS's ``camera_info`` YAML."""

from __future__ import annotations

from pathlib import Path

from ..boards import parse_grid
from ..camera import Camera
from ..ros import load_camera_info, save_camera_info
from ._common import _check_output, _commit, _Parser, _refuse_clobber


def add(sub) -> None:
    """Register the command on the ``fidlearn`` parser's subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``fidlearn`` parser's subcommands (``parser.add_subparsers()``).
    """
    p = sub.add_parser(
        "camera",
        help="camera files to and from ROS camera_info YAML",
        description="Convert camera files: fidlearn's JSON (or OpenCV's YAML) to and from the camera_info YAML "
        "that ROS's camera_calibration writes and camera_info_manager reads (plumb_bob or rational_polynomial "
        "distortion, or equidistant for a fisheye; the pixel convention is the same, so K is copied as it is).",
    )
    verbs = p.add_subparsers(dest="camera_command", metavar="export|import", parser_class=_Parser)
    e = verbs.add_parser("export", help="a camera file to ROS camera_info YAML")
    e.add_argument("camera", type=Path, metavar="CAMERA", help="camera file (fidlearn JSON or OpenCV YAML)")
    e.add_argument("--ros", type=Path, required=True, metavar="CAMERA_INFO.yaml", help="the YAML file to write")
    e.add_argument("--camera-name", default="camera", metavar="NAME", help="camera_name in the file (default camera)")
    e.add_argument("--image-size", metavar="WxH", help="for an OpenCV YAML file that does not say its size")
    e.set_defaults(run=run_export)
    i = verbs.add_parser("import", help="ROS camera_info YAML to a fidlearn camera file")
    i.add_argument("camera_info", type=Path, metavar="CAMERA_INFO.yaml", help="the ROS camera_info YAML file")
    i.add_argument("-o", "--output", type=Path, required=True, metavar="CAMERA.json", help="the camera file to write")
    i.set_defaults(run=run_import)


def run_export(args) -> int:
    """Write the camera as ROS camera_info YAML.

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
        A user error; :func:`fidlearn.cli.main` prints it as one ``error:`` line and exits with status 2.
    """
    out = _check_output(args.ros, (".yaml", ".yml"), "--ros")
    _refuse_clobber([("--ros", out)], [args.camera])
    size = parse_grid(args.image_size, "--image-size") if args.image_size else None
    cam = Camera.load(args.camera, image_size=size)
    save_camera_info(cam, out, args.camera_name)
    _commit()
    n_dist = len(cam.dist) if cam.dist is not None else 0
    print(f"{out}: camera_info for {args.camera_name}, {cam.width}x{cam.height}, {n_dist} distortion terms")
    return 0


def run_import(args) -> int:
    """Write a fidlearn camera file from ROS camera_info YAML.

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
        A user error; :func:`fidlearn.cli.main` prints it as one ``error:`` line and exits with status 2.
    """
    out = _check_output(args.output, (".json",), "-o")
    _refuse_clobber([("-o", out)], [args.camera_info])
    cam = load_camera_info(args.camera_info)
    cam.save(out)
    _commit()
    print(f"{out}: camera {cam.width}x{cam.height} from {args.camera_info}")
    return 0
