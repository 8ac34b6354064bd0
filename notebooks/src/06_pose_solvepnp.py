# %% [markdown]
# # 06 PnP: the pose from several markers with `cv2.solvePnP`
#
# **What you will learn**
#
# * how detections and the world map become **2D-3D correspondences**: every corner of every known marker
#   gives one pixel and one 3D point, matched by id and by the winding order TL, TR, BR, BL;
# * how `cv2.solvePnP` turns them into `rvec, tvec`, the extrinsics `T_camera_world`;
# * how the solvers differ (IPPE, SQPnP, iterative, EPnP), measured against the true pose, and which ones
#   fail on markers that all lie on one wall, or on several;
# * how to judge a pose without knowing the truth: the **reprojection error**, with `cv2.projectPoints`;
# * that `fidlearn.estimate_pose` does all of this in one call.
#
# Run the cells from top to bottom (Shift-Enter).

# %%
# %matplotlib inline
import json

import cv2
import matplotlib.pyplot as plt
import numpy as np

from fidlearn import Camera, MarkerMap, data_path, estimate_pose, frames, plotting
from fidlearn.detection import detect_markers, load_image

np.set_printoptions(precision=3, suppress=True)

# %% [markdown]
# ## 1. The picture, the camera and the map
#
# Scene 1 of `data/scenes/`: the seed's wall (three 80 mm markers) seen from 1.7 m, off to the side. We know the
# camera's intrinsics (`camera.json`, notebook 02), the markers' places (`world_map.json`, notebook 04) and,
# because the picture is rendered, the true pose to check against.

# %%
camera = Camera.load(data_path("scenes", "camera.json"))
world_map = MarkerMap.load(data_path("world_map.json"))
scenes = json.loads(data_path("scenes", "poses.json").read_text())["images"]

record = scenes[1]
image = load_image(data_path("scenes", record["image"]))
T_world_camera_true = np.array(record["T_world_camera"])
detections = detect_markers(image, world_map.dictionary)
print("detected:", [d.id for d in detections], " in the map:", world_map.ids)
markers_centre = np.vstack(list(world_map.corners().values())).mean(axis=0)
print(
    "true camera position (mm):",
    T_world_camera_true[:3, 3],
    f"- {np.linalg.norm(T_world_camera_true[:3, 3] - markers_centre) / 1000:.1f} m from the markers' centre",
)

ax = plotting.show_image(None, image, title=f"{record['image']}: three markers, twelve corners")
plotting.plot_detections(ax, detections)
plt.show()

# %% [markdown]
# ## 2. Matching 2D and 3D points
#
# The map gives each marker's four world corners in mm, in the order TL, TR, BR, BL (`MarkerMap.corners()`);
# the detector gives its four pixel corners in the same order (notebook 05). Stacking both, marker after
# marker, gives two arrays whose rows match: row k of `object_points` (mm, world) is seen at row k of
# `image_points` (pixels). A detected id that the map does not know is skipped.

# %%
world_corners = world_map.corners()  # {id: (4, 3) mm}

object_points, image_points, used = [], [], []
for d in detections:
    if d.id not in world_corners:
        continue  # a marker that is not on our wall
    object_points.append(world_corners[d.id])
    image_points.append(d.corners_px)
    used.append(d.id)
object_points = np.vstack(object_points).astype(np.float64)  # (4N, 3) mm, world frame
image_points = np.vstack(image_points).astype(np.float64)  # (4N, 2) px

print("object_points", object_points.shape, " image_points", image_points.shape, " markers", used)
names = ["TL", "TR", "BR", "BL"]
for k in range(4):
    print(f"marker {used[0]} {names[k]}: world {object_points[k]} mm  <->  pixel {image_points[k]}")
assert object_points.shape == (4 * len(used), 3) and image_points.shape == (4 * len(used), 2)

