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
from fidlearn.detection import Detection, detect_markers, load_image, refine_corners_edges
from fidlearn.drawing import draw_detections

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
    dictionary = aruco.Dictionary_get(aruco.DICT_ARUCO_ORIGINAL)  # the seed's code
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
wall_centre = np.vstack(list(world_map.corners().values())).mean(axis=0)
away_m = [np.linalg.norm(np.array(rec["T_world_camera"])[:3, 3] - wall_centre) / 1000 for rec in scenes[:6]]
print(f"scenes 0 to 5: the camera {min(away_m):.1f} to {max(away_m):.1f} m from the markers")
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
# Without refinement the corners are right to half a pixel to a pixel; fitting the edges brings them to a few
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
# Plain OpenCV draws detections too: `cv2.aruco.drawDetectedMarkers(image, corners, ids)` outlines each marker
# in green, marks its first corner (TL) with a small red square and writes its id. It draws into the picture
# you give it (a 3-channel copy here) and wants the corners as OpenCV returns them, (1, 4, 2) float32 each:

# %%
photo_corners, photo_ids, _ = aruco.ArucoDetector(
    aruco.getPredefinedDictionary(aruco.DICT_6X6_250), aruco.DetectorParameters()
).detectMarkers(photo)
drawn = photo.copy() if photo.ndim == 3 else cv2.cvtColor(photo, cv2.COLOR_GRAY2BGR)
cv2.aruco.drawDetectedMarkers(drawn, photo_corners, np.asarray(photo_ids).reshape(-1, 1))
print("drawDetectedMarkers on", len(photo_corners), "markers, ids", sorted(np.asarray(photo_ids).ravel().tolist()))
assert sorted(np.asarray(photo_ids).ravel().tolist()) == [23, 40, 62, 98, 124, 203]
plotting.show_image(None, drawn, title="cv2.aruco.drawDetectedMarkers: outline, id, and a red square on TL")
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
    print(
        f"marker {d.id:3d}: signed area {signed_area_px2(d.corners_px):6.0f} px^2, turned {turns[d.id]:3d} deg "
        "clockwise"
    )
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
    print(
        f"marker 0 alone, {name:13s}: position error {err:4.0f} mm, orientation error {turn:3.0f} deg, "
        f"reprojection RMS {pose.reprojection_rms_px:.2f} px"
    )
assert np.linalg.norm(right.position_mm - T_true[:3, 3]) < 20
assert np.linalg.norm(rotated.position_mm - T_true[:3, 3]) > 150 and rotated.reprojection_rms_px < 0.5

shown = {
    "true pose": (T_true, "tab:green"),
    "one marker, rotated order": (rotated.T_world_camera, "tab:orange"),
    "three, mirrored order (solvePnP)": (wrong_poses["TL, BL, BR, TR (mirrored)"], "tab:red"),
}
frustums = np.vstack([plotting.camera_frustum(camera, T, 150) for T, _ in shown.values()])
fig = plotting.plot_scene(
    world_map, extra_points=frustums, title="where the camera ends up when the corner order is wrong"
)
ax = fig.axes[0]
for name, (T, colour) in shown.items():
    plotting.draw_camera(ax, camera, T, scale_mm=150, color=colour, show_axes=False)[0].set_label(name)
ax.legend(loc="upper left", fontsize=8)
plt.show()

# %% [markdown]
# ## 7. Sub-pixel corners: how the `edges` refinement works
#
# Section 3 showed OpenCV's unrefined corners half a pixel to a pixel from the truth, and `edges` a few
# hundredths. Here is the whole method, written out on marker 0 of scene 0, starting from OpenCV's unrefined
# corners. The idea: **a corner is where two straight edges meet, and an edge is easy to locate to a fraction
# of a pixel** along its whole length, while the corner itself is rounded by blur.
#
# 1. Across each of the four sides, sample 16 short **profiles** of the gray level (bilinear interpolation,
#    `cv2.remap`), from inside the black border to the white margin, keeping clear of the corners.
# 2. The edge is where a profile crosses the gray level **half-way** between black (the darkest samples
#    inside) and white (the brightest outside): find that crossing between two samples by linear interpolation.
# 3. Fit a **straight line** through each side's 16 edge points (total least squares: the first singular
#    vector of the centred points).
# 4. Each corner is the **intersection** of its two sides' lines.

