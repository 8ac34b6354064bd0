# %% [markdown]
# # 03 Extrinsics: rotations, translations and frames
#
# **What you will learn**
#
# * how a rotation matrix R and a translation t describe where one frame is in another;
# * the 4x4 homogeneous matrix `T_a_b` and the naming rule `p_a = T_a_b @ p_b`, so names chain:
#   `T_world_marker = T_world_camera @ T_camera_marker`;
# * OpenCV's Rodrigues vectors (`rvec`), and that solvePnP's `rvec, tvec` are `T_camera_world`;
# * the closed-form inverse `[R^T, -R^T t]`, which turns the extrinsics into the camera's pose;
# * roll, pitch and yaw, and why their order matters;
# * the ROS Z-up world versus a Y-up world (graphics, games), and how to convert a pose between them.

# %%
# %matplotlib inline
import math

import cv2
import matplotlib.pyplot as plt
import numpy as np

from fidlearn import Camera, MarkerMap, data_path, frames, look_at, plotting

np.set_printoptions(precision=3, suppress=True)

# %% [markdown]
# ## 1. Rotations
#
# A rotation matrix R (3x3) turns vectors. Its **columns** are the rotated frame's x, y, z axes written in
# the original frame; they are unit vectors at right angles (R^T R = I) and det R = +1 (no mirror).
# A rotation by θ about Z:
#
# $$R_z(\theta) = \begin{pmatrix} \cos\theta & -\sin\theta & 0 \\ \sin\theta & \cos\theta & 0 \\ 0 & 0 & 1 \end{pmatrix}$$

# %%
theta = math.radians(90)  # radians inside the maths; degrees only at the edges
Rz = np.array([[math.cos(theta), -math.sin(theta), 0], [math.sin(theta), math.cos(theta), 0], [0, 0, 1]])
print(Rz.round(12))
assert np.allclose(Rz, frames.rot_z(theta))
assert np.allclose(Rz @ [1, 0, 0], [0, 1, 0])  # X turns into Y (right-hand rule about Z)
assert np.allclose(Rz.T @ Rz, np.eye(3)) and math.isclose(np.linalg.det(Rz), 1.0)

# %% [markdown]
# ## 2. Frames and the 4x4 matrix
#
# A **frame** is an origin plus three axes. The pose of frame *b* in frame *a* is a rotation `R_a_b`
# (b's axes in a's coordinates) and a translation `t_a_b` (b's origin in a's coordinates, mm). A point
# known in b is then, in a,
#
# $$p_a = R_{ab}\, p_b + t_{ab}$$
#
# Both fit in one 4x4 matrix acting on (x, y, z, 1):
#
# $$T_{ab} = \begin{pmatrix} R_{ab} & t_{ab} \\ 0\;0\;0 & 1 \end{pmatrix}, \qquad
# \begin{pmatrix} p_a \\ 1 \end{pmatrix} = T_{ab} \begin{pmatrix} p_b \\ 1 \end{pmatrix}$$
#
# fidlearn writes the frames into the names: `T_world_camera` is the camera's pose in the world,
# and the inner names of a product must match: `T_a_b @ T_b_c = T_a_c`.

# %%
# a camera 2 m into the room, 30 cm to the side, 1.2 m up, looking back at the north wall
T_world_camera = look_at([2000, 300, 1200], [0, 200, 300])
print("T_world_camera =\n", T_world_camera)

R_world_camera = T_world_camera[:3, :3]
t_world_camera = T_world_camera[:3, 3]
p_camera = np.array([0.0, 0.0, 1000.0])  # 1 m straight ahead of the lens, in the camera frame
p_world = R_world_camera @ p_camera + t_world_camera
p_world_h = T_world_camera @ np.append(p_camera, 1.0)
print("1 m in front of the camera is, in the world:", p_world)
assert np.allclose(p_world_h[:3], p_world) and p_world_h[3] == 1.0
assert np.allclose(frames.transform_points(T_world_camera, p_camera), p_world)

