"""The corner noise of a fisheye's markers, as ``fidlearn.planning.noise`` models it (measured on renders)."""

from __future__ import annotations

import numpy as np

__all__ = ["FISHEYE_NOISE_SIDE_PX", "FISHEYE_NOISE_SIGMA_PX", "FISHEYE_MARKER_SHIFT_PX"]

#: The corner noise table of ``noise`` through a fisheye (``Camera(..., model="fisheye")``): the robust sigma
#: at :data:`FISHEYE_NOISE_SIDE_PX` of the corners ``locate`` gives on a fisheye picture (the "edges" refinement,
#: then each side fitted as the lens bends it at the marker's own levels, ``fidlearn._fisheye_edges``), measured on
#: renders through a 160-degree equidistant fisheye at 800 x 600 (walls of 1 to 12 markers of 80 mm, and of 1 to 4
#: of 200 mm, 0.3 to 1.5 m away, anywhere from the picture's centre to its edge; 1,150 markers, 2 to 250 per bin;
#: ``python benchmarks/bench_planning.py --noise --fisheye``). Smaller than the pinhole's from 15 px up.
FISHEYE_NOISE_SIDE_PX = np.array([11, 13, 15, 18, 22, 27, 33, 40, 50, 65, 85, 110], dtype=float)
FISHEYE_NOISE_SIGMA_PX = np.array([0.110, 0.080, 0.048, 0.029, 0.022, 0.018, 0.018, 0.019, 0.021, 0.027, 0.029, 0.037])

#: ... and a shift common to the four corners of each fisheye marker (px per axis, as
#: :func:`~fidlearn.planning.noise.marker_shift_covariance` takes it), beyond what the corners' own noise gives their
#: mean. With the sides fitted at the marker's own levels none is left: on the same renders the RMS of a marker's
#: mean corner error is 0.008 to 0.011 px per axis at 15 to 50 px sides, what four corners of 0.018 to 0.022 px
#: give alone (when each side found its edge at its own levels, inside the squeezed margins, it was 0.013 to 0.016).
FISHEYE_MARKER_SHIFT_PX = 0.0