# %% [markdown]
# ## 3. `cv2.solvePnP`
#
# Perspective-n-Point: find the rotation R and translation t with
#
# $$\text{pixel}_k \approx \pi\!\left(K,\ \text{dist},\ R\, X_k + t\right)$$
#
# for every correspondence, where π is the projection of notebook 01. `solvePnP` returns R as a Rodrigues
# vector `rvec` and t as `tvec`: together they are **T_camera_world**, the transform that moves world points
# into the camera frame (notebook 03). The camera's own pose in the world is its inverse; notebook 07 derives
# it, here we just use `frames.invert_transform`.
#
# All our markers lie on one wall, so the points are **coplanar**: `SOLVEPNP_IPPE` is the solver made for
# that case. (Always name the flag, `cv2.SOLVEPNP_IPPE`: the numbers behind the names changed in OpenCV 5.)

# %%
ok, rvec, tvec = cv2.solvePnP(object_points, image_points, camera.K, camera.dist, flags=cv2.SOLVEPNP_IPPE)
assert ok
print("rvec:", rvec.ravel(), " tvec (mm):", tvec.ravel())

T_camera_world = frames.transform_from_rvec_tvec(rvec, tvec)
T_world_camera = frames.invert_transform(T_camera_world)
error_mm = np.linalg.norm(T_world_camera[:3, 3] - T_world_camera_true[:3, 3])
angle_deg = frames.rotation_angle_deg(T_world_camera[:3, :3], T_world_camera_true[:3, :3])
print(f"camera at {T_world_camera[:3, 3].round(1)} mm: {error_mm:.1f} mm and {angle_deg:.2f} deg from the truth")
assert error_mm < 10 and angle_deg < 0.5

# %% [markdown]
# The usual way to look at a pose in OpenCV is to draw it: `cv2.drawFrameAxes(image, K, dist, rvec, tvec,
# length)` projects a frame's x (red), y (green) and z (blue) axes, `length` mm long, with the pose `rvec, tvec`
# of that frame **in the camera**. With solvePnP's `rvec, tvec` that frame is the world: its origin lies on the
# floor below the wall, and its z points up. Each marker's own frame is `T_camera_marker = T_camera_world @
# T_world_marker` (notebook 03), its z out of the marker's face:

# %%
axes_image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR) if image.ndim == 2 else image.copy()
cv2.drawFrameAxes(axes_image, camera.K, camera.dist, rvec, tvec, 150, 3)  # the world frame, 150 mm axes
for marker_id in used:
    T_camera_marker = T_camera_world @ world_map.T_world_marker(marker_id)
    r_m, _ = cv2.Rodrigues(T_camera_marker[:3, :3])
    cv2.drawFrameAxes(axes_image, camera.K, camera.dist, r_m, T_camera_marker[:3, 3], 40, 2)
origin_px, _ = cv2.projectPoints(np.zeros(3), rvec, tvec, camera.K, camera.dist)
print(f"the world origin is drawn at pixel {origin_px.ravel().round(1)}")
ax = plotting.show_image(
    None, axes_image, title="cv2.drawFrameAxes: the world frame (long axes) and each marker's frame"
)
ax.set_xlim(origin_px[0, 0, 0] - 150, origin_px[0, 0, 0] + 250)
ax.set_ylim(origin_px[0, 0, 1] + 60, origin_px[0, 0, 1] - 260)
plt.show()

# %% [markdown]
# ## 4. Solvers compared
#
# `solvePnP` knows several algorithms:
#
# * **IPPE**: closed form for points on a plane; gives both poses of the planar ambiguity (notebook 08).
# * **SQPnP**: a globally optimal solver (sequential quadratic programming) for any layout, planar or not, from 3
#   points.
# * **ITERATIVE** (the default): a start from a homography (planar) or DLT (non-planar, needs 6 points), then
#   Levenberg-Marquardt on the reprojection error.
# * **EPnP**: expresses the points through four control points; fast, for many non-coplanar points.
#
# Let us run each on every scene and compare the camera position with the truth. Scenes 0-5 show the seed's
# wall (coplanar), scenes 6-9 the two-walls map (markers on the north wall and a side wall: not coplanar).