# %%
CELLS = 7  # ARUCO_ORIGINAL: 5 x 5 bits and a one-cell black border


def edge_points(gray, quad, cells, n_profiles=16, n_steps=13):
    """Sub-pixel edge points (list of four (n, 2) arrays, px) across the sides TL-TR, TR-BR, BR-BL, BL-TL."""
    cell_px = np.linalg.norm(np.roll(quad, -1, axis=0) - quad, axis=1).mean() / cells
    half = np.clip(0.6 * cell_px, 1.5, 5.0)  # each profile reaches 0.6 cell either side of the side
    steps = np.linspace(-half, half, n_steps)
    sides = []
    for k in range(4):
        a, b = quad[k], quad[(k + 1) % 4]
        along = (b - a) / np.linalg.norm(b - a)
        normal = np.array([along[1], -along[0]])  # points outwards: corners run clockwise on screen
        margin = min((0.5 * cell_px + 1.5) / np.linalg.norm(b - a), 0.3)
        t = np.linspace(margin, 1 - margin, n_profiles)
        # OpenCV's outline runs through the centres of the outermost dark pixels: start half a pixel out
        starts = a + t[:, None] * (b - a) + 0.5 * normal
        samples_xy = starts[:, None, :] + steps[None, :, None] * normal  # (n_profiles, n_steps, 2)
        profiles = cv2.remap(gray, samples_xy.astype(np.float32), None, cv2.INTER_LINEAR).astype(float)
        mid = n_steps // 2
        black = np.median(profiles[:, : mid + 1].min(axis=1))
        white = np.median(profiles[:, mid:].max(axis=1))
        level = 0.5 * (black + white)
        points = []
        for start, row in zip(starts, profiles):
            j = int(np.argmax(row >= level))  # first sample at or above the half-way level
            if j == 0:
                continue
            s = steps[j - 1] + (level - row[j - 1]) / (row[j] - row[j - 1]) * (steps[j] - steps[j - 1])
            points.append(start + s * normal)
        sides.append(np.array(points))
    return sides


def fit_line(points):
    """Total least squares line through (n, 2) points: (a point on it, its unit direction)."""
    centre = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - centre)
    return centre, vt[0]


def intersect(line1, line2):
    """The point where two lines (point, direction) cross."""
    (p, d), (q, e) = line1, line2
    s, _ = np.linalg.solve(np.column_stack([d, -e]), q - p)
    return p + s * d


gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
unrefined = {d.id: d.corners_px for d in detect_markers(image, world_map.dictionary, refine="none")}
subpixel = {d.id: d.corners_px for d in detect_markers(image, world_map.dictionary, refine="subpix")}
quad = unrefined[0]
sides = edge_points(gray, quad, CELLS)
lines = [fit_line(p) for p in sides]
ours = np.array([intersect(lines[(k - 1) % 4], lines[k]) for k in range(4)])  # corner k: sides k-1 and k
library = refine_corners_edges(gray, quad[None], CELLS)[0]

names = ["TL", "TR", "BR", "BL"]
print("corner   OpenCV unrefined   OpenCV subpix   ours (edges)   library edges   (error from the truth, px)")
for k in range(4):
    e = [np.linalg.norm(c[k] - true_corners[0][k]) for c in (quad, subpixel[0], ours, library)]
    print(f"{names[k]:6s} {e[0]:14.3f} {e[1]:15.3f} {e[2]:14.3f} {e[3]:15.3f}")
assert np.abs(ours - true_corners[0]).max() < 0.15
assert np.abs(ours - library).max() < 0.05  # the few lines above are fidlearn's method
assert np.linalg.norm(quad - true_corners[0], axis=1).mean() > 3 * np.linalg.norm(ours - true_corners[0], axis=1).mean()

# %% [markdown]
# The picture: on the left the whole marker with the 64 edge points and the four fitted lines; on the right a
# zoom on its top-left corner, where every square is one pixel (pixel centres at whole numbers).