# the camera's z axis (third column) points from the camera towards what it looks at
towards_target = np.array([0, 200, 300]) - t_world_camera
assert np.allclose(R_world_camera[:, 2], towards_target / np.linalg.norm(towards_target))

# %% [markdown]
# The camera frame is OpenCV's: x right, y **down**, z forward. In the picture the camera is the
# orange pyramid (apex at the lens centre, base = the image, the thick edge is the image's top), with
# its own axes x red, y green, z blue; the world axes are drawn at the origin, Z up.

# %%
wall = MarkerMap.load(data_path("world_map.json"))
camera = Camera.from_fov(60, (640, 480))
fig = plotting.plot_scene(wall, poses=[T_world_camera], camera=camera, scale_mm=400,
                          title="the seed wall and a camera at T_world_camera")
plt.show()

# %% [markdown]
# ## 3. Rodrigues vectors: OpenCV's rotations
#
# OpenCV stores a rotation as a 3-vector `rvec`: its direction is the rotation axis, its length the angle
# in radians. `cv2.Rodrigues` converts both ways.

# %%
rvec = np.array([0.0, 0.0, math.radians(90)])  # 90 degrees about Z
R, _ = cv2.Rodrigues(rvec)
print(R.round(12))
assert np.allclose(R, Rz)

R_any = frames.rotation_from_rpy_deg(10, -20, 35)
rvec_any, _ = cv2.Rodrigues(R_any)
rvec_any = rvec_any.ravel()
angle_deg = math.degrees(np.linalg.norm(rvec_any))
print("rvec:", rvec_any, f"-> a rotation of {angle_deg:.2f} deg about", rvec_any / np.linalg.norm(rvec_any))
assert math.isclose(angle_deg, frames.rotation_angle_deg(R_any))
assert np.allclose(cv2.Rodrigues(rvec_any)[0], R_any)  # and back

# %% [markdown]
# ## 4. Extrinsics: the world seen from the camera
#
# To project a world point, OpenCV first needs it in the camera frame: `p_camera = T_camera_world @ p_world`.
# `T_camera_world` is the **extrinsic matrix**, and it is what `cv2.solvePnP` returns as `rvec, tvec`
# (and what `cv2.projectPoints` takes). It is **not** the camera's pose: its translation is where the
# world's origin is as seen from the camera. The pose `T_world_camera` is its inverse.
#
# The inverse of a rigid transform has a closed form, no general matrix inversion needed:
#
# $$T_{ab}^{-1} = T_{ba} = \begin{pmatrix} R^T & -R^T t \\ 0 & 1 \end{pmatrix}$$

# %%
R = T_world_camera[:3, :3]
t = T_world_camera[:3, 3]
T_camera_world = np.eye(4)
T_camera_world[:3, :3] = R.T
T_camera_world[:3, 3] = -R.T @ t
print("T_camera_world =\n", T_camera_world)

assert np.allclose(T_camera_world, np.linalg.inv(T_world_camera))
assert np.allclose(T_camera_world, frames.invert_transform(T_world_camera))
assert np.allclose(T_camera_world @ T_world_camera, np.eye(4))

# the camera's position is -R^T t of the extrinsics: NOT their tvec
rvec, tvec = frames.rvec_tvec_from_transform(T_camera_world)
print("tvec (the world origin in the camera frame):", tvec)
print("camera position in the world             :", -cv2.Rodrigues(rvec)[0].T @ tvec)
assert np.allclose(-cv2.Rodrigues(rvec)[0].T @ tvec, [2000, 300, 1200])

# %% [markdown]
# With the extrinsics, `cv2.projectPoints` projects world points; `Camera.project(points_world,
# T_world_camera)` takes the pose and does the inversion for you. The two must agree:

# %%
corners_world = wall.corners()[0]  # marker 0's corners, mm, TL TR BR BL
px_cv, _ = cv2.projectPoints(corners_world.reshape(-1, 1, 3), rvec, tvec, camera.K, camera.dist)
px_cv = px_cv.reshape(-1, 2)
print(px_cv)
assert np.allclose(px_cv, camera.project(corners_world, T_world_camera))

