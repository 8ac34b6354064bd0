# %% [markdown]
# # 07 Where is the camera? Inverting the transform
#
# **What you will learn**
#
# * why `cv2.solvePnP` answers with **T_camera_world** (the world as the camera sees it), and why its `tvec`
#   is *not* the camera's position;
# * the derivation of the inverse, $T_{world\_camera} = T_{camera\_world}^{-1} = [R^T \mid -R^T t]$, and the
#   camera's position $C = -R^T t$;
# * the closed-form inverse against `np.linalg.inv`, and both against the true poses;
# * which way the camera looks, read from the pose;
# * a pose from a single marker, chained through the map: $T_{world\_camera} = T_{world\_marker}\, T_{marker\_camera}$;
# * the camera drawn in the world, with the markers it saw.
#
# Run the cells from top to bottom (Shift-Enter).

# %%
# %matplotlib inline
import json

import cv2
import matplotlib.pyplot as plt
import numpy as np

from fidlearn import Camera, MarkerMap, TransformError, data_path, frames, plotting
from fidlearn.detection import detect_markers, load_image

np.set_printoptions(precision=3, suppress=True)

# %% [markdown]
# ## 1. What solvePnP returns
#
# As in notebook 06, now with scene 2: the seed's wall seen from 1.3 m out and 1 m to the side (east), the camera
# a little lower than the markers.

# %%
camera = Camera.load(data_path("scenes", "camera.json"))
world_map = MarkerMap.load(data_path("world_map.json"))
scenes = json.loads(data_path("scenes", "poses.json").read_text())["images"]
record = scenes[2]
T_world_camera_true = np.array(record["T_world_camera"])

detections = detect_markers(load_image(data_path("scenes", record["image"])), world_map.dictionary)
world_corners = world_map.corners()
object_points = np.vstack([world_corners[d.id] for d in detections])  # (12, 3) mm, world
image_points = np.vstack([d.corners_px for d in detections])  # (12, 2) px

ok, rvec, tvec = cv2.solvePnP(object_points, image_points, camera.K, camera.dist, flags=cv2.SOLVEPNP_IPPE)
rvec, tvec = cv2.solvePnPRefineLM(object_points, image_points, camera.K, camera.dist, rvec, tvec)
assert ok
R, _ = cv2.Rodrigues(rvec)  # (3, 3)
t = tvec.reshape(3)  # (3,) mm
print("tvec (mm)                :", t)
print("true camera position (mm):", T_world_camera_true[:3, 3])

# %% [markdown]
# `tvec` looks nothing like the camera's position. The pose solvePnP finds is the one that **moves world
# points into the camera frame**, where projection happens (notebook 01):
#
# $$p_{camera} = R\, p_{world} + t, \qquad T_{camera\_world} = \begin{pmatrix} R & t \\ 0 & 1 \end{pmatrix}$$
#
# So `t` is where the **world's origin** is, in camera coordinates (x right, y down, z forward, mm), and R turns
# world axes into camera axes. Check: moving the world corners into the camera frame by hand and projecting
# them with the camera at the identity gives the detected pixels back.

# %%
T_camera_world = frames.make_transform(R, t)
corners_camera = object_points @ R.T + t  # R p + t for every row
assert np.allclose(corners_camera, frames.transform_points(T_camera_world, object_points))
print("corners in the camera frame (mm), first marker:\n", corners_camera[:4])
print("their depth z (mm):", corners_camera[:, 2].round(0))

reprojected = camera.project(corners_camera, np.eye(4))  # the camera frame is now the "world"
assert np.abs(reprojected - image_points).max() < 0.2  # pixels
assert np.all(corners_camera[:, 2] > 0)  # every corner in front of the camera

# %% [markdown]
# ## 2. The inverse, derived
#
# We want the camera's pose in the world, $T_{world\_camera}$: it maps camera coordinates to world coordinates,
# and its translation is the camera's centre. Solve $p_c = R\,p_w + t$ for $p_w$. A rotation matrix is
# orthonormal, $R^T R = I$, so multiplying on the left by $R^T$:
#
# $$R^T p_c = R^T R\, p_w + R^T t = p_w + R^T t \quad\Longrightarrow\quad p_w = R^T p_c - R^T t$$
#
# which is again a rotation and a translation:
#
# $$T_{world\_camera} = T_{camera\_world}^{-1} = \begin{pmatrix} R^T & -R^T t \\ 0 & 1 \end{pmatrix}$$
#
# The camera's centre is the origin of the camera frame, $p_c = 0$:
#
# $$C = -R^T t$$
#
# and the columns of $R^T$ are the camera's own axes (x right, y down, z along the optical axis) written in
# world coordinates. No general matrix inverse is needed: a transpose and a product.


