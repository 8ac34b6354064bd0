# %% [markdown]
# # 01 The pinhole camera and its intrinsics K
#
# **What you will learn**
#
# * how a camera turns a 3D point into a pixel: the pinhole model, `u = fx X/Z + cx`;
# * what the four numbers of the intrinsic matrix **K** (fx, fy, cx, cy) mean, in pixels;
# * how the field of view follows from fx and the image width;
# * that OpenCV's `cv2.projectPoints` does exactly this, plus lens distortion;
# * what lens distortion (k1, k2, p1, p2, k3) does to straight lines, and how to undo it.
#
# Run the cells from top to bottom (Shift-Enter).

# %%
# %matplotlib inline
import math

import cv2
import matplotlib.pyplot as plt
import numpy as np

from fidlearn import Camera, MarkerMap, data_path, look_at, plotting, widgets

np.set_printoptions(precision=3, suppress=True)

# %% [markdown]
# ## 1. The pinhole model
#
# Put the camera's centre at the origin of its own frame, OpenCV's **camera frame**: x to the right,
# y **down**, z forward (out of the lens). A point at (X, Y, Z) mm in that frame lands on the image at
#
# $$u = f_x \frac{X}{Z} + c_x, \qquad v = f_y \frac{Y}{Z} + c_y$$
#
# * **fx, fy**: the focal length measured in pixels (focal length in mm divided by the pixel pitch in mm);
#   they are equal when pixels are square.
# * **cx, cy**: the principal point, where the optical axis meets the image, in pixels; near the image centre.
#
# Written as a matrix, the **intrinsic matrix K**:
#
# $$K = \begin{pmatrix} f_x & 0 & c_x \\ 0 & f_y & c_y \\ 0 & 0 & 1 \end{pmatrix}, \qquad
# \begin{pmatrix} u \\ v \\ 1 \end{pmatrix} \propto K \begin{pmatrix} X \\ Y \\ Z \end{pmatrix}$$
#
# Pixel convention (OpenCV's): the **centre** of the top-left pixel is (0, 0), so a 640 x 480 image spans
# u from -0.5 to 639.5 and its centre is (319.5, 239.5).

# %%
fx, fy, cx, cy = 600.0, 600.0, 319.5, 239.5  # pixels
K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1]])

# four points in the camera frame, mm: 2 m in front of the camera
points_camera = np.array([
    [0.0, 0.0, 2000.0],      # on the optical axis
    [500.0, 0.0, 2000.0],    # half a metre to the right
    [0.0, -300.0, 2000.0],   # 30 cm up (y points down)
    [500.0, 250.0, 1000.0],  # closer
])

X, Y, Z = points_camera.T
u = fx * X / Z + cx
v = fy * Y / Z + cy
by_hand = np.column_stack([u, v])
print(by_hand)

# the same with the matrix: K @ p, then divide by the third coordinate
uvw = points_camera @ K.T
by_matrix = uvw[:, :2] / uvw[:, 2:]
assert np.allclose(by_hand, by_matrix)
assert np.allclose(by_hand[0], [cx, cy])  # a point on the optical axis lands on the principal point

# %% [markdown]
# ## 2. The same with OpenCV
#
# `cv2.projectPoints(points, rvec, tvec, K, dist)` does the same, for points given in any frame: `rvec`
# and `tvec` move them into the camera frame first (notebook 03). Here the points are already in the
# camera frame, so both are zero; `dist` holds the lens distortion, zero for now.
#
# fidlearn's `Camera` wraps K, the distortion and the image size; `Camera.project(points_world,
# T_world_camera)` calls `cv2.projectPoints` for a camera at pose `T_world_camera` (here the identity:
# world frame = camera frame).

# %%
rvec = np.zeros(3)
tvec = np.zeros(3)
dist = np.zeros(5)
px_cv, _ = cv2.projectPoints(points_camera.reshape(-1, 1, 3), rvec, tvec, K, dist)
px_cv = px_cv.reshape(-1, 2)

