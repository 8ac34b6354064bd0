"""What the detector delivers: corner noise against marker size, and the smallest marker it finds.

Both models were measured on fidlearn's own renders (``fidlearn.synthetic.render_scene`` with
the bundled scenes' settings: blur 0.5 px, sensor noise 1.2 gray levels, illumination gradient
0.2) with the default ``edges`` corner refinement; ``python benchmarks/bench_planning.py
--noise`` measures the noise table again, and the benchmark checks both against other renders.
A real camera (motion blur, JPEG, a soft print) is noisier: pass the noise you measured
(``corner_sigma_px``), e.g. the RMS reprojection error of your own ``locate`` runs.
"""

from __future__ import annotations

import numpy as np

#: Apparent marker side (px, mean of the four sides) at which the corner noise was measured ...
NOISE_SIDE_PX = np.array([11, 13, 15, 18, 22, 27, 33, 40, 50, 65, 85, 110, 150, 200], dtype=float)
#: ... and the measured corner noise per axis (px) at that side: the robust sigma (1.4826 times
#: the median absolute error, which ``estimate_pose``'s outlier test makes the relevant one: a
#: corner a pixel off is rejected, not averaged) over every marker detected in 150 rendered rooms
#: (walls of 1 to 12 markers seen from 0.5 to 4 m, 640x480 to 1920x1080; 744 markers, 5 to 126
#: per bin). The RMS is the same from 18 px up and 2 to 3 times larger below, where a few
#: corners land a pixel off.
NOISE_SIGMA_PX = np.array(
    [0.231, 0.099, 0.082, 0.082, 0.071, 0.079, 0.069, 0.050, 0.041, 0.032, 0.034, 0.031, 0.023, 0.023]
)

#: The decoder needs about 1.2 px per cell of a 7-cell marker: below this perimeter (px) it
#: fails whatever the image size (measured: half of the face-on markers found at 8.4 px sides,
#: 640x480, six rolls per distance).
DECODE_MIN_PERIMETER_PX = 34.0
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

    Parameters
    ----------
    side_px : float or ndarray
        Apparent marker side (px, mean of the four sides).

    Returns
    -------
    float or ndarray
        Corner noise per axis (px), the shape of ``side_px``.

    Examples
    --------
    >>> round(float(corner_sigma_px(50.0)), 3)
    0.041
    """
    return np.interp(side_px, NOISE_SIDE_PX, NOISE_SIGMA_PX)


def min_perimeter_px(image_size: tuple[int, int]) -> float:
    """The smallest marker perimeter (px) the default detector finds in a picture of ``image_size``.

    Parameters
    ----------
    image_size : (int, int)
        Width and height of the picture (px).

    Returns
    -------
    float
        The perimeter (px) below which markers are lost: the decoder's own limit or OpenCV's
        ``minMarkerPerimeterRate`` rule, whichever is larger.

    Examples
    --------
    >>> round(min_perimeter_px((1920, 1080)), 1)
    65.7
    >>> min_perimeter_px((640, 480))
    34.0
    """
    return max(DECODE_MIN_PERIMETER_PX, PERIMETER_RATE * PERIMETER_RULE_SLACK * max(image_size))