# %% [markdown]
# ## 5. Composing frames
#
# Each marker has its own frame (origin at its centre, x from TL to TR, y up the marker, z out of its
# face): `MarkerMap.T_world_marker(id)`. Where is marker 0 as seen from the camera? Chain the names:
#
# `T_camera_marker = T_camera_world @ T_world_marker`
#
# and back: `T_world_marker = T_world_camera @ T_camera_marker`. This is how a single marker's pose,
# measured by the camera, places the camera in the world (notebook 07).

# %%
T_world_marker = wall.T_world_marker(0)
T_camera_marker = T_camera_world @ T_world_marker
print("marker 0 seen from the camera:\n", T_camera_marker)
distance_mm = np.linalg.norm(T_camera_marker[:3, 3])
print(f"marker 0's centre is {distance_mm:.1f} mm from the camera")

assert np.allclose(T_world_camera @ T_camera_marker, T_world_marker)
assert np.allclose(frames.compose(T_world_camera, T_camera_marker), T_world_marker)
assert math.isclose(distance_mm, np.linalg.norm(T_world_marker[:3, 3] - T_world_camera[:3, 3]))

# the marker's corners in its own frame (centre origin, 80 mm side), carried to the camera frame
s = wall.marker_size_mm
corners_marker = np.array([[-s / 2, s / 2, 0], [s / 2, s / 2, 0], [s / 2, -s / 2, 0], [-s / 2, -s / 2, 0]])
corners_camera = frames.transform_points(T_camera_marker, corners_marker)
assert np.allclose(frames.transform_points(T_world_camera, corners_camera), corners_world)
assert np.all(corners_camera[:, 2] > 0)  # in front of the camera

# %% [markdown]
# The three frames of the chain in one picture: the world at the origin, the camera, and marker 0's own
# frame at its centre (x along its top edge, y up the marker, z, blue, out of its face towards the room).
# The grey line is `T_camera_marker`'s translation: the marker's centre as the camera sees it.

# %%
fig = plotting.plot_scene(wall, poses=[T_world_camera], camera=camera, scale_mm=400,
                          title="T_world_camera @ T_camera_marker = T_world_marker")
ax = fig.axes[0]
plotting.draw_frame(ax, T_world_marker, length_mm=150, label="marker 0")
ax.plot(*np.column_stack([T_world_camera[:3, 3], T_world_marker[:3, 3]]), color="0.5", linestyle="--")
plt.show()

# %% [markdown]
# ## 6. Roll, pitch and yaw
#
# Maps and reports use three angles in degrees: roll about X, pitch about Y, yaw about Z, all about the
# **fixed world axes**, applied roll first: `R = Rz(yaw) @ Ry(pitch) @ Rx(roll)` (ROS REP-103). The
# order matters: the same three angles in another order give another rotation.

# %%
roll, pitch, yaw = 20.0, -30.0, 45.0
R_rpy = frames.rotation_from_rpy_deg(roll, pitch, yaw)
by_hand = frames.rot_z(math.radians(yaw)) @ frames.rot_y(math.radians(pitch)) @ frames.rot_x(math.radians(roll))
other_order = frames.rot_x(math.radians(roll)) @ frames.rot_y(math.radians(pitch)) @ frames.rot_z(math.radians(yaw))
assert np.allclose(R_rpy, by_hand)
print(f"the two orders differ by {frames.rotation_angle_deg(R_rpy, other_order):.1f} deg")
assert frames.rotation_angle_deg(R_rpy, other_order) > 10

back = frames.rpy_deg_from_rotation(R_rpy)
print("roll, pitch, yaw recovered:", back)
assert np.allclose(back, [roll, pitch, yaw])
print("the camera above: roll, pitch, yaw =", frames.rpy_deg_from_rotation(T_world_camera[:3, :3]).round(3) + 0.0)

