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
# * Rodrigues' formula, derived: from an axis and an angle to R and back, checked against `cv2.Rodrigues`;
# * roll, pitch and yaw, why their order matters, gimbal lock (a floor marker sits right on it) and why a
#   level camera reports a roll of -90 deg;
# * quaternions `(x, y, z, w)`, what ROS and every robot use: to and from R, `q` and `-q`, and slerp, the
#   right way to interpolate between two orientations;
# * the ROS Z-up world versus a Y-up world (graphics, games), and the left-handed Unity world converted to
#   ROS and back.
#
# **Before you start**: notebook 01 (the camera frame: x right, y down, z forward); vectors, the matrix
# product and the cross product; sine and cosine. Python with numpy arrays (`A @ B`, `A.T`, slicing).

# %%
# %matplotlib inline
import math

import cv2
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from fidlearn import Camera, MarkerMap, data_path, frames, look_at, plotting

np.set_printoptions(precision=3, suppress=True)

# %% [markdown]
# ## 1. Rotations
#
# A rotation matrix R (3x3) turns vectors. Its **columns** are the rotated frame's x, y, z axes written in
# the original frame; they are unit vectors at right angles (R^T R = I) and det R = +1 (no mirror).
# A rotation by θ about Z:
#
# $$R_z(\theta) = \begin{pmatrix} \cos\theta & -\sin\theta & 0 \\ \sin\theta & \cos\theta & 0 \\
# 0 & 0 & 1 \end{pmatrix}$$

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

# %% [markdown]
# ### `look_at`, derived
#
# `look_at(eye, target)` (used since notebook 01) builds this pose from two points and the world's up
# direction, with two cross products. The columns of `R_world_camera` are the camera's axes in the world:
#
# * **z** (forward) points from the eye to the target: $z = \dfrac{target - eye}{\lVert target - eye \rVert}$;
# * **x** (right in the image) is at right angles to both the view and the world's up:
#   $x = \dfrac{z \times up}{\lVert z \times up \rVert}$ (so the image's rows stay level: the camera is not
#   turned about its optical axis);
# * **y** (down in the image) completes a right-handed frame: $y = z \times x$.
#
# With `up` = world Z, `z × up` points to the camera's right. The translation is the eye itself: the
# camera's position. Looking straight up or down makes `z × up` zero: `look_at` refuses it and asks for
# another `up`.

# %%
eye, target, up = np.array([2000.0, 300, 1200]), np.array([0.0, 200, 300]), np.array([0.0, 0, 1])
z = (target - eye) / np.linalg.norm(target - eye)
x = np.cross(z, up)
x /= np.linalg.norm(x)
y = np.cross(z, x)
T_by_hand = np.eye(4)
T_by_hand[:3, :3] = np.column_stack([x, y, z])
T_by_hand[:3, 3] = eye
print("x (right):", x, " y (down):", y, " z (forward):", z)
assert np.allclose(T_by_hand, T_world_camera)
assert x[2] == 0 and y[2] < 0  # the image's rows are level, and "down in the image" points down in the world

# %% [markdown]
# The camera frame is OpenCV's: x right, y **down**, z forward. In the picture the camera is the
# orange pyramid (apex at the lens centre, base = the image, the thick edge is the image's top), with
# its own axes x red, y green, z blue; the world axes are drawn at the origin, Z up. The legend names
# what is drawn, so nothing is written on top of the small markers.

# %%
wall = MarkerMap.load(data_path("world_map.json"))
camera = Camera.from_fov(60, (640, 480))


def room_picture(title, T_world_cam=T_world_camera, extra_handles=(), extra_points=()):
    """The seed wall, the world axes and one camera in 3D, explained by a legend; returns the Axes."""
    ax = plotting.new_axes_3d(figsize=(8, 6))
    plotting.draw_world_axes(ax, 500, label=None)
    plotting.draw_markers(ax, wall, show_ids=False)
    plotting.draw_camera(ax, camera, T_world_cam, scale_mm=400)
    points = np.vstack(
        [
            np.zeros((1, 3)),
            500 * np.eye(3),
            *wall.corners().values(),
            plotting.camera_frustum(camera, T_world_cam, 400),
            np.reshape(extra_points, (-1, 3)),
        ]
    )
    plotting.set_axes_equal(ax, points)
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(4))  # fewer ticks: no numbers run into each other
    handles = [
        Line2D([], [], color=c, linewidth=2, label=f"{name}: world {w} (long, at the origin), camera {k}")
        for c, name, w, k in zip(
            plotting.AXIS_COLORS, ("red", "green", "blue"), "XYZ", ("x (right)", "y (down)", "z (forward)")
        )
    ]
    handles += [
        Line2D([], [], color="tab:orange", label="camera: apex = lens, thick edge = image top"),
        Line2D([], [], color="0.2", marker="s", linestyle="", label="markers 0, 1, 2 (red dot: TL)"),
        *extra_handles,
    ]
    ax.legend(handles=handles, loc="center left", bbox_to_anchor=(1.08, 0.5), fontsize=8)
    ax.set_title(title)
    return ax