# %%
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.5))
x0, y0 = np.floor(quad.min(axis=0)) - 6
x1, y1 = np.ceil(quad.max(axis=0)) + 6
for ax, (left, right, top, bottom) in (
    (ax1, (x0, x1, y0, y1)),
    (ax2, (ours[0][0] - 5, ours[0][0] + 5, ours[0][1] - 5, ours[0][1] + 5)),
):
    ax.imshow(gray, cmap="gray", vmin=0, vmax=255, interpolation="nearest")
    for k, (p, d) in enumerate(lines):
        ends = p + np.outer([-200, 200], d)
        ax.plot(ends[:, 0], ends[:, 1], color="tab:cyan", linewidth=1, label="fitted edge lines" if k == 0 else None)
    edge_xy = np.vstack(sides)
    ax.plot(edge_xy[:, 0], edge_xy[:, 1], ".", color="tab:orange", markersize=5, label="edge points (half-way level)")
    ax.plot(quad[:, 0], quad[:, 1], "x", color="tab:red", markersize=9, mew=2, label="OpenCV, unrefined")
    ax.plot(subpixel[0][:, 0], subpixel[0][:, 1], "^", color="tab:purple", markersize=7, label="OpenCV, subpix")
    ax.plot(
        ours[:, 0], ours[:, 1], "o", mfc="none", color="tab:green", markersize=10, mew=2, label="intersection (edges)"
    )
    ax.plot(true_corners[0][:, 0], true_corners[0][:, 1], "+", color="yellow", markersize=12, mew=2, label="truth")
    ax.set_xlim(left, right)
    ax.set_ylim(bottom, top)
ax1.set_title("marker 0 of scene_00: edge points and lines")
ax2.set_title("zoom on TL (one square = one pixel)")
ax2.legend(loc="lower right", fontsize=8, framealpha=0.9)
fig.tight_layout()
plt.show()

# %% [markdown]
# ## 8. Why OpenCV's corners sit inside the marker
#
# OpenCV finds a marker by thresholding the picture and tracing the outline of the black blob. That outline
# runs through the **centres of the outermost dark pixels**, which lie about half a pixel inside the true
# edge; the unrefined corners are its polygon's vertices, at whole pixels. `CORNER_REFINE_CONTOUR` fits lines to
# the same outline, so it keeps the offset. `CORNER_REFINE_SUBPIX` (`cv2.cornerSubPix`) looks at the corner
# itself in a small window; blur rounds a corner, so the gray pattern there is pulled towards the inside of
# the black square, and so is the corner it finds. An edge line, away from the corners, is not rounded.
#
# Measure it: the **radial offset** of each corner, its error along the direction from the marker's centre
# to the true corner (negative = inwards), over the 72 corners of scenes 0 to 5:


# %%
def radial_offset_px(found_quad, true_quad):
    """Signed offset (px, (4,)) of each corner along the outward direction from the marker's centre."""
    outward = true_quad - true_quad.mean(axis=0)
    outward /= np.linalg.norm(outward, axis=1, keepdims=True)
    return np.sum((found_quad - true_quad) * outward, axis=1)


radial = {r: [] for r in refinements}
for rec in scenes[:6]:
    img = load_image(data_path("scenes", rec["image"]))
    truth = {int(i): np.array(c) for i, c in rec["corners_px"].items()}
    for r in refinements:
        radial[r] += [
            radial_offset_px(d.corners_px, truth[d.id]) for d in detect_markers(img, world_map.dictionary, refine=r)
        ]
radial = {r: np.concatenate(v) for r, v in radial.items()}
print("refinement   mean radial offset (px, negative = inwards)   corners inside the truth")
for r, v in radial.items():
    print(f"{r:10s} {v.mean():+20.3f} {np.mean(v < 0) * 100:33.0f} %")
assert radial["none"].mean() < -0.3 and radial["contour"].mean() < -0.3 and radial["subpix"].mean() < -0.1
assert abs(radial["edges"].mean()) < 0.05

