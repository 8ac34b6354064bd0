"""A robot's drive past the markers: the true poses, frame after frame, and their pictures."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import frames
from ..camera import Camera
from ..errors import FidlearnError
from ..frames import look_at
from ..markermap import MarkerMap
from ._checks import MAX_FRAMES, _check_indices, _check_render_work, _check_scene, _check_seed
from ._scenes import render_scene


@dataclass(eq=False)
class Trajectory:
    """Frames of a camera on a robot driving past the markers, with the truth of every frame.

    Attributes
    ----------
    images : list of ndarray (H, W) uint8
        The frames, in driving order.
    T_world_camera : list of ndarray (4, 4)
        The camera's true pose (mm, world) in each frame.
    truth : list of dict
        Per frame, ``{id: (4, 2) float64}`` true pixel corners of the markers seen whole.
    marker_map : MarkerMap
        The markers' true placements.
    camera : Camera
        The true camera.
    """

    images: list
    T_world_camera: list
    truth: list
    marker_map: MarkerMap
    camera: Camera
    seed: int = 0
    render_kwargs: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.images)

    @property
    def positions_mm(self) -> np.ndarray:
        """Camera positions (N, 3), mm, world."""
        return np.array([T[:3, 3] for T in self.T_world_camera])

    def __repr__(self) -> str:
        w, h = self.camera.image_size
        seen = sum(len(t) for t in self.truth)
        d = np.linalg.norm(np.diff(self.positions_mm, axis=0), axis=1).sum() if len(self) > 1 else 0.0
        return (
            f"Trajectory({len(self)} frames {w}x{h}, {d / 1000:.2f} m driven, {seen} marker sightings, "
            f"seed={self.seed})"
        )


def _check_drive_options(
    n_frames, start_distance_mm, end_distance_mm, start_lateral_mm, end_lateral_mm, height_mm, wobble_deg
) -> None:
    """Raise :class:`FidlearnError` naming the first option of :func:`trajectory_poses` that is not a number."""
    if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)) or not 1 <= n_frames <= MAX_FRAMES:
        raise FidlearnError(f"n_frames must be a whole number from 1 to {MAX_FRAMES}, got {n_frames!r}")
    for name, value in (
        ("start_distance_mm", start_distance_mm),
        ("end_distance_mm", end_distance_mm),
        ("start_lateral_mm", start_lateral_mm),
        ("end_lateral_mm", end_lateral_mm),
        ("height_mm", 0.0 if height_mm is None else height_mm),
        ("wobble_deg", wobble_deg),
    ):
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float, np.integer, np.floating))
            or not math.isfinite(value)
            or abs(value) > 1e7
        ):
            raise FidlearnError(f"{name} must be a finite number (mm, or degrees for wobble_deg), got {value!r}")


def trajectory_poses(
    marker_map: MarkerMap,
    n_frames: int = 40,
    seed: int = 0,
    *,
    start_distance_mm: float = 2200.0,
    end_distance_mm: float = 700.0,
    start_lateral_mm: float = -700.0,
    end_lateral_mm: float = 500.0,
    height_mm: float | None = None,
    wobble_deg: float = 3.0,
) -> list[np.ndarray]:
    """True poses of a camera on a robot driving toward the markers.

    The robot drives a gentle arc on the floor: from ``start_distance_mm`` in
    front of the markers (along their mean facing direction) and
    ``start_lateral_mm`` to the side (the direction to the camera's right when
    it faces the wall) to ``end_distance_mm`` and ``end_lateral_mm``. The
    camera sits at the markers' height (``height_mm``, default their mean
    centre height), keeps pointing at the markers' centre, and sways a little
    (``wobble_deg``, smooth, seeded) with a millimetre of vibration.

    Parameters
    ----------
    marker_map : MarkerMap
        The markers driven toward; they must face a common horizontal direction.
    n_frames : int
        Number of poses, 1 to :data:`MAX_FRAMES`.
    seed : int
        Seed of ``numpy.random.default_rng`` (sway phases, vibration).
    start_distance_mm, end_distance_mm : float
        Distance in front of the markers' centre at the start and at the end, mm.
    start_lateral_mm, end_lateral_mm : float
        Sideways offset at the start and at the end, mm.
    height_mm : float, optional
        Camera height (world Z), mm; by default the markers' mean centre height.
    wobble_deg : float
        Amplitude of the sway (pan; tilt and roll are smaller), degrees.

    Returns
    -------
    list of ndarray, shape (4, 4)
        ``T_world_camera`` per frame, mm, in driving order.

    Raises
    ------
    FidlearnError
        If the map is not a MarkerMap, an option is not a finite number, or the markers do not face a
        common horizontal direction.

    Examples
    --------
    >>> from fidlearn import MarkerMap, data_path
    >>> poses = trajectory_poses(MarkerMap.load(data_path("world_map.json")), n_frames=5)
    >>> len(poses), poses[0].shape
    (5, (4, 4))
    """
    _check_scene(marker_map, None, with_camera=False, where="trajectory_poses")
    _check_drive_options(
        n_frames, start_distance_mm, end_distance_mm, start_lateral_mm, end_lateral_mm, height_mm, wobble_deg
    )
    rng = np.random.default_rng(_check_seed(seed))
    centres = np.array([marker_map.marker_corners(i).mean(axis=0) for i in marker_map.ids])
    normals = np.array([marker_map.normal(i) for i in marker_map.ids])
    centre = centres.mean(axis=0)
    facing = normals.mean(axis=0)
    facing[2] = 0.0
    if np.linalg.norm(facing) < 1e-6:
        raise FidlearnError(
            f"{marker_map.source}: the markers do not face a common horizontal direction (on the floor or "
            "facing each other), so there is no wall to drive toward; give poses of your own"
        )
    facing /= np.linalg.norm(facing)
    lateral = np.cross(-facing, [0.0, 0.0, 1.0])  # the camera's right when it faces the wall
    z = centre[2] if height_mm is None else float(height_mm)
    phases = rng.uniform(0, 2 * math.pi, size=6)
    tau = np.linspace(0.0, 1.0, n_frames)
    poses = []
    for s in tau:
        d = start_distance_mm + (end_distance_mm - start_distance_mm) * s
        lat = (
            start_lateral_mm
            + (end_lateral_mm - start_lateral_mm) * s
            + 0.25 * abs(end_lateral_mm - start_lateral_mm) * math.sin(math.pi * s)
        )
        eye = centre + facing * d + lateral * lat
        eye[2] = z + float(rng.normal(0.0, 1.0))
        pan = wobble_deg * math.sin(2 * math.pi * 1.3 * s + phases[0]) + 0.3 * wobble_deg * math.sin(
            2 * math.pi * 3.1 * s + phases[1]
        )
        tilt = 0.5 * wobble_deg * math.sin(2 * math.pi * 0.9 * s + phases[2])
        roll = 0.3 * wobble_deg * math.sin(2 * math.pi * 2.3 * s + phases[3])
        T = look_at(eye, [centre[0], centre[1], z], roll_deg=roll)
        R = T[:3, :3] @ frames.rot_y(math.radians(pan)) @ frames.rot_x(math.radians(tilt))
        poses.append(frames.make_transform(R, eye))
    return poses


def render_trajectory(
    marker_map: MarkerMap,
    camera: Camera,
    n_frames: int = 40,
    seed: int = 0,
    *,
    poses: Sequence[np.ndarray] | None = None,
    frames_to_render: Sequence[int] | None = None,
    blur_px: float = 0.5,
    noise_std_gray: float = 1.5,
    gradient: float = 0.1,
    supersample: int = 4,
    wall_texture_std_gray: float = 3.0,
    **trajectory_options: Any,
) -> Trajectory:
    """Render a robot's drive past the markers (see :func:`trajectory_poses`), frame by frame.

    Frame ``i`` is ``render_scene(marker_map, camera, poses[i], seed=seed * 1000 + i, ...)``.

    Parameters
    ----------
    marker_map : MarkerMap
        The markers (mm, world). The map comes first, then the camera.
    camera : Camera
        The true camera.
    n_frames, seed : int
        Frames of the default drive, and the seed of the drive and of the pictures.
    poses : sequence of array_like, shape (4, 4), optional
        ``T_world_camera`` per frame (mm) instead of the default drive.
    frames_to_render : sequence of int, optional
        Keep only these frame indices (each identical to the same frame of the whole drive).
    blur_px, noise_std_gray, gradient, supersample, wall_texture_std_gray :
        As for :func:`render_scene`, applied to every frame.
    **trajectory_options
        Passed to :func:`trajectory_poses` (not with ``poses``).

    Returns
    -------
    Trajectory
        The frames, their true poses and per frame the true corners of the markers seen whole.

    Raises
    ------
    FidlearnError
        If the map or the camera is not one (a swapped call says so), both ``poses`` and trajectory
        options are given, or a frame index does not exist; or as :func:`render_scene`.

    Examples
    --------
    >>> from fidlearn import Camera, MarkerMap, data_path
    >>> cam = Camera.from_fov(60, (320, 240))
    >>> drive = render_trajectory(MarkerMap.load(data_path("world_map.json")), cam, n_frames=3)
    >>> len(drive), drive.images[0].shape, sorted(drive.truth[-1])
    (3, (240, 320), [0, 1, 2])
    """
    _check_scene(marker_map, camera, where="render_trajectory")
    if frames_to_render is None and poses is None and isinstance(n_frames, int):  # refused before any pose is drawn
        _check_render_work(camera, supersample, n_frames, "frames")
    if poses is None:
        poses = trajectory_poses(marker_map, n_frames, seed, **trajectory_options)
    elif trajectory_options:
        raise FidlearnError(f"give either poses or trajectory options ({', '.join(trajectory_options)}), not both")
    elif isinstance(poses, (str, bytes, dict)) or not hasattr(poses, "__len__"):
        raise FidlearnError(f"poses must be a list of 4x4 T_world_camera, got {type(poses).__name__}")
    render_kwargs: dict[str, Any] = dict(
        blur_px=blur_px,
        noise_std_gray=noise_std_gray,
        gradient=gradient,
        supersample=supersample,
        wall_texture_std_gray=wall_texture_std_gray,
    )
    chosen = _check_indices(frames_to_render, len(poses), "frames_to_render")
    _check_render_work(camera, supersample, len(chosen), "frames")
    images, truths = [], []
    for i in chosen:
        scene = render_scene(marker_map, camera, poses[i], seed=int(seed) * 1000 + i, **render_kwargs)
        images.append(scene.image)
        truths.append(scene.truth)
    kept = [np.asarray(poses[i], dtype=float) for i in chosen]
    return Trajectory(images, kept, truths, marker_map, camera, seed=int(seed), render_kwargs=render_kwargs)