ax = room_picture("the seed wall and a camera at T_world_camera")
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
# ### Rodrigues' formula, derived
#
# Turn a vector $v$ by the angle $\theta$ about the unit axis $k$. Split $v$ into its part along the axis,
# $v_\parallel = k\,(k \cdot v)$, which does not move, and the rest, $v_\perp = v - v_\parallel$, which turns
# in the plane at right angles to $k$. In that plane $k \times v$ is $v_\perp$ turned by 90 deg (and as long),
# so
#
# $$v' = v_\parallel + \cos\theta\, v_\perp + \sin\theta\, (k \times v)$$
#
# Write the cross product as a matrix, $k \times v = K v$ with the **cross-product matrix**
#
# $$K = [k]_\times = \begin{pmatrix} 0 & -k_z & k_y \\ k_z & 0 & -k_x \\ -k_y & k_x & 0 \end{pmatrix}$$
#
# Then $K^2 v = k \times (k \times v) = k\,(k \cdot v) - v = -v_\perp$, so $v_\parallel = v + K^2 v$ and
# $v_\perp = -K^2 v$. Put in:
#
# $$R = I + \sin\theta\, K + (1 - \cos\theta)\, K^2 \qquad \text{(Rodrigues' formula)}$$
#
# **Back from R.** $K$ is antisymmetric and $K^2$ symmetric, so $R - R^T = 2 \sin\theta\, K$: the
# antisymmetric part of R holds $k \sin\theta$. The trace holds the cosine: $\operatorname{tr} K = 0$ and
# $\operatorname{tr} K^2 = -2$, so $\operatorname{tr} R = 1 + 2\cos\theta$. Taking the angle with `atan2`
# from both is accurate at every angle; the axis is then the antisymmetric part divided by $\sin\theta$.
# Near $\theta = 180$ deg $\sin\theta \to 0$ and the axis must come from the symmetric part instead
# (`cv2.Rodrigues` does that); the hand version below stops short of a half turn.


# %%
def cross_matrix(k):
    """[k]x, the matrix with cross_matrix(k) @ v == np.cross(k, v)."""
    return np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])


def rotation_from_rvec(rvec):
    """Rodrigues' formula: R = I + sin(theta) K + (1 - cos(theta)) K^2, theta = |rvec|, K = [rvec/theta]x."""
    theta = np.linalg.norm(rvec)
    if theta == 0:
        return np.eye(3)
    K = cross_matrix(np.asarray(rvec) / theta)
    return np.eye(3) + math.sin(theta) * K + (1 - math.cos(theta)) * K @ K


def rvec_from_rotation(R):
    """Back: sin(theta) k from R - R^T, cos(theta) from the trace (for 0 <= theta < 180 deg)."""
    k_sin = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    theta = math.atan2(np.linalg.norm(k_sin), (np.trace(R) - 1) / 2)
    return np.zeros(3) if theta == 0 else theta * k_sin / np.linalg.norm(k_sin)


assert np.allclose(cross_matrix([1, 2, 3]) @ [4, 5, 6], np.cross([1, 2, 3], [4, 5, 6]))

print("angle (deg) | largest |R - cv2's R|   | largest |rvec - cv2's rvec|")
rvecs = [[0.1, 0.2, 0.3], [0, 0, math.pi / 2], [-1.2, 0.4, 2.0], [2.0, -1.0, 0.5], [0, 3.0, 0], rvec_any]
for rv in np.array(rvecs, dtype=float):
    R_hand = rotation_from_rvec(rv)
    R_cv = cv2.Rodrigues(rv)[0]
    rv_hand = rvec_from_rotation(R_cv)
    rv_cv = cv2.Rodrigues(R_cv)[0].ravel()
    err_R, err_rv = np.abs(R_hand - R_cv).max(), np.abs(rv_hand - rv_cv).max()
    print(f"{math.degrees(np.linalg.norm(rv)):11.2f} | {err_R:.1e} | {err_rv:.1e}")
    assert err_R < 1e-12 and err_rv < 1e-12 and np.allclose(rv_cv, rv)

# the formula is the picture: the part along the axis stays, the rest turns
k, theta, v = np.array([0.0, 0.6, 0.8]), math.radians(50), np.array([1.0, 2.0, 3.0])
v_par = k * (k @ v)
turned = v_par + math.cos(theta) * (v - v_par) + math.sin(theta) * np.cross(k, v)
assert np.allclose(rotation_from_rvec(theta * k) @ v, turned)

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
# frame at its centre (short axes: x along its top edge, y up the marker, z, blue, out of its face towards
# the room). The grey line is `T_camera_marker`'s translation: the marker's centre as the camera sees it.