# %%
solvers = ["IPPE", "SQPNP", "ITERATIVE", "EPNP"]
maps = {name: MarkerMap.load(data_path(name)) for name in ("world_map.json", "two_walls_map.json")}


def solve_position_error_mm(flag, obj, img, T_true):
    """Position error (mm) of cv2.solvePnP with one solver, or NaN when it reports failure."""
    ok, r, t = cv2.solvePnP(obj, img, camera.K, camera.dist, flags=getattr(cv2, "SOLVEPNP_" + flag))
    if not ok:
        return np.nan
    T = frames.invert_transform(frames.transform_from_rvec_tvec(r, t))
    return float(np.linalg.norm(T[:3, 3] - T_true[:3, 3]))


table = np.full((len(scenes), len(solvers)), np.nan)
for s, rec in enumerate(scenes):
    m = maps[rec["map"]]
    found = detect_markers(load_image(data_path("scenes", rec["image"])), m.dictionary)
    corners3d = m.corners()
    obj = np.vstack([corners3d[d.id] for d in found if d.id in corners3d])
    img = np.vstack([d.corners_px for d in found if d.id in corners3d])
    for j, flag in enumerate(solvers):
        table[s, j] = solve_position_error_mm(flag, obj, img, np.array(rec["T_world_camera"]))

print("position error (mm) against the truth; 'fail' = solvePnP returned False")
print("scene  map                " + "".join(f"{f:>11s}" for f in solvers))
for s, rec in enumerate(scenes):
    cells = "".join(f"{'fail':>11s}" if np.isnan(v) else f"{v:11.1f}" for v in table[s])
    print(f"{s:5d}  {rec['map']:19s}{cells}")

planar, walls = table[:6], table[6:]
assert np.all(planar[:, :3] < 20)  # IPPE, SQPnP, iterative: within 2 cm on one wall
assert np.median(planar[:, 3]) > 500  # EPnP on coplanar points: metres off
assert np.all(np.isnan(walls[:, 0]))  # IPPE refuses points that are not on one plane
assert np.all(walls[:, 1:] < 20)  # the others handle two walls

# %% [markdown]
# What the table shows:
#
# * On a single wall, **IPPE**, **SQPnP** and **ITERATIVE** agree with the truth to millimetres; IPPE alone is a
#   little worse (up to about 2 cm in the face-on scene 0): it is a closed form, not a least-squares fit.
#   SQPnP and ITERATIVE minimise the reprojection error itself.
# * **EPnP** on coplanar points is a metre or more off in most scenes: its control points are degenerate
#   when all points lie on one plane. Never use it for markers on one wall.
# * With markers on two walls **IPPE fails** (it only works on a plane) and the others are fine.
#
# `fidlearn.estimate_pose` therefore uses IPPE for coplanar corners and SQPnP otherwise, and always finishes
# with Levenberg-Marquardt on the reprojection error.
#
# ## 5. The reprojection error
#
# Without ground truth, how do you know a pose is right? Project the 3D corners with the pose found
# (`cv2.projectPoints`, notebook 01) and compare with the detected pixels. The differences are the
# **residuals**; their RMS is the **reprojection error**. A good pose from good corners leaves a fraction of
# a pixel; a wrong map or a wrong corner order (notebook 05) leaves pixels or more. A wrong camera need not:
# in notebook 02 a K meant for another sensor mode (a 4:3 crop) gave a pose 14 cm off, and one for another
# resolution 1.2 m off, each with a residual under a tenth of a pixel,
# because the pose bends to fit the camera it is given. A small error says the pose agrees with the map and
# the camera you gave it, not that they are right.
#
# `cv2.solvePnPRefineLM` polishes a pose by Levenberg-Marquardt on exactly this error:


# %%
def reprojection(rvec, tvec):
    """Residuals (observed - projected, px, (N, 2)) and their RMS for a pose rvec, tvec = T_camera_world."""
    projected, _ = cv2.projectPoints(object_points, rvec, tvec, camera.K, camera.dist)
    residuals = image_points - projected.reshape(-1, 2)
    return residuals, float(np.sqrt(np.mean(np.sum(residuals**2, axis=1))))