# %% [markdown]
# A marker whose corners all sit half a pixel inwards looks **smaller** than it is, so the camera seems
# further away: a systematic error that averaging over frames does not remove (notebook 08 measures it on the
# pose).
#
# ## 9. On real photos
#
# Real photos have no corner truth, but they can be checked against a known geometry. The ChArUco board of
# `data/real/opencv_charuco/` (five 640 x 480 photos; 20 mm `6X6_250` markers on a flat 5 x 7 board) is flat:
# once the lens distortion is removed (with the tutorial's calibration), the board's marker corners must map to
# the picture by **one homography**. The RMS residual of that fit measures how consistent the corners are with
# the board's geometry (print and lens errors count the same for every method). Smaller is better:

# %%
charuco_camera = Camera.load(data_path("real", "opencv_charuco", "tutorial_camera_charuco.yml"))
board = aruco.CharucoBoard((5, 7), 40.0, 20.0, aruco.getPredefinedDictionary(aruco.DICT_6X6_250))
board_xy = {
    int(i): np.asarray(o, float).reshape(4, 3)[:, :2] for i, o in zip(np.ravel(board.getIds()), board.getObjPoints())
}  # mm on the board
board_photos = [
    load_image(data_path("real", "opencv_charuco", n))
    for n in ("img_00.jpg", "img_01.jpg", "img_02.jpg", "img_03.jpg", "chocclusion_original.jpg")
]

homography_rms = {}
for r in ["none", "subpix", "contour", "apriltag", "edges"]:
    residuals, n_markers = [], 0
    for ph in board_photos:
        dets = [d for d in detect_markers(ph, "6X6_250", refine=r) if d.id in board_xy]
        on_board = np.concatenate([board_xy[d.id] for d in dets])
        in_photo = cv2.undistortPoints(
            np.concatenate([d.corners_px for d in dets]).reshape(-1, 1, 2),
            charuco_camera.K,
            charuco_camera.dist,
            P=charuco_camera.K,
        ).reshape(-1, 2)
        H, _ = cv2.findHomography(on_board, in_photo, 0)  # 0: plain least squares, every corner counts
        residuals.append(in_photo - cv2.perspectiveTransform(on_board.reshape(-1, 1, 2), H).reshape(-1, 2))
        n_markers += len(dets)
    homography_rms[r] = float(np.sqrt(np.mean(np.sum(np.concatenate(residuals) ** 2, axis=1))))
    print(f"{r:8s}: {n_markers} markers in 5 photos, homography residual RMS {homography_rms[r]:.3f} px")
opencv_best = min(homography_rms[r] for r in ("none", "subpix", "contour"))
print(f"the best of none, subpix and contour is {opencv_best / homography_rms['edges']:.1f} x the edges residual")
assert homography_rms["edges"] < 0.6 * opencv_best

# %% [markdown]
# `edges` fits the flat board about twice as well as OpenCV's none, subpix and contour (the ratio printed
# above). `apriltag` does as well here, but it shifts every corner by the mean (dx, dy) printed in the next
# table, which a homography absorbs and a pose does not; it also misses small markers and is many times slower
# (docs/corner_refinement.md).
#
# On the tutorial's single-marker photo of section 4 there is no board, but we can compare the refinements
# with each other: how far, and in which direction, does each method's corner lie from the `edges` corner?

# %%
edges_photo = {d.id: d.corners_px for d in detect_markers(photo, "6X6_250", refine="edges")}
print("refinement   mean distance from edges (px)   edges further out by (px)   mean shift (dx, dy) px")
for r in ["none", "subpix", "contour", "apriltag"]:
    dist_px, outward_px, shift = [], [], []
    for d in detect_markers(photo, "6X6_250", refine=r):
        e = edges_photo[d.id]
        dist_px.append(np.linalg.norm(e - d.corners_px, axis=1))
        outward_px.append(-radial_offset_px(d.corners_px, e))  # > 0: the edges corner lies further out
        shift.append(d.corners_px - e)
    dist_px, outward_px, shift = np.concatenate(dist_px), np.concatenate(outward_px), np.concatenate(shift)
    print(
        f"{r:10s} {dist_px.mean():22.2f} {outward_px.mean():27.2f}      ({shift[:, 0].mean():+.2f}, "
        f"{shift[:, 1].mean():+.2f})"
    )
    if r in ("none", "contour"):
        assert outward_px.mean() > 0.3  # the same inward offset as on the renders

