"""A synthetic world with ground truth: printed markers and boards seen by a known camera.

Every picture fidlearn renders comes with the answer: the true camera, the true
pose and the true pixel corners of each visible marker, so detection, pose
and calibration can be checked against known numbers.

How a frame is made (the realism that matters for detection and accuracy):

* Each printed sheet (an ArUco marker with its white quiet zone, a checkerboard
  or a ChArUco board with a white margin) is a textured plane in the world;
  the wall behind it is mid gray with a faint, smooth, seeded texture (fixed
  to the image, not to the wall: it is there so that nothing is perfectly flat).
* For every pixel of a supersampled image (``supersample`` x ``supersample``
  sub-pixels per pixel) the renderer finds the ray through it, undistorting
  with the camera's own model (``cv2.undistortPoints`` refined by Newton
  steps to 1e-9 px), intersects the ray with each plane through the plane's
  homography and looks the texture up (``cv2.remap``). The nearest plane wins;
  a plane seen from behind is not drawn.
* The supersampled image is averaged down block by block, so each pixel holds
  the area integral of the scene over its footprint (edges land at sub-pixel
  positions, as on a real sensor). A sub-pixel ``u_h`` of the fine grid sits at
  ``u = (u_h + 0.5) / k - 0.5`` in the output (pixel centres at integers).
* Then, optionally: Gaussian blur (defocus), an illumination gradient and
  Gaussian sensor noise, all from ``numpy.random.default_rng(seed)``.

The truth of a marker is ``camera.project(marker_map.marker_corners(id),
T_world_camera)``: exactly what ``cv2.projectPoints`` gives for its 3D corners.
Checked against plain OpenCV (``tests/test_synthetic.py``): checkerboard
X-corners found by ``cv2.cornerSubPix`` sit within a few thousandths of a
pixel of the truth on average, through strong distortion.

Same inputs, same OpenCV build: the same pixels, run after run (OpenCV 4.14
and 5.0 agree bit for bit). Another release may round ``cv2.remap``'s
bilinear weights differently, which moves a gray level here and there at
edges (see ``data/README.md``).
"""

from __future__ import annotations

from ._calibration_views import CalibrationViews, render_calibration_views
from ._checks import DEFAULT_GRAYS, MAX_FRAMES, MAX_RENDER_SAMPLES
from ._room import MIXED_WALL, board_survey_room, mixed_survey_room, mixed_wall, survey_room, survey_walk, tape_measured
from ._scenes import Scene, render_scene, visible_markers
from ._trajectory import Trajectory, render_trajectory, trajectory_poses

__all__ = [
    "render_scene",
    "Scene",
    "survey_room",
    "mixed_survey_room",
    "board_survey_room",
    "mixed_wall",
    "MIXED_WALL",
    "survey_walk",
    "tape_measured",
    "visible_markers",
    "render_calibration_views",
    "CalibrationViews",
    "trajectory_poses",
    "render_trajectory",
    "Trajectory",
    "DEFAULT_GRAYS",
    "MAX_RENDER_SAMPLES",
    "MAX_FRAMES",
]