residuals_ippe, rms_ippe = reprojection(rvec, tvec)
rvec_lm, tvec_lm = cv2.solvePnPRefineLM(object_points, image_points, camera.K, camera.dist, rvec.copy(), tvec.copy())
residuals_lm, rms_lm = reprojection(rvec_lm, tvec_lm)

T_lm = frames.invert_transform(frames.transform_from_rvec_tvec(rvec_lm, tvec_lm))
error_lm_mm = np.linalg.norm(T_lm[:3, 3] - T_world_camera_true[:3, 3])
print(f"IPPE     : reprojection RMS {rms_ippe:.3f} px, position error {error_mm:.1f} mm")
print(f"IPPE + LM: reprojection RMS {rms_lm:.3f} px, position error {error_lm_mm:.1f} mm")
assert rms_lm <= rms_ippe and rms_lm < 0.1
assert error_lm_mm < 2

# %% [markdown]
# The residual of each corner, as arrows from the detected corner (magnified 1000 times so a hundredth of a
# pixel shows as 10 pixels), and the residual lengths per corner:

# %%
projected_lm = image_points - residuals_lm
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4))
plotting.show_image(ax1, image)
err_px = plotting.draw_reprojection(ax1, image_points, projected_lm, scale=1000)
pad = 40
ax1.set_xlim(image_points[:, 0].min() - pad, image_points[:, 0].max() + pad)
ax1.set_ylim(image_points[:, 1].max() + pad, image_points[:, 1].min() - pad)
ax1.set_title("residuals after IPPE + LM, magnified x1000")
labels = [f"{i}{n}" for i in used for n in names]
ax2.bar(range(len(labels)), np.linalg.norm(residuals_ippe, axis=1), width=0.4, label="IPPE", align="edge")
ax2.bar(range(len(labels)), err_px, width=-0.4, label="IPPE + LM", align="edge")
ax2.set_xticks(range(len(labels)), labels, rotation=90)
ax2.set_ylabel("residual (px)")
ax2.set_title("residual per corner (marker id + corner)")
ax2.legend()
fig.tight_layout()
plt.show()
assert np.allclose(err_px, np.linalg.norm(residuals_lm, axis=1))

# %% [markdown]
# ## 6. All of it in one call: `fidlearn.estimate_pose`
#
# `estimate_pose(detections, marker_map, camera)` does sections 2-5: it matches ids, picks the solver
# (`ippe_square` for one marker, `ippe` on one plane, `sqpnp` otherwise), refines with LM, keeps the second
# planar solution (notebook 08), rejects a misplaced marker, and returns a `Pose` with the residuals and an
# uncertainty. `method=` names one OpenCV solver to compare them, as above.

# %%
pose = estimate_pose(detections, world_map, camera)
print(pose)
print("method:", pose.method, " markers:", pose.marker_ids, f" RMS {pose.reprojection_rms_px:.3f} px")

error_mm = np.linalg.norm(pose.position_mm - T_world_camera_true[:3, 3])
print(f"position error against the truth: {error_mm:.2f} mm")
assert error_mm < 3
assert frames.rotation_angle_deg(pose.T_world_camera[:3, :3], T_world_camera_true[:3, :3]) < 0.1
# the same pose as ours by hand (IPPE + LM), the same rvec/tvec convention as cv2.solvePnP
assert np.allclose(pose.tvec, tvec_lm.ravel(), atol=0.5) and np.allclose(pose.rvec, rvec_lm.ravel(), atol=1e-3)
assert abs(pose.reprojection_rms_px - rms_lm) < 0.01

# %% [markdown]
# And on every scene, one wall or two, against the truth:

# %%
errors_mm = []
for rec in scenes:
    m = maps[rec["map"]]
    p = estimate_pose(detect_markers(load_image(data_path("scenes", rec["image"])), m.dictionary), m, camera)
    errors_mm.append(np.linalg.norm(p.position_mm - np.array(rec["T_world_camera"])[:3, 3]))
    print(
        f"{rec['image']}: {p.method:9s} {len(p.marker_ids)} markers, RMS {p.reprojection_rms_px:.2f} px, "
        f"error {errors_mm[-1]:5.1f} mm"
    )