# %%
dashed = Line2D([], [], color="0.5", linestyle="--", label="T_camera_marker's translation (to marker 0)")
short = Line2D([], [], color="0.3", linewidth=1.5, label="marker 0's frame: x, y, z (z out of its face)")
ax = room_picture("T_world_camera @ T_camera_marker = T_world_marker", extra_handles=[dashed, short])
plotting.draw_frame(ax, T_world_marker, length_mm=300, linewidth=1.5)
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

# %% [markdown]
# ### Gimbal lock: the floor marker
#
# A marker on the floor has pitch -90 (notebook 04): `Ry(-90)` turns the marker's face, +X, up to +Z.
# Turn it on the floor by 30 deg. Written as roll 30 (about X, applied **before** the pitch) or as yaw 30
# (about Z, applied **after**), it is the same marker: the pitch has laid the X axis onto Z, so roll and yaw
# now turn about one and the same line and only their sum counts. One of the three angles is lost: that is
# **gimbal lock**, and the floor marker sits exactly on it. The way back cannot know which was meant;
# `rpy_deg_from_rotation` then reports roll 0 and puts the whole turn into yaw.

# %%
floor_rpy = [30.0, -90.0, 0.0]
R_floor = frames.rotation_from_rpy_deg(*floor_rpy)
floor_back = frames.rpy_deg_from_rotation(R_floor)
print("a floor marker turned by 30 deg: rpy", floor_rpy, "comes back as", floor_back.round(6) + 0.0)
print("its face (the marker's x axis) points", R_floor[:, 0])
assert np.allclose(floor_back, [0, -90, 30]) and np.allclose(R_floor[:, 0], [0, 0, 1])

for r in (30.0, 20.0, 0.0, -60.0):  # any roll + yaw = 30 at pitch -90: one rotation
    R_same = frames.rotation_from_rpy_deg(r, -90, 30 - r)
    print(f"rpy ({r:5.1f}, -90, {30 - r:5.1f}) is {frames.rotation_angle_deg(R_floor, R_same):.1f} deg from it")
    assert frames.rotation_angle_deg(R_floor, R_same) < 1e-6

# near the lock the angles are unstable: a 0.2 deg nudge swings roll and yaw by tens of degrees
R_near = frames.rotation_from_rpy_deg(30, -89.9, 0)
R_nudged = frames.rot_x(math.radians(0.2)) @ R_near
print(
    "rpy (30, -89.9, 0), turned by",
    round(frames.rotation_angle_deg(R_near, R_nudged), 3),
    "deg about X, reads",
    frames.rpy_deg_from_rotation(R_nudged).round(1),
)
assert abs(frames.rpy_deg_from_rotation(R_nudged)[0] - 30) > 45

# %% [markdown]
# So never average, filter or compare roll-pitch-yaw angles of a marker on the floor or of a camera
# looking straight down: use the rotation matrix, a rotation vector or a quaternion (section 7).
#
# ### Why a level camera reports roll -90 deg
#
# A camera standing level, looking straight at the north wall (along -X), reports roll -90, pitch 0,
# yaw 90. It is not tilted: the angles describe `R_world_camera`, and R = I would put the camera's axes on
# the world's. The optical frame's z (forward) would then be the world's Z: a camera with **R = I looks
# at the ceiling**. Roll -90 (about X) tips its view down to the horizon (z onto +Y, y, the image's
# down, onto -Z), and yaw 90 (about Z) turns it round to face the wall. A camera tilted down by a few
# degrees adds them to the -90 of the roll: in the optical frame a tilt shows up as roll, not pitch.

# %%
T_level = look_at([2000, 300, 1200], [0, 300, 1200])  # level, looking at the north wall
R_level = T_level[:3, :3]
print("R_world_camera of the level camera:\n", R_level + 0.0)
print("its roll, pitch, yaw:", frames.rpy_deg_from_rotation(R_level) + 0.0)
assert np.allclose(frames.rpy_deg_from_rotation(R_level), [-90, 0, 90])
rpy_above = frames.rpy_deg_from_rotation(T_world_camera[:3, :3])
tilt_above = math.degrees(math.asin(-T_world_camera[2, 2]))  # how far its optical axis points below level
print(
    f"the camera above looks {tilt_above:.1f} deg down: roll, pitch, yaw =",
    rpy_above.round(1) + 0.0,
    f"(roll -90 - {tilt_above:.1f})",
)
assert math.isclose(rpy_above[0], -90 - tilt_above) and abs(rpy_above[1]) < 1e-9

steps = [np.eye(3), frames.rot_x(math.radians(-90)), frames.rot_z(math.radians(90)) @ frames.rot_x(math.radians(-90))]
assert np.allclose(steps[2], R_level)
assert np.allclose(look_at([0, 0, 0], [0, 0, 1], up=(0, -1, 0))[:3, :3], steps[0])  # R = I: looking up