# %% [markdown]
# ## 10. How far plain OpenCV gets
#
# Without fidlearn, the detector's parameters are what you can tune: `cornerRefinementMethod`
# (`CORNER_REFINE_NONE`, `_SUBPIX`, `_CONTOUR`, `_APRILTAG`) and, for subpix, the window
# `cornerRefinementWinSize`. Since OpenCV 4.7 the window is also capped at `relativeCornerRefinmentWinSize`
# (sic, 0.3 by default) times the marker's cell size, so on these markers (cell sizes printed below) a larger
# `cornerRefinementWinSize` changes nothing until the relative cap is raised too. The same six scenes,
# plain `cv2.aruco.ArucoDetector`:

# %%
scene_images = [
    (load_image(data_path("scenes", rec["image"])), {int(i): np.array(c) for i, c in rec["corners_px"].items()})
    for rec in scenes[:6]
]
cells_px = [
    np.linalg.norm(np.roll(c, -1, axis=0) - c, axis=1).mean() / CELLS
    for _, truth in scene_images
    for c in truth.values()
]
print(
    f"cell size of the markers: {min(cells_px):.1f} to {max(cells_px):.1f} px; 0.3 cell = "
    f"{0.3 * min(cells_px):.1f} to {0.3 * max(cells_px):.1f} px"
)
settings = [
    ("CORNER_REFINE_NONE", {}),
    ("CORNER_REFINE_SUBPIX", {"cornerRefinementWinSize": 2}),
    ("CORNER_REFINE_SUBPIX", {"cornerRefinementWinSize": 5}),  # the default
    ("CORNER_REFINE_SUBPIX", {"cornerRefinementWinSize": 10}),
    ("CORNER_REFINE_SUBPIX", {"cornerRefinementWinSize": 10, "relativeCornerRefinmentWinSize": 0.5}),
    ("CORNER_REFINE_SUBPIX", {"cornerRefinementWinSize": 10, "relativeCornerRefinmentWinSize": 1.0}),
    ("CORNER_REFINE_CONTOUR", {}),
    ("CORNER_REFINE_APRILTAG", {}),
]
table = {}
print(f"{'cornerRefinementMethod':24s} {'window settings':34s} corners  RMS error  max error  radial  (px)")
for method, extra in settings:
    params = aruco.DetectorParameters()
    params.cornerRefinementMethod = getattr(aruco, method)
    for field, value in extra.items():
        setattr(params, field, value)
    plain = aruco.ArucoDetector(aruco.getPredefinedDictionary(aruco.DICT_ARUCO_ORIGINAL), params)
    err, rad = [], []
    for img, truth in scene_images:
        cs, found_ids, _ = plain.detectMarkers(img)
        for c, i in zip(cs, np.asarray(found_ids).reshape(-1)):
            c = c.reshape(4, 2).astype(np.float64)
            err.append(np.linalg.norm(c - truth[int(i)], axis=1))
            rad.append(radial_offset_px(c, truth[int(i)]))
    err, rad = np.concatenate(err), np.concatenate(rad)
    window = ", ".join(
        f"{k.replace('cornerRefinement', '').replace('relativeCornerRefinment', 'relative')}={v}"
        for k, v in extra.items()
    )
    table[(method, window)] = float(np.sqrt(np.mean(err**2)))
    print(
        f"{method:24s} {window:34s} {len(err):7d} {table[(method, window)]:10.3f} {err.max():10.3f} {rad.mean():+7.3f}"
    )
edges_rms = float(np.sqrt(np.mean(errors["edges"] ** 2)))
print(
    f"{'fidlearn edges':24s} {'':34s} {len(errors['edges']):7d} {edges_rms:10.3f} {errors['edges'].max():10.3f} "
    f"{radial['edges'].mean():+7.3f}"
)
best_plain = min(table.values())
print(f"best plain OpenCV setting: {best_plain:.3f} px RMS, {best_plain / edges_rms:.0f} x fidlearn's edges")
assert table[("CORNER_REFINE_SUBPIX", "WinSize=5")] == table[("CORNER_REFINE_SUBPIX", "WinSize=10")]
assert best_plain > 2 * edges_rms

