"""What the detector delivers: corner noise against marker size, and the smallest marker it finds.

Both models were measured on fidlearn's own renders (``fidlearn.synthetic.render_scene`` with
the bundled scenes' settings: blur 0.5 px, sensor noise 1.2 gray levels, illumination gradient
0.2) with the default ``edges`` corner refinement, one 80 mm ARUCO_ORIGINAL marker seen from
-50 to 50 degrees off its axis; ``python benchmarks/bench_planning.py --noise`` measures them
again. A real camera (motion blur, JPEG, a soft print) is noisier: pass the noise you measured
(``corner_sigma_px``), e.g. the RMS reprojection error of your own ``locate`` runs.
"""

from __future__ import annotations

import numpy as np

#: Apparent marker side (px, mean of the four sides) at which the corner noise was measured ...
NOISE_SIDE_PX = np.array([12.1, 14.6, 18.3, 22.8, 28.7, 40.3, 60.5, 89.9, 143.2, 236.6])
#: ... and the measured RMS corner error per axis (px) at that side.
NOISE_SIGMA_PX = np.array([0.372, 0.284, 0.060, 0.065, 0.067, 0.049, 0.036, 0.041, 0.048, 0.089])

#: The decoder needs about 1.5 px per cell of a 7-cell marker: below this perimeter (px) it
#: fails whatever the image size (measured: half of the markers found at 10.5 px sides).
DECODE_MIN_PERIMETER_PX = 42.0
#: OpenCV's ``minMarkerPerimeterRate`` default: candidates whose contour is shorter than this
#: fraction of the image's larger side are dropped before decoding ...
PERIMETER_RATE = 0.03
#: ... measured on the marker's outer edge, which is longer than the thresholded contour
#: OpenCV measures: half of the markers are found at 1.14 times the rule's perimeter
#: (1280x720: 11.5 px sides, 1920x1080: 16.5 px).
PERIMETER_RULE_SLACK = 1.14
#: A marker seen obliquely is lost when its shortest side gets below this (px): 30 px markers
#: were found up to 70 deg off their axis (10 px short sides) and lost at 74 deg (8 px);
#: 60 px markers came and went between 74 and 82 deg (17 to 8 px).
MIN_SHORT_SIDE_PX = 9.0
#: The largest angle (deg) between a marker's normal and the line of sight at which it was
#: measured to be found (120 px markers at 82 deg); beyond it, a marker counts as lost.
MAX_VIEW_ANGLE_DEG = 82.0


def corner_sigma_px(side_px: float | np.ndarray) -> float | np.ndarray:
    """Predicted RMS corner error per axis (px) of a marker whose sides measure ``side_px``.

    Linear interpolation of the measured table (:data:`NOISE_SIDE_PX`,
    :data:`NOISE_SIGMA_PX`), held constant outside it.

    Examples
    --------
    >>> round(float(corner_sigma_px(60.5)), 3)
    0.036
    """
    return np.interp(side_px, NOISE_SIDE_PX, NOISE_SIGMA_PX)


def min_perimeter_px(image_size: tuple[int, int]) -> float:
    """The smallest marker perimeter (px) the default detector finds in a picture of ``image_size``.

    Examples
    --------
    >>> round(min_perimeter_px((1920, 1080)), 1)
    65.7
    >>> min_perimeter_px((640, 480))
    42.0
    """
    return max(DECODE_MIN_PERIMETER_PX, PERIMETER_RATE * PERIMETER_RULE_SLACK * max(image_size))