fig, axes = plt.subplots(1, 3, figsize=(14, 4.8), subplot_kw={"projection": "3d"})
titles = [
    "R = I: the camera looks at the ceiling",
    "after roll -90 (about X): level, facing +Y",
    "after yaw 90 (about Z): facing the wall (-X)",
]
image = np.array([[-0.28, -0.21, 0.5], [0.28, -0.21, 0.5], [0.28, 0.21, 0.5], [-0.28, 0.21, 0.5]])  # y < 0: top
for ax, R, title in zip(axes, steps, titles):
    for k in range(3):
        e = np.eye(3)[k]
        ax.plot(*np.column_stack([np.zeros(3), 1.6 * e]), color=plotting.AXIS_COLORS[k], linestyle=":", linewidth=1.5)
        ax.text(*(1.75 * e), "XYZ"[k], color=plotting.AXIS_COLORS[k], fontsize=11)
        ax.plot(*np.column_stack([np.zeros(3), R[:, k]]), color=plotting.AXIS_COLORS[k], linewidth=3)
        ax.text(*(1.12 * R[:, k]), "xyz"[k], color=plotting.AXIS_COLORS[k], fontsize=11, fontweight="bold")
    corners = image @ R.T
    ax.plot(*corners[[0, 1, 2, 3, 0]].T, color="tab:orange", linewidth=1)
    ax.plot(*corners[[0, 1]].T, color="tab:orange", linewidth=3)
    for c in corners:
        ax.plot(*np.column_stack([np.zeros(3), c]), color="tab:orange", linewidth=0.6)
    ax.set(xlim=(-1.2, 1.8), ylim=(-1.2, 1.8), zlim=(-1.2, 1.8), xticks=[], yticks=[], zticks=[])
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=18, azim=-62)
    ax.set_title(title, fontsize=10)
handles = [
    Line2D([], [], color="0.3", linestyle=":", label="world X, Y, Z (Z up)"),
    Line2D([], [], color="0.3", linewidth=3, label="camera x right, y down, z forward"),
    Line2D([], [], color="tab:orange", linewidth=3, label="the image (thick: its top edge)"),
]
fig.legend(handles=handles, loc="lower center", ncol=3)
fig.suptitle("roll -90, pitch 0, yaw 90: the level camera built from R = I (colours: x/X red, y/Y green, z/Z blue)")
plt.show()

# %% [markdown]
# ROS keeps two frames per camera for this reason (REP-103, "suffix frames"): the **optical** frame
# (`camera_optical`, OpenCV's x right, y down, z forward) and the **body** frame (often `camera_link`: x forward,
# y left, z up, like a robot). Between them is a fixed rotation: written in the body frame, the optical axes
# are x_opt = -y_body (right is minus left), y_opt = -z_body (down is minus up) and z_opt = x_body (forward).
# A level camera's **body** reports roll 0 and pitch 0: the angles a person expects.

# %%
R_body_optical = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # columns: optical x, y, z
R_world_body = R_level @ R_body_optical.T
print("the level camera's body frame: roll, pitch, yaw =", frames.rpy_deg_from_rotation(R_world_body) + 0.0)
assert np.allclose(frames.rpy_deg_from_rotation(R_world_body), [0, 0, 180])
print("and the optical-in-body rotation itself is rpy", frames.rpy_deg_from_rotation(R_body_optical) + 0.0)

# %% [markdown]
# ## 7. Quaternions
#
# ROS messages (`geometry_msgs/Quaternion`), tf2, Unity and most robot software store an orientation as a
# unit **quaternion**: a rotation by θ about the unit axis k is four numbers
#
# $$q = (x, y, z, w) = \left(k \sin\tfrac{\theta}{2},\ \cos\tfrac{\theta}{2}\right), \qquad \lVert q \rVert = 1$$
#
# ROS, Unity and scipy's `as_quat` put the vector part first and w last; Eigen's constructor and many papers
# write (w, x, y, z): always check the order. Four numbers with one constraint, no gimbal lock, one
# product to chain two rotations, and a clean way to interpolate. The matrix, written out:
#
# $$R(q) = \begin{pmatrix} 1 - 2(y^2 + z^2) & 2(xy - wz) & 2(xz + wy) \\ 2(xy + wz) & 1 - 2(x^2 + z^2) &
# 2(yz - wx) \\ 2(xz - wy) & 2(yz + wx) & 1 - 2(x^2 + y^2) \end{pmatrix}$$
#
# and back: $\operatorname{tr} R = 4w^2 - 1$, and the differences
# $(R_{21} - R_{12},\ R_{02} - R_{20},\ R_{10} - R_{01})$ (where Rodrigues' formula read $2 k \sin\theta$ from)
# are $4w\,(x, y, z)$. So $w = \tfrac12\sqrt{1 + \operatorname{tr} R}$ and
# $(x, y, z) = (R_{21} - R_{12},\ R_{02} - R_{20},\ R_{10} - R_{01}) / 4w$. That divides by w: fine until
# near a half turn, where w goes to 0. `fidlearn.frames.quaternion_from_matrix` then starts from the
# largest of x, y, z, w instead (Shepperd's method) and returns the form with w >= 0.


