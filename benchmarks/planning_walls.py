"""The rendered walls of the planning benchmarks (``bench_planning.py``'s pinhole groups and
``planning_fisheye.py``'s fisheye group): the render settings, a wall of markers, and the corner-noise
table measured on them."""

from __future__ import annotations

import math

import numpy as np

from fidlearn import MarkerMap
from fidlearn.planning import noise

#: The render settings of every planning scene (and of the noise model's tables).
RENDER = {"blur_px": 0.5, "noise_std_gray": 1.2, "gradient": 0.2}


def wall_map(rng: np.random.Generator, n: int, size_mm: float = 80.0) -> MarkerMap:
    """``n`` markers on the wall X = 0 (facing +X), spread over 1.2 m x 0.8 m, no two overlapping."""
    placed: list[tuple[float, float]] = []
    while len(placed) < n:
        y, z = rng.uniform(-600, 600), rng.uniform(200, 1000)
        if all(abs(y - a) > 1.6 * size_mm or abs(z - b) > 1.6 * size_mm for a, b in placed):
            placed.append((y, z))
    markers = {str(i): {"translation": [0.0, y, z], "rotation": [0, 0, 0]} for i, (y, z) in enumerate(placed)}
    return MarkerMap.from_dict({"units": "mm", "marker_size_mm": size_mm, "markers": markers})


def print_noise_table(sides, errs) -> None:
    """The corner error of each marker side bin of ``noise.NOISE_SIDE_PX``: RMS per axis and robust sigma.

    ``sides`` (N,) are the markers' apparent sides (px), ``errs`` (N, 8) their corners' errors (px).
    """
    sides, errs = np.asarray(sides, dtype=float), np.asarray(errs, dtype=float)
    edges = np.concatenate([[0], (noise.NOISE_SIDE_PX[1:] + noise.NOISE_SIDE_PX[:-1]) / 2, [np.inf]])
    print("| side (px) | markers | corner RMS per axis (px) | robust sigma (1.4826 MAD, px) |\n|---|---|---|---|")
    for side, lo, hi in zip(noise.NOISE_SIDE_PX, edges[:-1], edges[1:]):
        sel = (sides >= lo) & (sides < hi)
        rms = float(np.sqrt(np.mean(errs[sel] ** 2))) if sel.any() else math.nan
        robust = float(1.4826 * np.median(np.abs(errs[sel]))) if sel.any() else math.nan
        print(f"| {side:.0f} | {int(sel.sum())} | {rms:.3f} | {robust:.3f} |")