# %% [markdown]
# What plain OpenCV can do: subpix with a window of about half a cell
# (`cornerRefinementWinSize=10, relativeCornerRefinmentWinSize=0.5`) is its best setting here, and still
# biased inwards; a window wider than a cell reaches the marker's inner bits and can lock onto the wrong
# corner. `apriltag` removes the inward bias but reports corners shifted and is slow. To get the edges' accuracy
# with plain OpenCV, detect without refinement and refine the corners yourself with the thirty lines of
# section 7 (or `fidlearn.detection.refine_corners_edges(gray, corners, cells)`).
#
# ## 11. Try it
#
# How does the error of OpenCV's unrefined corners change when the picture is blurred, and the edges'?
# **Predict first**, then set `BLUR_PX` (the standard deviation of a Gaussian blur, pixels; try 0.5, 1.5, 3)
# and run the cell.

# %%
BLUR_PX = 1.5  # try 0.5, 1.5, 3.0

blurred = cv2.GaussianBlur(image, (0, 0), BLUR_PX) if BLUR_PX > 0 else image.copy()
for r in ("none", "subpix", "edges"):
    got = detect_markers(blurred, world_map.dictionary, refine=r)
    e = np.concatenate([np.linalg.norm(d.corners_px - true_corners[d.id], axis=1) for d in got]) if got else []
    print(
        f"blur {BLUR_PX} px, {r:6s}: {len(got)} markers, mean corner error "
        f"{np.mean(e) if len(e) else float('nan'):.3f} px"
    )

# %% [markdown]
# ## Summary
#
# * Detection today: `aruco.ArucoDetector(aruco.getPredefinedDictionary(...), aruco.DetectorParameters())`
#   and its `detectMarkers(gray)`; the pre-4.7 `Dictionary_get` / `DetectorParameters_create` /
#   `aruco.detectMarkers` fail with an `AttributeError`. Flatten `ids` (its shape changed in OpenCV 5).
#   `fidlearn.detection.detect_markers` does this for you and refines the corners.
# * Corners are good to half a pixel to a pixel unrefined, a few hundredths of a pixel with edge refinement
#   (measured on rendered pictures against their truth).
# * The `edges` refinement samples profiles across the four outer edges, finds the half-way gray level in each,
#   fits a line per side and intersects neighbouring lines. OpenCV's corners sit inwards (the thresholded
#   outline runs through dark pixel centres; blur rounds the corner that `cornerSubPix` looks at); on the real
#   ChArUco photos the edges corners fit the flat board best, and no `cornerRefinementMethod` or window setting
#   of plain OpenCV comes close on the renders.
# * The corners always come TL, TR, BR, BL, starting at the **printed** marker's top-left and going clockwise in
#   the image, whichever way the marker is turned. Keep the same order in the map: a mixed-up order moves the
#   camera by metres (`estimate_pose` refuses a mirrored order, and a mixed-up one of several markers, with a
#   `PoseError`), and with a single marker nothing in the residuals warns you.
#
# **Exercises**: [exercises/05_detection.ipynb](exercises/05_detection.ipynb), with automatic feedback
# (or `from fidlearn import exercises; ex = exercises.lesson("05")` in a new cell).
#
# Next: [06 The pose from solvePnP](06_pose_solvepnp.ipynb).

# %% [markdown]
# ## References
#
# * OpenCV, "Detection of ArUco Markers" tutorial: https://docs.opencv.org/4.x/d5/dae/tutorial_aruco_detection.html
#   (the detector, its parameters, `drawDetectedMarkers`).
# * OpenCV, `cv::aruco::DetectorParameters` (the `cornerRefinement*` fields):
#   https://docs.opencv.org/4.x/d1/dcd/structcv_1_1aruco_1_1DetectorParameters.html
# * OpenCV, `cv::cornerSubPix`: https://docs.opencv.org/4.x/dd/d1a/group__imgproc__feature.html
# * fidlearn's measurements of every refinement: `docs/corner_refinement.md` in this repository.
