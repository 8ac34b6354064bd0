# %% [markdown]
# # 05 Detecting markers, and the winding order of their corners
#
# **What you will learn**
#
# * how OpenCV finds ArUco markers in a picture: `cv2.aruco.ArucoDetector` gives ids and four pixel corners;
# * why code written for OpenCV before 4.7 (`Dictionary_get`, `detectMarkers`) fails today, and how to port it;
# * that the corners always come in the **winding order TL, TR, BR, BL** of the printed marker, whichever
#   way the marker is turned in the picture;
# * how accurate the corners are, measured against the synthetic truth, with and without corner refinement;
# * what happens to the pose when the corners are fed in the wrong order (measured: metres, not millimetres).
#
# Run the cells from top to bottom (Shift-Enter).

# %%
# %matplotlib inline
import json

import cv2
import matplotlib.pyplot as plt
import numpy as np

from fidlearn import Camera, MarkerMap, PoseError, data_path, estimate_pose, frames, plotting
from fidlearn.detection import Detection, detect_markers, draw_detections, load_image

np.set_printoptions(precision=3, suppress=True)

# %% [markdown]
# ## 1. A picture with known answers
#
# `data/scenes/` holds rendered pictures of the seed's wall (three 80 mm `ARUCO_ORIGINAL` markers, the map of
# notebook 04) seen by an HD webcam from ten known poses. `poses.json` records, for each picture, the camera's
# true pose and the **true pixel corners** of every marker in view: our answer key.

# %%
camera = Camera.load(data_path("scenes", "camera.json"))
world_map = MarkerMap.load(data_path("world_map.json"))
scenes = json.loads(data_path("scenes", "poses.json").read_text())["images"]

record = scenes[0]
image = load_image(data_path("scenes", record["image"]))
true_corners = {int(i): np.array(c) for i, c in record["corners_px"].items()}
print(record["image"], image.shape, image.dtype, "- markers in view:", sorted(true_corners))
print("true corners of marker 0 (px), TL TR BR BL:\n", true_corners[0])

# %% [markdown]
# ## 2. The seed's detection code, and why it fails today
#
# The project this course grew from detected markers like this, the way OpenCV's tutorials did before
# version 4.7:

# %%
from cv2 import aruco

gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
try:
    dictionary = aruco.Dictionary_get(aruco.DICT_ARUCO_ORIGINAL)          # the seed's code
    params = aruco.DetectorParameters_create()
    corners, ids, rejected = aruco.detectMarkers(gray, dictionary, parameters=params)
except AttributeError as exc:
    print(f"{type(exc).__name__}: {exc}")
    seed_error = exc

assert "Dictionary_get" in str(seed_error)

# %% [markdown]
# OpenCV 4.7 moved ArUco detection into a class. The free functions `Dictionary_get` and
# `DetectorParameters_create` are gone (on OpenCV 5 `detectMarkers` is gone too), so the first line already
# fails, with the same message on OpenCV 4.8 to 5.x. The ported code: get the dictionary with
# `getPredefinedDictionary`, make the parameters with their constructor, and give both to an
# `ArucoDetector`, whose `detectMarkers` method does the work.

# %%
dictionary = aruco.getPredefinedDictionary(aruco.DICT_ARUCO_ORIGINAL)  # the ported code
params = aruco.DetectorParameters()
detector = aruco.ArucoDetector(dictionary, params)
corners, ids, rejected = detector.detectMarkers(gray)

# ids are (N, 1) before OpenCV 5 and (N,) from 5.0: flatten them to work on both
ids = np.asarray(ids).reshape(-1)
print("ids:", ids.tolist(), f"- {len(corners)} markers, each corner array shaped {corners[0].shape}")
print(f"{len(rejected)} candidate squares did not decode as a marker")
assert sorted(ids.tolist()) == sorted(true_corners)

