"""The marker map from photos, joined with the tape: a bundle adjustment (:func:`survey`).

Localization with a known map (:func:`fidlearn.locate`) trusts the map completely, and a map is
only as good as the tape measure that made it. Photos of the markers from several places hold
more: each shows where markers are relative to each other, to a fraction of a millimetre. The
survey puts every camera pose and every marker placement (6 unknowns each) into one least-squares
problem whose residuals are the corners' reprojection errors, and keeps the tape map as a prior
(each placement within ``map_sigma_mm``, learnt from the tape residuals unless given, with the
markers' print scale) so the result stays where the tape put the room. A
marker taped in the wrong place is named (:attr:`Survey.suspects`), markers absent from the map
are added, and each placement comes with its 6x6 covariance. A marker taped metres off (a typo)
is found first, by the photos alone (:attr:`Survey.gross_ids`), and never pulls the others. A board
or a bundle of the map is surveyed as one rigid object.

Modules: ``_inputs`` (photos to detected corners, the checks), ``_init`` (starting values, new
markers, the units check), ``_gross`` (the photos alone against the tape: gross errors and
the robust residuals), ``_geometry`` (rotation vectors and their Jacobians), ``_problem``
(unknowns, residuals, sparse Jacobian), ``_solve`` (the passes, covariance, suspect test),
``_entries`` (a board or a bundle as one placement), ``_variance`` (the tape's sigma and the print
scale learnt), ``_layout`` (each tag against the starting map, an official field layout:
:class:`TagChange`), ``_result`` (:class:`Survey`) and ``_survey`` (:func:`survey`).

Conventions: mm, ``T_a_b`` maps frame b into frame a, placements as in the map files (top-left
corner, roll-pitch-yaw in degrees), camera frame OpenCV's.
"""

from __future__ import annotations

from ._inputs import MAX_MAP_SIGMA_MM, MAX_PHOTOS, MIN_MAP_SIGMA_MM
from ._layout import TagChange
from ._print_check import MIN_PRINT_MARKERS, PrintCheck, check_print
from ._result import Survey, Suspect
from ._solve import SUSPECT_P
from ._survey import survey

__all__ = [
    "survey",
    "Survey",
    "Suspect",
    "TagChange",
    "check_print",
    "PrintCheck",
    "MIN_PRINT_MARKERS",
    "SUSPECT_P",
    "MAX_PHOTOS",
    "MIN_MAP_SIGMA_MM",
    "MAX_MAP_SIGMA_MM",
]

for _public in (survey, Survey, Suspect, TagChange, check_print, PrintCheck):
    _public.__module__ = __name__
del _public