# %%
def quaternion_from_rvec(rvec):
    """(x, y, z, w) = (k sin(theta/2), cos(theta/2)) for the rotation vector theta * k."""
    theta = np.linalg.norm(rvec)
    k = np.asarray(rvec, dtype=float) / theta if theta else np.zeros(3)
    return np.append(k * math.sin(theta / 2), math.cos(theta / 2))


def rotation_from_quaternion(q):
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def quaternion_from_rotation(R):
    """The trace way: w from the trace, (x, y, z) from the antisymmetric part (w must not be near 0)."""
    w = 0.5 * math.sqrt(1 + np.trace(R))
    return np.append(np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / (4 * w), w)


q_z90 = quaternion_from_rvec([0, 0, math.pi / 2])
print("90 deg about Z: q =", q_z90, "= (0, 0, sin 45, cos 45)")
assert np.allclose(q_z90, [0, 0, math.sqrt(0.5), math.sqrt(0.5)])
assert np.allclose(rotation_from_quaternion(q_z90), Rz)

for rv in np.array(rvecs, dtype=float):
    q = quaternion_from_rvec(rv)
    R_cv = cv2.Rodrigues(rv)[0]
    assert np.abs(rotation_from_quaternion(q) - R_cv).max() < 1e-12  # q -> R, against OpenCV
    assert np.abs(quaternion_from_rotation(R_cv) - q).max() < 1e-12  # R -> q, by the trace
    assert np.abs(frames.quaternion_from_matrix(R_cv) - q).max() < 1e-12  # fidlearn's helpers agree
    assert np.abs(frames.matrix_from_quaternion(q) - R_cv).max() < 1e-12
print(f"{len(rvecs)} rotations: quaternion <-> R by hand, OpenCV and fidlearn.frames agree to 1e-12")

# %% [markdown]
# ### q and -q: the double cover
#
# Negate all four numbers and every product in R(q) keeps its sign: **q and -q are the same rotation**.
# (They are θ about k and 360 - θ about -k.) So two quaternions can differ and still mean one orientation:
# compare rotations, or first bring both to w >= 0 (fidlearn's canonical form). The angle between two
# orientations is $2 \arccos \lvert q_0 \cdot q_1 \rvert$, with the absolute value for the same reason.

# %%
q_any = quaternion_from_rvec(rvec_any)
print("q  =", q_any, "\n-q =", -q_any)
assert np.allclose(rotation_from_quaternion(-q_any), rotation_from_quaternion(q_any))

q_350 = quaternion_from_rvec([0, 0, math.radians(350)])  # 350 deg about Z ...
q_canonical = frames.quaternion_from_matrix(rotation_from_quaternion(q_350))
print("350 deg about Z:", q_350, "-> canonical", q_canonical, "= -10 deg about Z")
assert np.allclose(q_canonical, -q_350) and np.allclose(q_canonical, quaternion_from_rvec([0, 0, math.radians(-10)]))

q_a, q_b = frames.quaternion_from_matrix(R_any), frames.quaternion_from_matrix(R_rpy)
angle_q = math.degrees(2 * math.acos(min(1.0, abs(q_a @ q_b))))
print(
    f"angle between two orientations: {angle_q:.3f} deg from the quaternions, "
    f"{frames.rotation_angle_deg(R_any, R_rpy):.3f} deg from the matrices"
)
assert math.isclose(angle_q, frames.rotation_angle_deg(R_any, R_rpy), abs_tol=1e-6)

# %% [markdown]
# ### Interpolation: slerp
#
# A robot's orientation between two keyframes, a camera path for a video, the mean of two estimates: all
# need "the rotation a fraction t of the way from R0 to R1". The right answer turns about **one fixed
# axis at constant speed** (the shortest way, a great-circle arc on the sphere of unit quaternions).
# Slerp (spherical linear interpolation, Shoemake 1985) writes it out: with $\cos\Omega = q_0 \cdot q_1$
# (after flipping q1 if the dot product is negative: the double cover, the shorter way round),
#
# $$\operatorname{slerp}(q_0, q_1, t) = \frac{\sin((1 - t)\Omega)}{\sin\Omega}\, q_0
# + \frac{\sin(t\Omega)}{\sin\Omega}\, q_1$$
#
# Two shortcuts people take instead: **nlerp**, a straight line between q0 and q1 pushed back to unit
# length (the right path, the wrong speed: it hurries through the middle), and **averaging rotation
# vectors**, $(1 - t)\, r_0 + t\, r_1$ (the wrong path: the axis wanders, unless one end is R = I).


# %%
def slerp(q0, q1, t):
    if q0 @ q1 < 0:
        q1 = -q1  # the same rotation, the shorter way round
    omega = math.acos(min(1.0, q0 @ q1))
    if omega < 1e-9:
        return q0
    return (math.sin((1 - t) * omega) * q0 + math.sin(t * omega) * q1) / math.sin(omega)


def nlerp(q0, q1, t):
    q = (1 - t) * q0 + t * (q1 if q0 @ q1 >= 0 else -q1)
    return q / np.linalg.norm(q)