# %% [markdown]
# Each marker's corners come as a (1, 4, 2) array of float32 pixels. Compare them with the truth:

# %%
opencv_error_px = []
for c, i in zip(corners, ids):
    c = c.reshape(4, 2).astype(np.float64)
    err = np.linalg.norm(c - true_corners[int(i)], axis=1)
    opencv_error_px.append(err)
    print(f"marker {int(i)}: corner errors {err.round(2)} px")
opencv_error_px = np.concatenate(opencv_error_px)
assert opencv_error_px.max() < 1.5  # right to about a pixel, even without refinement

# %% [markdown]
# `fidlearn.detection.detect_markers(image, dictionary)` wraps the same detector (made once and cached) and
# returns a list of `Detection(id, corners_px)`, sorted by id, corners as (4, 2) float64 pixels. It also refines
# the corners: OpenCV offers `"subpix"`, `"contour"` and `"apriltag"`; fidlearn's default `"edges"` fits a
# straight line to each of the marker's four outer edges and intersects neighbouring lines.

# %%
detections = detect_markers(image, world_map.dictionary)
print(detections)

ax = plotting.show_image(None, image, title="scene_00.png: ids, and corners in winding order TL, TR, BR, BL")
plotting.plot_detections(ax, detections)
plt.show()

# %% [markdown]
# ## 3. How accurate are the corners?
#
# Over the six pictures of the seed's wall (scenes 0 to 5, 1 to 3 m away), the distance between each detected
# corner and its true position, for each refinement:

# %%
refinements = ["none", "subpix", "contour", "edges"]
errors = {r: [] for r in refinements}
for rec in scenes[:6]:
    img = load_image(data_path("scenes", rec["image"]))
    truth = {int(i): np.array(c) for i, c in rec["corners_px"].items()}
    for r in refinements:
        found = detect_markers(img, world_map.dictionary, refine=r)
        assert sorted(d.id for d in found) == sorted(truth), (rec["image"], r)
        errors[r] += [np.linalg.norm(d.corners_px - truth[d.id], axis=1) for d in found]

errors = {r: np.concatenate(e) for r, e in errors.items()}
print("refinement   corners   mean error   max error (px)")
for r, e in errors.items():
    print(f"{r:10s} {len(e):8d} {e.mean():11.3f} {e.max():11.3f}")

assert errors["none"].mean() < 1.0 and errors["none"].max() < 1.5
assert errors["edges"].mean() < 0.1 and errors["edges"].max() < 0.3
assert errors["edges"].mean() < errors["subpix"].mean() < errors["none"].mean()

fig, ax = plt.subplots(figsize=(7, 3.5))
ax.boxplot([errors[r] for r in refinements])
ax.set_xticks(range(1, len(refinements) + 1), refinements)
ax.set_ylabel("corner error (px)")
ax.set_xlabel("corner refinement (72 corners in six pictures)")
ax.set_title("detected corners against the synthetic truth")
fig.tight_layout()
plt.show()

# %% [markdown]
# Without refinement the corners are right to about half a pixel; fitting the edges brings them to a few
# hundredths. The pose inherits this error (notebook 08 measures how much).
#
# ## 4. A real photo
#
# `data/real/opencv_aruco_photo/singlemarkersoriginal.jpg` is the photo of OpenCV's ArUco tutorial: six
# `6X6_250` markers on a sheet of paper, ids 23, 40, 62, 98, 124 and 203. Detect with the right dictionary:

# %%
photo = load_image(data_path("real", "opencv_aruco_photo", "singlemarkersoriginal.jpg"))
found = detect_markers(photo, "6X6_250")
print("6X6_250       :", [d.id for d in found])
assert [d.id for d in found] == [23, 40, 62, 98, 124, 203]

wrong = detect_markers(photo, "4X4_50")
print("4X4_50 (wrong):", [d.id for d in wrong])