# %%
def invert_closed_form(T_a_b):
    """Inverse of a rigid transform (4, 4): [R^T, -R^T t]."""
    R_ab, t_ab = T_a_b[:3, :3], T_a_b[:3, 3]
    T_b_a = np.eye(4)
    T_b_a[:3, :3] = R_ab.T
    T_b_a[:3, 3] = -R_ab.T @ t_ab
    return T_b_a


T_world_camera = invert_closed_form(T_camera_world)
C = -R.T @ t
print("camera position C = -R^T t (mm):", C)
print("true position (mm)             :", T_world_camera_true[:3, 3])
error_mm = np.linalg.norm(C - T_world_camera_true[:3, 3])
angle_deg = frames.rotation_angle_deg(T_world_camera[:3, :3], T_world_camera_true[:3, :3])
print(f"error: {error_mm:.2f} mm, {angle_deg:.3f} deg")

assert np.allclose(T_world_camera[:3, 3], C)
assert error_mm < 2 and angle_deg < 0.1
assert np.allclose(T_world_camera @ T_camera_world, np.eye(4))
# the camera's centre, moved into the camera frame, is the origin
assert np.allclose(frames.transform_points(T_camera_world, C[None])[0], 0, atol=1e-9)

# %% [markdown]
# ## 3. Closed form or `np.linalg.inv`?
#
# `np.linalg.inv(T)` gives the same matrix, to rounding. The closed form is cheaper and keeps the rotation
# block an exact transpose, so it stays orthonormal as well as R itself is; a general inverse (an LU
# factorisation) only approximates that. fidlearn's `frames.invert_transform` is the closed form, and checks
# that its input is a rigid transform first.

# %%
T_inv = np.linalg.inv(T_camera_world)
T_lib = frames.invert_transform(T_camera_world)
print("max |closed form - np.linalg.inv| below 1e-9 mm:", bool(np.abs(T_world_camera - T_inv).max() < 1e-9))
assert np.allclose(T_world_camera, T_inv, atol=1e-9) and np.array_equal(T_world_camera, T_lib)

# the transpose is exactly orthonormal when R is; inv's rotation block is within rounding of it
ortho_closed = np.abs(T_world_camera[:3, :3].T @ T_world_camera[:3, :3] - np.eye(3)).max()
ortho_inv = np.abs(T_inv[:3, :3].T @ T_inv[:3, :3] - np.eye(3)).max()
assert ortho_closed < 1e-12 and ortho_inv < 1e-12

# a matrix that is not a rigid transform (here a scaled rotation) is refused, not silently inverted
scaled = T_camera_world.copy()
scaled[:3, :3] *= 1.01
try:
    frames.invert_transform(scaled)
except TransformError as exc:
    print(f"TransformError: {exc}")
else:
    raise AssertionError("a scaled rotation must be refused")

# %% [markdown]
# ## 4. Two classic mistakes, measured
#
# * using `tvec` as the position;
# * forgetting the transpose: $-R\,t$ instead of $-R^T t$ (R and $R^T$ are different rotations unless the
#   rotation is 0 or 180 degrees).

# %%
candidates = {"C = -R^T t (right)": -R.T @ t, "tvec": t, "-R t (no transpose)": -R @ t}
for name, position in candidates.items():
    err = np.linalg.norm(position - T_world_camera_true[:3, 3])
    print(f"{name:22s} {position.round(0)} mm, {err:6.0f} mm from the truth")
    if name.startswith("C"):
        assert err < 2
    else:
        assert err > 500

# %% [markdown]
# ## 5. Checked on every scene
#
# The same three lines (solvePnP, LM, closed-form inverse) on all ten scenes, against the true
# `T_world_camera` of `poses.json`. Scenes 6-9 show two walls, so SQPnP replaces IPPE (notebook 06).

# %%
maps = {name: MarkerMap.load(data_path(name)) for name in ("world_map.json", "two_walls_map.json")}
print("scene         position error   orientation error")
for rec in scenes:
    m = maps[rec["map"]]
    dets = detect_markers(load_image(data_path("scenes", rec["image"])), m.dictionary)
    wc = m.corners()
    obj = np.vstack([wc[d.id] for d in dets])
    img = np.vstack([d.corners_px for d in dets])
    flag = "IPPE" if m.is_coplanar() else "SQPNP"
    ok, r, tv = cv2.solvePnP(obj, img, camera.K, camera.dist, flags=getattr(cv2, "SOLVEPNP_" + flag))
    r, tv = cv2.solvePnPRefineLM(obj, img, camera.K, camera.dist, r, tv)
    T_est = invert_closed_form(frames.transform_from_rvec_tvec(r, tv))
    T_true = np.array(rec["T_world_camera"])
    e_mm = np.linalg.norm(T_est[:3, 3] - T_true[:3, 3])
    e_deg = frames.rotation_angle_deg(T_est[:3, :3], T_true[:3, :3])
    print(f"{rec['image']}  {e_mm:10.1f} mm {e_deg:14.2f} deg")
    assert ok and e_mm < 15 and e_deg < 0.5