R0, R1 = frames.rotation_from_rpy_deg(10, -20, 30), frames.rotation_from_rpy_deg(-40, 50, 160)
q0, q1 = frames.quaternion_from_matrix(R0), frames.quaternion_from_matrix(R1)
r0, r1 = cv2.Rodrigues(R0)[0].ravel(), cv2.Rodrigues(R1)[0].ravel()
r_step = cv2.Rodrigues(R0.T @ R1)[0].ravel()  # the one fixed axis (in R0's frame) times the whole angle
ts = np.linspace(0, 1, 101)
paths = {
    "slerp": [rotation_from_quaternion(slerp(q0, q1, t)) for t in ts],
    "nlerp (normalised straight line)": [rotation_from_quaternion(nlerp(q0, q1, t)) for t in ts],
    "average of rotation vectors": [cv2.Rodrigues((1 - t) * r0 + t * r1)[0] for t in ts],
}
axis = r_step / np.linalg.norm(r_step)
total = frames.rotation_angle_deg(R0, R1)
print(f"R0 to R1: {total:.1f} deg about one axis")


def off_arc_deg(R):
    """How far R is from the arc R0 @ Rot(axis, s): the closest Rot(axis, s) has |q . q_s| = |(v . axis, w)|."""
    v_w = frames.quaternion_from_matrix(R0.T @ R)
    return math.degrees(2 * math.acos(min(1.0, math.hypot(v_w[:3] @ axis, v_w[3]))))


travelled, off_path, lag = {}, {}, {}
for name, Rs in paths.items():
    assert frames.rotation_angle_deg(Rs[0], R0) < 1e-5 and frames.rotation_angle_deg(Rs[-1], R1) < 1e-5
    travelled[name] = np.array([frames.rotation_angle_deg(R0, R) for R in Rs])
    off_path[name] = max(off_arc_deg(R) for R in Rs)
    lag[name] = np.abs(travelled[name] - ts * total).max()
    print(
        f"{name:32s}: off the arc by up to {off_path[name]:5.2f} deg, "
        f"ahead of or behind constant speed by up to {lag[name]:5.2f} deg"
    )
assert off_path["slerp"] < 1e-4 and lag["slerp"] < 1e-4
assert off_path["nlerp (normalised straight line)"] < 1e-4 and lag["nlerp (normalised straight line)"] > 1
assert off_path["average of rotation vectors"] > 1

# %% [markdown]
# In pictures: where the rotated frame's x axis points along the way (left, on the unit sphere), and how
# far each method has turned at each t (right). Slerp's line is straight: constant speed.

# %%
fig = plt.figure(figsize=(12, 5))
ax3 = fig.add_subplot(1, 2, 1, projection="3d")
u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 25), np.linspace(0, np.pi, 13))
ax3.plot_wireframe(np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v), color="0.85", linewidth=0.5)
styles = {
    "slerp": ("tab:blue", "-", 3),
    "nlerp (normalised straight line)": ("tab:orange", "--", 2),
    "average of rotation vectors": ("tab:red", "-", 1.5),
}
for name, Rs in paths.items():
    colour, line, width = styles[name]
    tips = np.array([R[:, 0] for R in Rs])
    ax3.plot(*tips.T, color=colour, linestyle=line, linewidth=width, label=name)
    ax3.scatter(*tips[::25].T, color=colour, s=18, depthshade=False)  # t = 0, 0.25, 0.5, 0.75, 1
ax3.text(*(1.2 * R0[:, 0]), "t = 0 (R0)", fontsize=10)
ax3.text(*(1.2 * R1[:, 0]), "t = 1 (R1)", fontsize=10)
ax3.set_box_aspect((1, 1, 1))
ax3.set(xticks=[], yticks=[], zticks=[], title="the rotated x axis (dots: t = 0, 0.25, ..., 1)")
ax3.legend(loc="lower left", fontsize=8)
ax2 = fig.add_subplot(1, 2, 2)
for name in paths:
    colour, line, width = styles[name]
    ax2.plot(ts, travelled[name], color=colour, linestyle=line, linewidth=width, label=name)
ax2.set(xlabel="t", ylabel="angle turned from R0 (deg)", title="how far each has turned")
ax2.grid(alpha=0.3)
ax2.legend(fontsize=8)
plt.show()

# %% [markdown]
# ## 8. Z-up (ROS) versus Y-up
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
assert np.allclose(T_yup_glcamera[:3, 3], T_yup_camera[:3, 3])  # same place
assert np.allclose(T_yup_glcamera[:3, 2], -T_yup_camera[:3, 2])  # it looks along its -z

# %% [markdown]
# The same camera and wall, drawn with both worlds' axes: the Y-up world's axes (thin, longer, names with
# a prime) lie along fidlearn's, each one on the Z-up axis it equals: X' on Y, Y' on Z, Z' on X.

