"""The corner noise of a fisheye's markers, as ``fidlearn.planning.noise`` models it (measured on renders).

On a fisheye picture ``locate`` fits each side of a marker as the lens bends it and finds its edge at the marker's
own dark and light levels (``fidlearn._fisheye_edges``). Its corners' errors are of two kinds: each side's line
wanders on its own (offset and slope, the line model of :func:`~fidlearn.planning.noise.corner_covariance`), and the
four sides move out or in together (the levels a little off: the outline's offset,
:func:`~fidlearn.planning._corner_lines.edge_offset_covariance`). One sigma for all corners (the robust sigma the
pinhole's table gives) puts too much into the lines' slopes, the marker's tilt, and too little into its size: a
lone marker's position error was predicted 1.4 times too large. The three tables below are measured on renders
through a 160-degree equidistant fisheye at 800 x 600 (walls of 1 to 12 markers of 80 mm, and of 1 to 4 of
200 mm, 0.3 to 1.5 m away, anywhere from the picture's centre to its edge; 1,035 markers, 3 to 193 per bin;
``python benchmarks/bench_planning.py --noise --fisheye``): each marker's corner errors split, by least squares under
the line model, into the outline's offset and each side's line (chi-square with 2 degrees of freedom times that
side's variance). A side's variance depends on how it lies on the pixel grid (:data:`FISHEYE_SWEEP_VARIANCE`): up to
24 times larger along the pixel rows or columns (40 times with bilinear profiles), which made a quarter of the
markers several times noisier than the rest and the single markers' flips unexpected.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "FISHEYE_NOISE_SIDE_PX",
    "FISHEYE_NOISE_SIGMA_PX",
    "FISHEYE_EDGE_OFFSET_PX",
    "FISHEYE_EDGE_BIAS_PX",
    "FISHEYE_SWEEP_PX",
    "FISHEYE_SWEEP_VARIANCE",
]

#: Apparent marker side (px) of each bin ...
FISHEYE_NOISE_SIDE_PX = np.array([11, 13, 15, 18, 22, 27, 33, 40, 50, 65, 85, 110], dtype=float)
#: ... the lines' noise, as the corner noise (px per axis) of the line model, for sides whose pixel phase averages
#: out (:data:`FISHEYE_SWEEP_VARIANCE`; fitted with it by medians of each side's chi-square: robust) ...
FISHEYE_NOISE_SIGMA_PX = np.array([0.094, 0.016, 0.012, 0.011, 0.013, 0.012, 0.012, 0.015, 0.021, 0.025, 0.028, 0.037])
#: ... the spread of the outline's offset beyond what the lines' noise gives it (px, standard deviation; 1.4826
#: times its median absolute deviation, less the line model's share) ...
FISHEYE_EDGE_OFFSET_PX = np.array([0.030, 0.012, 0.008, 0.005, 0.003, 0.003, 0.002, 0.002, 0.003, 0.007, 0.005, 0.011])
#: ... and its median (px, outward positive): the outlines of markers under 15 px are found a little inside the
#: truth, the margin's white squeezed by the lens and blurred into the marker's black; a bias, the same in every
#: picture of that size, which moves a pose (most of all a lone small marker's distance) rather than spreading it.
FISHEYE_EDGE_BIAS_PX = np.array([-0.043, -0.015, -0.006, 0.001, 0.001, 0.002, 0.002, 0.003, 0.006, 0.006, 0.001, 0.013])


def edge_offset_px(side_px: float) -> tuple[float, float]:
    """``(spread, bias)`` (px) of a fisheye marker's outline offset at an apparent side of ``side_px``."""
    return (
        float(np.interp(side_px, FISHEYE_NOISE_SIDE_PX, FISHEYE_EDGE_OFFSET_PX)),
        float(np.interp(side_px, FISHEYE_NOISE_SIDE_PX, FISHEYE_EDGE_BIAS_PX)),
    )


#: How far (px) a side crosses the pixel rows or columns along its length, ``L sin(a)`` (``a`` its angle to the
#: nearer pixel axis) ...
FISHEYE_SWEEP_PX = np.array([0.25, 0.75, 1.25, 1.75, 2.5, 3.5, 5.0, 8.0, 15.0])
#: ... and its line's variance against a side that sweeps 6 px or more (where the pixel phase averages out). Each
#: edge crossing is found between pixels by interpolation, which is off by an amount that depends on where the
#: edge falls between pixel centres; a side along the pixel rows keeps one phase, and its errors add up instead of
#: averaging out.
FISHEYE_SWEEP_VARIANCE = np.array([16.91, 24.18, 12.25, 2.56, 2.79, 1.45, 0.89, 0.84, 1.16])


def side_sweeps_px(corners_px: np.ndarray) -> np.ndarray:
    """(4,) how far (px) each side (corner ``k`` to ``k + 1``) crosses the pixel rows or columns along its length."""
    side = np.roll(corners_px, -1, axis=0) - corners_px
    return np.min(np.abs(side), axis=1)


def side_variance(corners_px: np.ndarray) -> np.ndarray:
    """(4,) each side's line variance (:data:`FISHEYE_SWEEP_VARIANCE` at its sweep, :func:`side_sweeps_px`)."""
    return np.interp(side_sweeps_px(np.asarray(corners_px, dtype=float)), FISHEYE_SWEEP_PX, FISHEYE_SWEEP_VARIANCE)