assert max(errors_mm) < 15 and np.median(errors_mm) < 3

# %% [markdown]
# ## Try it
#
# The corners are accurate to a few hundredths of a pixel here. What if they were noisier, say 0.5 px, as
# OpenCV's unrefined corners are (notebook 05)? Will the camera move by millimetres or centimetres? And will the
# reprojection RMS tell you? **Predict first**, then change `NOISE_PX` and run the cell.

# %%
NOISE_PX = 0.5  # standard deviation of the noise added to every corner, px; try 0.1, 1, 2

rng = np.random.default_rng(0)
noisy = image_points + rng.normal(0.0, NOISE_PX, image_points.shape)
ok, r_noisy, t_noisy = cv2.solvePnP(object_points, noisy, camera.K, camera.dist, flags=cv2.SOLVEPNP_IPPE)
r_noisy, t_noisy = cv2.solvePnPRefineLM(object_points, noisy, camera.K, camera.dist, r_noisy, t_noisy)
T_noisy = frames.invert_transform(frames.transform_from_rvec_tvec(r_noisy, t_noisy))
projected_noisy, _ = cv2.projectPoints(object_points, r_noisy, t_noisy, camera.K, camera.dist)
rms_noisy = np.sqrt(np.mean(np.sum((noisy - projected_noisy.reshape(-1, 2)) ** 2, axis=1)))
print(
    f"corner noise {NOISE_PX} px: camera {np.linalg.norm(T_noisy[:3, 3] - T_world_camera_true[:3, 3]):.1f} mm "
    f"from the truth, reprojection RMS {rms_noisy:.2f} px"
)

# %% [markdown]
# ## Summary
#
# * PnP needs matched pairs: each known marker gives four rows, world corners (mm) and pixel corners, in the
#   same TL, TR, BR, BL order.
# * `cv2.solvePnP(object_points, image_points, K, dist, flags=...)` returns `rvec, tvec` = **T_camera_world**;
#   the camera's pose is its inverse (notebook 07).
# * On one plane use IPPE (or SQPnP); never EPnP. Off a plane IPPE fails; use SQPnP. Finish with
#   Levenberg-Marquardt (`cv2.solvePnPRefineLM`).
# * The reprojection RMS (`cv2.projectPoints`) tells a good pose from a bad one without the truth: a few
#   hundredths of a pixel here.
# * `cv2.drawFrameAxes(image, K, dist, rvec, tvec, length)` draws a pose on the picture: the quickest check.
# * `fidlearn.estimate_pose` does it all and matched the truth to a few mm on every scene.
#
# **Exercises**: [exercises/06_pnp.ipynb](exercises/06_pnp.ipynb), with automatic feedback
# (or `from fidlearn import exercises; ex = exercises.lesson("06")` in a new cell).
#
# Next: [07 Where is the camera?](07_inverting_the_transform.ipynb)

# %% [markdown]
# ## References
#
# * OpenCV, "Perspective-n-Point (PnP) pose computation" (every solver, `solvePnPRefineLM`):
#   https://docs.opencv.org/4.x/d5/d1f/calib3d_solvePnP.html and `solvePnP`, `drawFrameAxes` in
#   https://docs.opencv.org/4.x/d9/d0c/group__calib3d.html
# * T. Collins and A. Bartoli, "Infinitesimal Plane-based Pose Estimation", International Journal of Computer
#   Vision 109(3), 2014: the IPPE solver.
# * G. Terzakis and M. Lourakis, "A Consistently Fast and Globally Optimal Solution to the Perspective-n-Point
#   Problem", ECCV 2020: SQPnP.
# * V. Lepetit, F. Moreno-Noguer and P. Fua, "EPnP: An Accurate O(n) Solution to the PnP Problem", IJCV 81, 2009.