camera = Camera(K, dist, image_size=(640, 480))
px_camera = camera.project(points_camera, np.eye(4))
print(camera)
print(px_cv)

assert np.allclose(px_cv, by_hand)
assert np.allclose(px_camera, by_hand)

# %% [markdown]
# ## 3. Field of view from fx
#
# The image's left and right edges are w/2 pixels from the centre. A ray at angle θ from the optical axis
# lands `fx tan θ` pixels from cx, so the horizontal field of view is
#
# $$\text{hfov} = 2 \arctan\frac{w}{2 f_x}$$
#
# A larger fx (a longer lens, or zooming in) gives a narrower view and bigger markers in the image.

# %%
w, h = camera.image_size
hfov_deg = math.degrees(2 * math.atan(w / (2 * fx)))
vfov_deg = math.degrees(2 * math.atan(h / (2 * fy)))
print(f"fx = {fx:.0f} px on a {w} px wide image: field of view {hfov_deg:.2f} x {vfov_deg:.2f} deg")
assert np.allclose(camera.fov_deg, (hfov_deg, vfov_deg))

# and back: the fx of an ideal camera with a 60 degree horizontal field of view
f60 = (w / 2) / math.tan(math.radians(60) / 2)
ideal = Camera.from_fov(60, (640, 480))
print(f"60 deg on 640 px: fx = {f60:.2f} px;", ideal)
assert math.isclose(ideal.fx, f60) and math.isclose(ideal.fov_deg[0], 60.0)

# %% [markdown]
# What does the camera see of the markers on the wall? `data/world_map.json` places three 80 mm markers
# on the north wall (notebook 04 explains the file). Below, the same camera 1.5 m from the wall with two
# lenses: the projected corners carry the names TL, TR, BR, BL, the order used everywhere in fidlearn.
# `look_at(eye, target)` gives the pose of a camera standing at `eye` and looking at `target` (a 4x4
# matrix, `T_world_camera`); notebook 03 derives it from two cross products.

# %%
wall = MarkerMap.load(data_path("world_map.json"))
T_world_camera = look_at([1500, 150, 250], [0, 150, 250])  # 1.5 m in front of the wall, looking at it

fig, axes = plt.subplots(1, 2, figsize=(11, 4))
for ax, f in zip(axes, (600.0, 1200.0)):
    cam_f = Camera([[f, 0, cx], [0, f, cy], [0, 0, 1]], None, (640, 480))
    corners_px = plotting.draw_projected_markers(ax, wall, cam_f, T_world_camera)
    side_px = np.linalg.norm(corners_px[0][1] - corners_px[0][0])
    ax.set_title(f"fx = {f:.0f} px: hfov {cam_f.fov_deg[0]:.1f} deg, marker 0 is {side_px:.1f} px wide")
    # an 80 mm marker 1500 mm away is fx * 80 / 1500 pixels wide
    assert math.isclose(side_px, f * 80 / 1500, rel_tol=1e-9)
plt.show()

# %% [markdown]
# ## 4. Explore K
#
# Move the sliders (release to redraw). The picture is a flat grid 2 m x 1.5 m, 1.5 m in front of the
# camera; the red cross is the principal point (cx, cy), the grey one the image centre.
#
# * **fx, fy** zoom: the grid grows; fx ≠ fy stretches it (non-square pixels, or a wrong calibration).
# * **cx, cy** slide the whole picture: the grid's centre follows the principal point.
# * **k1** bends straight lines: negative is *barrel* distortion (wide-angle lenses), positive *pincushion*.
#
# The drawing is `widgets.render_intrinsics_view(fx, fy, cx, cy, k1)`, a plain function: the next cell
# calls it directly, so you can see one picture even without the sliders.

# %%
# NBVAL_IGNORE_OUTPUT
widgets.intrinsics_explorer(Camera.from_fov(60, (640, 480)))

# %%
widgets.render_intrinsics_view(fx=554.0, fy=554.0, cx=319.5, cy=239.5, k1=-0.25)