annotated = draw_detections(photo, found)  # a BGR copy with outlines, ids and corner names
plotting.show_image(None, annotated, title="the tutorial's photo: TL is the marker's own top-left corner")
plt.show()

# %% [markdown]
# With the wrong dictionary the six markers are not found, but something else may be: a random pattern on the
# box happens to decode as a `4X4_50` marker. Small dictionaries accept more by chance; detect with the
# dictionary you printed, and ignore ids that are not in your map (`estimate_pose` lists them in
# `Pose.ignored_ids`).
#
# ## 5. The winding order: TL, TR, BR, BL
#
# Look at markers 62 and 124 above: they lie turned on the paper, and their **TL** is not the corner at the
# top-left of the picture. The detector decodes the bits, so it knows which corner is the printed marker's
# top-left; it always reports the corners starting there and going **clockwise as seen in the image**:
# TL, TR, BR, BL. The world map's corners (notebook 04) come in the same order, so corner k of a detection
# matches corner k of the map.
#
# Let us check the order from the geometry. In an image (y down) a quad listed clockwise has a positive
# signed area by the shoelace formula, and the side from TL to TR points along the marker's "right":

# %%
def signed_area_px2(quad):
    """Shoelace area of a (4, 2) quad in image coordinates: positive when listed clockwise on screen."""
    x, y = quad[:, 0], quad[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def turned_deg(quad):
    """How far the marker is turned in the image: the direction of TL -> TR, to the nearest quarter turn."""
    right = quad[1] - quad[0]
    angle_deg = np.degrees(np.arctan2(right[1], right[0]))  # clockwise on screen, since y points down
    return int(round(angle_deg / 90.0)) * 90 % 360


turns = {}
for d in found:
    turns[d.id] = turned_deg(d.corners_px)
    print(f"marker {d.id:3d}: signed area {signed_area_px2(d.corners_px):6.0f} px^2, turned {turns[d.id]:3d} deg clockwise")
    assert signed_area_px2(d.corners_px) > 0  # clockwise, every one
assert turns == {23: 0, 40: 0, 62: 180, 98: 0, 124: 90, 203: 0}

# %% [markdown]
# ## 6. Feeding the corners in the wrong order
#
# Some code (hand-written corner lists, a map written as TL, BL, BR, TR, or corners sorted by their position
# in the image) breaks the winding order. The solver then matches TR's pixel with BL's 3D point, and so on.
# A bare solver still returns *a* pose. How wrong is it? Here the three markers of scene 0, with the order
# mixed up the same way in each, given to `cv2.solvePnP` (notebook 06) with its default solver, and to
# `estimate_pose`:

# %%
T_true = np.array(record["T_world_camera"])
orders = {
    "TL, TR, BR, BL (right)": [0, 1, 2, 3],
    "TL, BL, BR, TR (mirrored)": [0, 3, 2, 1],
    "TR, BR, BL, TL (rotated)": [1, 2, 3, 0],
    "BL, BR, TR, TL (upside down)": [3, 2, 1, 0],
}
object_points = np.concatenate([world_map.marker_corners(d.id) for d in detections])
wrong_poses = {}
print("order                         solvePnP: position error  reprojection RMS")
for name, order in orders.items():
    image_points = np.concatenate([d.corners_px[order] for d in detections])
    ok, rvec, tvec = cv2.solvePnP(object_points, image_points, camera.K, camera.dist)
    T_world_camera = frames.invert_transform(frames.transform_from_rvec_tvec(rvec, tvec))
    wrong_poses[name] = T_world_camera
    error_mm = np.linalg.norm(T_world_camera[:3, 3] - T_true[:3, 3])
    rms_px = np.sqrt(np.mean(np.sum((image_points - camera.project(object_points, T_world_camera)) ** 2, axis=1)))
    print(f"{name:28s} {error_mm:14.0f} mm {rms_px:14.1f} px")
    if order == [0, 1, 2, 3]:
        assert error_mm < 5 and rms_px < 0.5
    else:
        assert error_mm > 500  # half a metre and more: the pose is useless

for name, order in orders.items():
    try:
        pose = estimate_pose([Detection(d.id, d.corners_px[order]) for d in detections], world_map, camera)
        print(f"estimate_pose, {name}: position error {np.linalg.norm(pose.position_mm - T_true[:3, 3]):.1f} mm")
        assert order == [0, 1, 2, 3]
    except PoseError as exc:
        print(f"estimate_pose, {name}: PoseError: {exc}")
        assert order != [0, 1, 2, 3]

# %% [markdown]
# With the right order the camera is found within a millimetre. Any other order puts it a metre or more away,
# and the reprojection error (notebook 06), tens to hundreds of pixels, gives the mistake away: no rigid pose
# can put three markers' corners where the shuffled list says. `estimate_pose` checks this for you and raises
# `PoseError` instead of returning such a pose: a marker's corners listed anticlockwise on the screen (the
# mirrored and the upside-down orders) are refused before any solving, with the marker named, and a fit whose
# error is a large part of a marker's size is refused after it.
#
# With **one** marker the reprojection error does not warn you: a marker is a square, so its corners listed
# from the wrong starting point (rotated order) look exactly like the same marker turned by 90 degrees. The
# fit is perfect and the pose is wrong:

# %%
marker0 = [d for d in detections if d.id == 0]
right = estimate_pose(marker0, world_map, camera)
rotated = estimate_pose([Detection(0, marker0[0].corners_px[[1, 2, 3, 0]])], world_map, camera)
for name, pose in (("right order", right), ("rotated order", rotated)):
    err = np.linalg.norm(pose.position_mm - T_true[:3, 3])
    turn = frames.rotation_angle_deg(pose.T_world_camera[:3, :3], T_true[:3, :3])
    print(f"marker 0 alone, {name:13s}: position error {err:4.0f} mm, orientation error {turn:3.0f} deg, "
          f"reprojection RMS {pose.reprojection_rms_px:.2f} px")
assert np.linalg.norm(right.position_mm - T_true[:3, 3]) < 20
assert np.linalg.norm(rotated.position_mm - T_true[:3, 3]) > 150 and rotated.reprojection_rms_px < 0.5

fig = plotting.plot_scene(world_map, poses=[T_true, rotated, wrong_poses["TL, BL, BR, TR (mirrored)"]],
                          camera=camera, labels=["true", "one marker, rotated order", "three, mirrored order (solvePnP)"],
                          scale_mm=150, title="where the camera ends up when the corner order is wrong")
plt.show()

# %% [markdown]
# ## Summary
#
# * Detection today: `aruco.ArucoDetector(aruco.getPredefinedDictionary(...), aruco.DetectorParameters())`
#   and its `detectMarkers(gray)`; the pre-4.7 `Dictionary_get` / `DetectorParameters_create` /
#   `aruco.detectMarkers` fail with an `AttributeError`. Flatten `ids` (its shape changed in OpenCV 5).
#   `fidlearn.detection.detect_markers` does this for you and refines the corners.
# * Corners are good to about half a pixel unrefined, a few hundredths of a pixel with edge refinement
#   (measured on rendered pictures against their truth).
# * The corners always come TL, TR, BR, BL, starting at the **printed** marker's top-left and going clockwise in
#   the image, whichever way the marker is turned. Keep the same order in the map: a mixed-up order moves the
#   camera by metres (`estimate_pose` refuses a mirrored order, and a mixed-up one of several markers, with a
#   `PoseError`), and with a single marker nothing in the residuals warns you.
#
# **Exercises**: [exercises/05_detection.ipynb](exercises/05_detection.ipynb), with automatic feedback
# (or `from fidlearn import exercises; ex = exercises.lesson("05")` in a new cell).
#
# Next: [06 The pose from solvePnP](06_pose_solvepnp.ipynb).