# %%
T_world_yup = frames.invert_transform(T_yup_world)
prime = Line2D([], [], color="0.3", linewidth=1, label="X', Y', Z': the Y-up world (thin, longer)")
ax = room_picture(
    "Z-up world (X, Y, Z) and Y-up world (X', Y', Z')", extra_handles=[prime], extra_points=1000 * np.eye(3)
)
plotting.draw_frame(ax, T_world_yup, length_mm=900, linewidth=1, axis_names=("X'", "Y'", "Z'"))
plt.show()

# %% [markdown]
# ### Unity (left-handed, Y up) to ROS (right-handed, Z up), and back
#
# Unity's world: x right, **y up**, z forward, in metres, and **left-handed** (x × y = -z). ROS's (and
# fidlearn's) world: x forward, y left, z up, right-handed; fidlearn counts millimetres. Naming the same
# directions: forward is z in Unity and x in ROS, left is -x in Unity and y in ROS, up is y in Unity and z
# in ROS:
#
# $$p_{ros} = M\, p_{unity}, \qquad M = \begin{pmatrix} 0 & 0 & 1 \\ -1 & 0 & 0 \\ 0 & 1 & 0 \end{pmatrix},
# \qquad \det M = -1$$
#
# M is a **mirror**, not a rotation: no rotation turns a left-handed frame into a right-handed one. A
# rotation matrix converts on both sides, $R_{ros} = M R_{unity} M^T$ (a proper rotation again). For the
# quaternion, a mirror turns an axis k into $-Mk$ and keeps the angle ($M [k]_\times M^T = -[Mk]_\times$
# when det M = -1), so $(x, y, z)_{ros} = -M\,(x, y, z)_{unity}$ and w stays:
#
# $$q_{ros} = (-z_u,\ x_u,\ -y_u,\ w_u), \qquad q_{unity} = (y_r,\ -z_r,\ -x_r,\ w_r)$$
#
# A concrete pose: a Unity object at (1.0, 1.5, -2.0) m, turned by `Quaternion.Euler(30, 90, 0)`: Unity
# applies z, then x, then y, so that is 30 deg about x (in Unity, nose down) and then 90 deg about y (a turn
# to the right, seen from above). Its forward vector should point right and down.


# %%
def quaternion_product(a, b):
    """The product a * b of (x, y, z, w) quaternions: the rotation b first, then a."""
    va, wa, vb, wb = a[:3], a[3], b[:3], b[3]
    return np.append(wa * vb + wb * va + np.cross(va, vb), wa * wb - va @ vb)


M = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
print("det M =", round(np.linalg.det(M), 12), ": a mirror")

p_unity = np.array([1.0, 1.5, -2.0])  # m
q_turn, q_nose_down = quaternion_from_rvec([0, math.radians(90), 0]), quaternion_from_rvec([math.radians(30), 0, 0])
q_unity = quaternion_product(q_turn, q_nose_down)  # Quaternion.Euler(30, 90, 0): about x first, then about y
R_unity = frames.matrix_from_quaternion(q_unity)
forward_unity = R_unity @ [0, 0, 1]  # Unity's transform.forward
print("Unity: position", p_unity, "m, rotation (x, y, z, w)", q_unity.round(5), ", forward", forward_unity)
assert np.allclose(forward_unity, [math.cos(math.radians(30)), -0.5, 0])  # right (+x) and down (-y)

# Unity -> ROS / fidlearn (mm)
p_ros_mm = 1000 * M @ p_unity
q_ros = np.array([-q_unity[2], q_unity[0], -q_unity[1], q_unity[3]])
R_ros = frames.matrix_from_quaternion(q_ros)
print("ROS:   position", p_ros_mm, "mm, rotation (x, y, z, w)", q_ros.round(5))
print(
    "       roll, pitch, yaw =",
    frames.rpy_deg_from_rotation(R_ros).round(6) + 0.0,
    "(pitch +30: nose down in ROS; yaw -90: turned right)",
)
assert np.allclose(R_ros, M @ R_unity @ M.T) and math.isclose(np.linalg.det(R_ros), 1.0)
assert np.allclose(R_ros @ [1, 0, 0], M @ forward_unity)  # ROS's forward (x) is Unity's forward (z)
assert np.allclose(frames.rpy_deg_from_rotation(R_ros), [0, 30, -90])

# ROS -> Unity, and the round trip
p_back = M.T @ p_ros_mm / 1000
q_back = np.array([q_ros[1], -q_ros[2], -q_ros[0], q_ros[3]])
print("back:  position", p_back, "m, rotation (x, y, z, w)", q_back.round(5))
assert np.allclose(p_back, p_unity, atol=1e-12) and np.allclose(q_back, q_unity, atol=1e-12)
assert np.allclose(M.T @ R_ros @ M, R_unity)

# %% [markdown]
# A Unity **camera** needs one more step for fidlearn's `T_world_camera`: it looks along its own +z with y
# **up** in the image, OpenCV's y points down. Flip the camera's y, `F = diag(1, -1, 1)` (a second mirror,
# so the product is a rotation): $R_{world,camera} = M\, R_{unity}\, F$. The result is the camera that
# `look_at` builds at the same place looking the same way.