# %% [markdown]
# ## 5. Lens distortion
#
# Real lenses bend rays. OpenCV models it on the *normalized* coordinates x = X/Z, y = Y/Z, before K
# is applied, with r² = x² + y²:
#
# $$x_d = x\,(1 + k_1 r^2 + k_2 r^4 + k_3 r^6) + 2 p_1 x y + p_2 (r^2 + 2x^2)$$
# $$y_d = y\,(1 + k_1 r^2 + k_2 r^4 + k_3 r^6) + p_1 (r^2 + 2y^2) + 2 p_2 x y$$
# $$u = f_x x_d + c_x, \qquad v = f_y y_d + c_y$$
#
# `dist = [k1, k2, p1, p2, k3]` is the order OpenCV reads and writes. Let us check the formula against
# OpenCV with a lens that has some of everything.

# %%
dist = np.array([-0.28, 0.09, 0.001, -0.0005, -0.012])  # k1, k2, p1, p2, k3
k1, k2, p1, p2, k3 = dist

x, y = X / Z, Y / Z
r2 = x**2 + y**2
radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x**2)
yd = y * radial + p1 * (r2 + 2 * y**2) + 2 * p2 * x * y
distorted_by_hand = np.column_stack([fx * xd + cx, fy * yd + cy])

lens = Camera(K, dist, (640, 480))
distorted_cv = lens.project(points_camera, np.eye(4))
print("pinhole   :\n", by_hand)
print("distorted :\n", distorted_cv)
assert np.allclose(distorted_by_hand, distorted_cv, atol=1e-9)

# %% [markdown]
# A point on the optical axis does not move (r = 0), and points move more the further they are from the
# centre. `Camera.undistort_points` inverts the model numerically, giving back the pinhole pixels:

# %%
shift_px = np.linalg.norm(distorted_cv - by_hand, axis=1)
print("distortion moved the points by", shift_px.round(2), "px")
assert shift_px[0] < 1e-9 and shift_px[3] > shift_px[1] > 0

undistorted = lens.undistort_points(distorted_cv)
print("undistorted:\n", undistorted)
assert np.allclose(undistorted, by_hand, rtol=0, atol=0.01)  # undistortion is iterative: within 0.01 px

# %% [markdown]
# Straight lines in the world stay straight in a pinhole image; with distortion they bend. Ignoring the
# distortion of a real lens puts the corners of a marker near the image border several pixels off, and
# the pose (notebook 06) absorbs that error.

# %%
fig, axes = plt.subplots(1, 3, figsize=(13, 3.6), sharey=True)
for ax, (title, k1_demo) in zip(axes, [("pinhole (k1 = 0)", 0.0), ("barrel (k1 = -0.3)", -0.3),
                                       ("pincushion (k1 = +0.3)", 0.3)]):
    for line in widgets.intrinsics_view_polylines(554, 554, 319.5, 239.5, k1=k1_demo):
        ax.plot(line[:, 0], line[:, 1], color="tab:blue", linewidth=0.8)
    ax.set_xlim(-0.5, 639.5)
    ax.set_ylim(479.5, -0.5)
    ax.set_aspect("equal")
    ax.set_title(title)
plt.show()

# %% [markdown]
# ## Summary
#
# * A camera maps a point (X, Y, Z) of its own frame to `u = fx X/Z + cx`, `v = fy Y/Z + cy`: the
#   intrinsic matrix K holds fx, fy, cx, cy, all in **pixels**.
# * The field of view is `2 atan(w / 2fx)`; a marker of side s at distance Z is about `fx s / Z` pixels wide.
# * `cv2.projectPoints` (and `Camera.project`) add lens distortion, on normalized coordinates, with
#   `dist = [k1, k2, p1, p2, k3]`; `Camera.undistort_points` removes it.
# * K and the distortion belong to one camera **at one resolution**: notebook 02 measures them.
#
# **Exercises**: [exercises/01_pinhole.ipynb](exercises/01_pinhole.ipynb), with automatic feedback
# (or `from fidlearn import exercises; ex = exercises.lesson("01")` in a new cell).
#
# Next: [02 Calibration](02_calibration.ipynb).
