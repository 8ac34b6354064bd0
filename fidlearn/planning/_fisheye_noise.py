"""The corner noise of a fisheye's markers, as ``fidlearn.planning.noise`` models it (measured on renders)."""

from __future__ import annotations

import numpy as np

__all__ = ["FISHEYE_NOISE_SIDE_PX", "FISHEYE_NOISE_SIGMA_PX", "FISHEYE_MARKER_SHIFT_PX"]

#: The corner noise table of ``noise`` through a fisheye (``Camera(..., model="fisheye")``): the robust sigma
#: at :data:`FISHEYE_NOISE_SIDE_PX` of the corners ``locate`` gives on a fisheye picture (the "edges" refinement
#: with its curved sides' bias taken out, ``fidlearn._fisheye_edges``), measured on renders through a 160-degree
#: equidistant fisheye at 800 x 600 (walls of 1 to 12 markers of 80 mm, and of 1 to 4 of 200 mm, 0.3 to 1.5 m
#: away, anywhere from the picture's centre to its edge; 1150 markers, 3 to 250 per bin;
#: ``python benchmarks/bench_planning.py --noise --fisheye``). Smaller than the pinhole's from 15 to 50 px;
#: larger markers' sides curve more than the straightening takes out.
FISHEYE_NOISE_SIDE_PX = np.array([11, 13, 15, 18, 22, 27, 33, 40, 50, 65, 85, 110], dtype=float)
FISHEYE_NOISE_SIGMA_PX = np.array([0.110, 0.102, 0.053, 0.031, 0.025, 0.021, 0.019, 0.019, 0.029, 0.043, 0.071, 0.113])

#: ... and a shift common to the four corners of each fisheye marker (px per axis, as
#: :func:`~fidlearn.planning.noise.marker_shift_covariance` takes it), which the default noise model of a fisheye
#: adds: the straightening leaves each marker's corners a little off together (the RMS of a marker's mean corner
#: error was 0.013 to 0.016 px per axis at 20 to 50 px sides on the same renders, against 0.009 on a pinhole's),
#: and that does not average down over its corners.
FISHEYE_MARKER_SHIFT_PX = 0.015