# %%
F = np.diag([1.0, -1.0, 1.0])
T_from_unity = frames.make_transform(M @ R_unity @ F, p_ros_mm)
T_looking = look_at(p_ros_mm, p_ros_mm + 1000 * M @ forward_unity)
print("T_world_camera from Unity's camera:\n", T_from_unity.round(12) + 0.0)
assert np.allclose(T_from_unity, T_looking)

# %% [markdown]
# ## Try it
#
# A camera 2 m from the north wall, 1.2 m up, looking down by `tilt_deg` and turned left by `pan_deg`.
# Change the numbers, **predict** what the next cell prints, then run it. Which of the optical frame's
# angles move when you tilt? What does the body frame (x forward, y left, z up) report? Try a tilt of 89.9
# (nearly straight down): which numbers jump, and why does 90 fail (`look_at`'s `up`)? Is the quaternion
# still smooth there?

# %%
tilt_deg = 20.0  # down from level (try 0, 45, -30, 89.9)
pan_deg = 30.0  # to the left of facing the wall (try 0, 90, 180)

t_rad, p_rad = math.radians(tilt_deg), math.radians(pan_deg)
view = [-math.cos(t_rad) * math.cos(p_rad), -math.cos(t_rad) * math.sin(p_rad), -math.sin(t_rad)]
T_try = look_at([2000, 300, 1200], np.array([2000, 300, 1200]) + 1000 * np.array(view))
R_try_body = T_try[:3, :3] @ R_body_optical.T
print("optical frame: roll, pitch, yaw =", frames.rpy_deg_from_rotation(T_try[:3, :3]).round(2) + 0.0)
print("body frame   : roll, pitch, yaw =", frames.rpy_deg_from_rotation(R_try_body).round(2) + 0.0)
print("body frame   : quaternion (x, y, z, w) =", frames.quaternion_from_matrix(R_try_body).round(4) + 0.0)

# %% [markdown]
# ## Summary
#
# * `T_a_b` (4x4) is the pose of frame b in frame a: `p_a = T_a_b @ p_b`; products chain their names,
#   `T_world_marker = T_world_camera @ T_camera_marker`. `look_at` builds a pose from two cross products.
# * Rodrigues' formula $R = I + \sin\theta\, K + (1 - \cos\theta) K^2$ turns an axis-angle `rvec` into R;
#   the trace and the antisymmetric part of R give it back. `cv2.Rodrigues` does both. solvePnP's
#   `rvec, tvec` are the **extrinsics** `T_camera_world`; the camera's pose is their inverse, `[R^T, -R^T t]`.
# * Roll, pitch, yaw are about fixed X, Y, Z, `R = Rz(yaw) Ry(pitch) Rx(roll)`: the order matters, and at
#   pitch ±90 (a floor marker) roll and yaw merge: gimbal lock. A level camera's optical frame reports
#   roll -90 because R = I looks at the ceiling; its ROS body frame reports 0.
# * Quaternions (x, y, z, w) = (k sin θ/2, cos θ/2); q and -q are one rotation; interpolate with slerp.
# * Z-up and Y-up worlds differ by a change-of-basis rotation applied on the left of every pose; Unity's
#   left-handed world differs from ROS's by a mirror M, applied on both sides: `M R M^T`.
#
# **Exercises**: [exercises/03_extrinsics.ipynb](exercises/03_extrinsics.ipynb), with automatic feedback
# (or `from fidlearn import exercises; ex = exercises.lesson("03")` in a new cell).
#
# ## References
#
# * K. M. Lynch and F. C. Park, *Modern Robotics: Mechanics, Planning, and Control*, Cambridge University
#   Press, 2017, **chapter 3, Rigid-Body Motions** (rotation matrices, exponential coordinates and
#   Rodrigues' formula, homogeneous transforms); the book and videos are free at
#   <https://hades.mech.northwestern.edu/index.php/Modern_Robotics>.
# * OpenCV, *Camera Calibration and 3D Reconstruction* (calib3d): `cv2.Rodrigues`, `cv2.solvePnP`,
#   `cv2.projectPoints` and their `rvec, tvec`: <https://docs.opencv.org/4.x/d9/d0c/group__calib3d.html>.
# * ROS REP-103, *Standard Units of Measure and Coordinate Conventions* (Z up, x forward y left z up,
#   roll-pitch-yaw about fixed axes, the `_optical` frames): <https://www.ros.org/reps/rep-0103.html>.
# * K. Shoemake, "Animating rotation with quaternion curves", SIGGRAPH 1985 (slerp).
# * Unity, `Quaternion.Euler` (z, then x, then y): <https://docs.unity3d.com/ScriptReference/Quaternion.Euler.html>.
# * fidlearn's conventions: `docs/conventions.md`.
#
# Next: [04 Fiducials and the world map](04_fiducials_world_map.ipynb).