# %% [markdown]
# ## 7. Z-up (ROS) versus Y-up
#
# fidlearn's world is right-handed with **Z up** (ROS REP-103; the seed room: X out of the north wall
# into the room, Y along the wall). Graphics tools (OpenGL, three.js, the glTF format; Unity too, but
# left-handed) use **Y up**. Take a right-handed Y-up world whose axes are, in fidlearn's world:
# X_yup = Y (along the wall), Y_yup = Z (up), Z_yup = X (out of the wall). The change of basis is a
# rotation whose **rows** are the Y-up axes written in the Z-up world:
#
# $$R_{yup,world} = \begin{pmatrix} 0 & 1 & 0 \\ 0 & 0 & 1 \\ 1 & 0 & 0 \end{pmatrix}, \qquad
# p_{yup} = R_{yup,world}\, p_{world}$$
#
# A pose converts by composition, like any other frame: `T_yup_camera = T_yup_world @ T_world_camera`.
# The camera frame itself does not change: it is still OpenCV's. (An OpenGL *camera* is different
# again: x right, y up, z backwards: `T_camera_glcamera = diag(1, -1, -1, 1)`.)

# %%
R_yup_world = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
assert math.isclose(np.linalg.det(R_yup_world), 1.0)  # a rotation: both worlds are right-handed
T_yup_world = frames.make_transform(R_yup_world)

T_yup_camera = T_yup_world @ T_world_camera
print("camera position, Z-up world:", T_world_camera[:3, 3])
print("camera position, Y-up world:", T_yup_camera[:3, 3])
assert math.isclose(T_world_camera[2, 3], T_yup_camera[1, 3])  # the height: z in one, y in the other

# the camera looks down a little: its optical axis has a negative "up" component in both worlds
print("optical axis, Z-up:", T_world_camera[:3, 2], " Y-up:", T_yup_camera[:3, 2])
assert T_world_camera[2, 2] < 0 and T_yup_camera[1, 2] < 0

# an OpenGL-style camera (y up, z backwards) at the same place
T_camera_glcamera = np.diag([1.0, -1.0, -1.0, 1.0])
T_yup_glcamera = T_yup_camera @ T_camera_glcamera
assert np.allclose(T_yup_glcamera[:3, 3], T_yup_camera[:3, 3])   # same place
assert np.allclose(T_yup_glcamera[:3, 2], -T_yup_camera[:3, 2])  # it looks along its -z

# %% [markdown]
# The same camera and wall, drawn with both worlds' axes: the Y-up world's axes (labelled with a
# prime) sit on top of fidlearn's, each one on the Z-up axis it equals.

# %%
fig = plotting.plot_scene(wall, poses=[T_world_camera], camera=camera, scale_mm=400,
                          title="Z-up world (X, Y, Z) and Y-up world (X', Y', Z')")
ax = fig.axes[0]
T_world_yup = frames.invert_transform(T_yup_world)
plotting.draw_frame(ax, T_world_yup, length_mm=700, linewidth=1, axis_names=("X'", "Y'", "Z'"))
plt.show()

# %% [markdown]
# ## Summary
#
# * `T_a_b` (4x4) is the pose of frame b in frame a: `p_a = T_a_b @ p_b`; products chain their names,
#   `T_world_marker = T_world_camera @ T_camera_marker`.
# * `cv2.Rodrigues` turns an axis-angle `rvec` into R and back; solvePnP's `rvec, tvec` are the
#   **extrinsics** `T_camera_world`, and the camera's pose is their inverse, `[R^T, -R^T t]`.
# * Roll, pitch, yaw are about fixed X, Y, Z, `R = Rz(yaw) Ry(pitch) Rx(roll)`: the order matters.
# * Z-up and Y-up worlds differ by a change-of-basis rotation applied on the left of every pose.
#
# **Exercises**: [exercises/03_extrinsics.ipynb](exercises/03_extrinsics.ipynb), with automatic feedback
# (or `from fidlearn import exercises; ex = exercises.lesson("03")` in a new cell).
#
# Next: [04 Fiducials and the world map](04_fiducials_world_map.ipynb).