# %% [markdown]
# ## 6. Which way does the camera look?
#
# The third column of $R_{world\_camera} = R^T$ is the camera's optical axis (its +z) in world coordinates.
# Scene 2 was rendered with `look_at(eye, target)`: the camera at `eye`, looking at `target`, a point on the
# wall. Follow the optical axis from C until it meets the wall (the plane X = 0):

# %%
axis_world = T_world_camera[:3, 2]  # unit vector, world frame
heading_deg = np.degrees(np.arctan2(axis_world[1], axis_world[0]))  # in the floor plane, from +X towards +Y
elevation_deg = np.degrees(np.arcsin(axis_world[2]))  # above the horizon when positive
s = -C[0] / axis_world[0]  # C + s * axis has X = 0
hit = C + s * axis_world
target = np.array(record["look_at"]["target_mm"], dtype=float)
side = "above" if elevation_deg > 0 else "below"
print(f"optical axis {axis_world}: heading {heading_deg:.1f} deg, {abs(elevation_deg):.1f} deg {side} the horizon")
print("it meets the wall at", hit.round(1), "mm; look_at's target was", target)
assert np.linalg.norm(hit - target) < 10

# %% [markdown]
# (Here the camera looks slightly *up*, at markers above it: the axis has a positive Z component.)
#
# ## 7. A pose from one marker, chained through the map
#
# With a single marker it is natural to give the solver the corners in the **marker's own frame**: origin at
# its centre, x to the right, y up, z out of its face, side s. `SOLVEPNP_IPPE_SQUARE` is made for exactly these
# four points (in this order). It then returns $T_{camera\_marker}$: the marker as the camera sees it. The map
# says where the marker is, $T_{world\_marker}$ (`MarkerMap.T_world_marker`), and the names chain:
#
# $$T_{world\_camera} = T_{world\_marker}\; T_{marker\_camera} = T_{world\_marker}\; T_{camera\_marker}^{-1}$$

# %%
side = world_map.marker_size_mm
square = np.array(
    [
        [-side / 2, side / 2, 0],
        [side / 2, side / 2, 0],  # TL, TR
        [side / 2, -side / 2, 0],
        [-side / 2, -side / 2, 0],
    ]
)  # BR, BL, in the marker's frame, mm
marker0 = next(d for d in detections if d.id == 0)
ok, r0, t0 = cv2.solvePnP(square, marker0.corners_px, camera.K, camera.dist, flags=cv2.SOLVEPNP_IPPE_SQUARE)
T_camera_marker = frames.transform_from_rvec_tvec(r0, t0)
T_world_marker = world_map.T_world_marker(0)
T_world_camera_1 = T_world_marker @ invert_closed_form(T_camera_marker)

print(f"distance camera - marker 0 centre: |t| = {np.linalg.norm(t0):.0f} mm")
err1 = np.linalg.norm(T_world_camera_1[:3, 3] - T_world_camera_true[:3, 3])
print(f"camera from marker 0 alone: {T_world_camera_1[:3, 3].round(1)} mm, {err1:.1f} mm from the truth")
assert ok and err1 < 30
# the marker's frame, mapped into the world, puts its corners where the map has them
assert np.allclose(frames.transform_points(T_world_marker, square), world_corners[0], atol=1e-9)

# %% [markdown]
# Here one 80 mm marker, 1.6 m away, placed the camera within a few millimetres; three markers did better.
# A single marker is not always this kind: its orientation is poorly determined and it can flip between two
# poses (notebook 08).
#
# ## 8. The camera in the world
#
# The wall's markers and the camera where we found it (the true pose is a fraction of a millimetre away: it
# would be drawn on top). The pyramid's apex is the camera's centre C, its thick edge the top of the image;
# the dotted line is the optical axis, from C to where it meets the wall.

# %%
fig = plotting.plot_scene(
    world_map,
    poses=[T_world_camera],
    camera=camera,
    labels=["camera (found)"],
    scale_mm=250,
    extra_points=np.vstack([C, hit]),
    title="scene_02: the camera's pose in the world",
)
ax = fig.axes[0]
ax.plot(*np.column_stack([C, hit]), color="tab:orange", linestyle=":", linewidth=1)  # the optical axis to the wall
plt.show()

# %% [markdown]
# ## 9. A real photo: the markers' distances, and the paper they lie on
#
# OpenCV's tutorial photo (notebook 05) has no map, only six 50 mm markers on a sheet of paper, each 0.7 to
# 0.9 m from the camera (`data/README.md`). Each marker alone gives $T_{camera\_marker}$; the length of its
# translation is the distance to the marker's centre, and the six centres must lie on one plane, the paper.

