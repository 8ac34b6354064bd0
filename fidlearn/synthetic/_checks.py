"""Checks shared by the synthetic world's entry points, and its limits."""

from __future__ import annotations

import numpy as np

from ..camera import Camera
from ..errors import FidlearnError
from ..markermap import MarkerMap

#: Gray levels of the synthetic world: the wall, the paper and the printed ink.
DEFAULT_GRAYS = {"wall": 120.0, "paper": 230.0, "ink": 25.0}

#: Most samples (pixels times supersample squared) one picture is rendered from: 1920x1080 at
#: supersample 4 (33 million) takes about 4 s on a busy 2-core machine; a billion took minutes.
MAX_RENDER_SAMPLES = 40_000_000
#: Most samples all the pictures of one call (a drive, calibration views) are rendered from together:
#: 200 frames of 640x480 at supersample 4.
MAX_RENDER_SAMPLES_ALL = 1_000_000_000
#: Most frames a trajectory may have.
MAX_FRAMES = 100_000


def _check_scene(marker_map, camera, with_camera: bool = True, where: str = "render_scene") -> None:
    """Raise a FidlearnError unless ``marker_map`` is a MarkerMap and ``camera`` a Camera (map first)."""
    order = f"{where}(marker_map, camera, ...): the map comes first, then the camera"
    if with_camera and isinstance(marker_map, Camera) and isinstance(camera, MarkerMap):
        raise FidlearnError(f"{order}; the arguments are swapped")
    if not isinstance(marker_map, MarkerMap):
        raise FidlearnError(
            f"marker_map must be a fidlearn.MarkerMap (MarkerMap.load reads a file), got {type(marker_map).__name__}; "
            f"{order}"
        )
    if with_camera and not isinstance(camera, Camera):
        raise FidlearnError(
            f"camera must be a fidlearn.Camera (Camera.load reads a file), got {type(camera).__name__}; {order}"
        )


def _check_render_work(camera, supersample, n_pictures: int, what: str) -> None:
    """Refuse up front a call whose pictures together need more than ``MAX_RENDER_SAMPLES_ALL`` samples."""
    k = supersample if isinstance(supersample, (int, np.integer)) and not isinstance(supersample, bool) else 1
    samples = camera.width * camera.height * max(int(k), 1) ** 2 * n_pictures
    if samples > MAX_RENDER_SAMPLES_ALL:
        raise FidlearnError(
            f"{n_pictures} {what} of {camera.width}x{camera.height} at supersample {k} need {samples / 1e9:.3g} "
            f"billion samples, more than the limit of {MAX_RENDER_SAMPLES_ALL / 1e9:g} billion "
            "(MAX_RENDER_SAMPLES_ALL, minutes of work): render fewer, smaller or less supersampled pictures"
        )


def _check_indices(chosen, n: int, what: str) -> list[int]:
    """The indices to render (all of ``range(n)`` for None): whole numbers, each from 0 to n - 1."""
    if chosen is None:
        return list(range(n))
    if isinstance(chosen, (str, bytes, dict)) or not hasattr(chosen, "__iter__"):
        raise FidlearnError(f"{what} must be a list of indices, got {type(chosen).__name__}")
    out = list(chosen)
    if not all(isinstance(i, (int, np.integer)) and not isinstance(i, bool) for i in out):
        raise FidlearnError(f"{what} must be whole numbers, got {out!r:.60}")
    bad = [int(i) for i in out if not 0 <= i < n]
    if bad:
        raise FidlearnError(f"{what} {bad[:10]} do not exist; there are {n}, 0 to {n - 1}")
    return [int(i) for i in out]


def _check_seed(seed) -> int:
    """A seed for ``numpy.random.default_rng``: a whole number from 0 to 2**63 - 1."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= int(seed) < 2**63:
        raise FidlearnError(f"seed must be a whole number from 0 to 2**63 - 1, got {seed!r}")
    return int(seed)