# %%
photo_camera = Camera.load(data_path("real", "opencv_aruco_photo", "tutorial_camera_params.yml"), image_size=(640, 480))
photo = load_image(data_path("real", "opencv_aruco_photo", "singlemarkersoriginal.jpg"))
s50 = 50.0
square50 = np.array([[-s50 / 2, s50 / 2, 0], [s50 / 2, s50 / 2, 0], [s50 / 2, -s50 / 2, 0], [-s50 / 2, -s50 / 2, 0]])
centres = {}
for d in detect_markers(photo, "6X6_250"):
    ok, r, tv = cv2.solvePnP(square50, d.corners_px, photo_camera.K, photo_camera.dist, flags=cv2.SOLVEPNP_IPPE_SQUARE)
    centres[d.id] = tv.reshape(3)
    print(
        f"marker {d.id:3d}: centre at {centres[d.id].round(0)} mm in the camera frame, {np.linalg.norm(tv):.0f} mm away"
    )
distances = np.array([np.linalg.norm(c) for c in centres.values()])
assert np.all((distances > 650) & (distances < 950))

P = np.array(list(centres.values()))
_, sv, vt = np.linalg.svd(P - P.mean(axis=0))
normal = vt[2]
off_plane_mm = (P - P.mean(axis=0)) @ normal
print(
    f"the six centres lie within {np.abs(off_plane_mm).max():.0f} mm of one plane; "
    f"the camera is {abs(P.mean(axis=0) @ normal):.0f} mm above it"
)
assert np.abs(off_plane_mm).max() < 10

# %% [markdown]
# ## Try it
#
# Section 7 placed the camera from marker 0 alone. Will marker 1 or marker 2 alone do better or worse, and will
# a wrong inverse (`tvec` taken for the position) be off by millimetres or by metres? **Predict first**, then
# change `MARKER_ID` and run the cell.

# %%
MARKER_ID = 1  # 0, 1 or 2: the seed's wall

seen = next(d for d in detections if d.id == MARKER_ID)
ok, r_m, t_m = cv2.solvePnP(square, seen.corners_px, camera.K, camera.dist, flags=cv2.SOLVEPNP_IPPE_SQUARE)
T_found = world_map.T_world_marker(MARKER_ID) @ invert_closed_form(frames.transform_from_rvec_tvec(r_m, t_m))
wrong = world_map.T_world_marker(MARKER_ID) @ frames.transform_from_rvec_tvec(r_m, t_m)  # no inverse at all
print(
    f"marker {MARKER_ID} alone: camera {np.linalg.norm(T_found[:3, 3] - T_world_camera_true[:3, 3]):.1f} mm from "
    f"the truth; without the inverse {np.linalg.norm(wrong[:3, 3] - T_world_camera_true[:3, 3]):.0f} mm"
)

# %% [markdown]
# ## Summary
#
# * `cv2.solvePnP` returns $T_{camera\_world}$: $p_c = R\,p_w + t$. `tvec` is the world origin seen from the
#   camera, not the camera's position.
# * The camera's pose is the inverse, in closed form: $T_{world\_camera} = [R^T \mid -R^T t]$, its position
#   $C = -R^T t$, its optical axis the third column of $R^T$. It matched the true poses of all ten scenes.
# * `tvec` as the position, or $-R\,t$, are metres off.
# * From one marker in its own frame (IPPE_SQUARE), chain through the map:
#   $T_{world\_camera} = T_{world\_marker}\, T_{camera\_marker}^{-1}$.
# * In fidlearn: `frames.invert_transform`, `Pose.T_world_camera`, `Pose.position_mm`; `Pose.rvec`, `Pose.tvec`
#   are solvePnP's.
#
# **Exercises**: [exercises/07_inversion.ipynb](exercises/07_inversion.ipynb), with automatic feedback
# (or `from fidlearn import exercises; ex = exercises.lesson("07")` in a new cell).
#
# Next: [08 Accuracy and pitfalls](08_accuracy_pitfalls.ipynb).

# %% [markdown]
# ## References
#
# * K. M. Lynch and F. C. Park, *Modern Robotics: Mechanics, Planning, and Control*, Cambridge University Press,
#   2017, chapter 3 (rigid-body motions, the inverse of a transform, chaining frames): http://modernrobotics.org
# * OpenCV, `solvePnP` and `SOLVEPNP_IPPE_SQUARE`: https://docs.opencv.org/4.x/d5/d1f/calib3d_solvePnP.html
# * T. Collins and A. Bartoli, "Infinitesimal Plane-based Pose Estimation", International Journal of Computer
#   Vision 109(3), 2014.
