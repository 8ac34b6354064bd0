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
from fidlearn.synthetic import render_calibration_views

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
points_camera = np.array(
    [
        [0.0, 0.0, 2000.0],  # on the optical axis
        [500.0, 0.0, 2000.0],  # half a metre to the right
        [0.0, -300.0, 2000.0],  # 30 cm up (y points down)
        [500.0, 250.0, 1000.0],  # closer
    ]
)

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
# The same numbers as a drawing. Seen from above (left), a ray from each point to the camera's centre crosses
# an **image plane** put at distance fx in front of it (in pixel units; a real sensor sits behind the lens, and
# this "virtual" plane in front gives the same picture without turning it upside down). Where the ray crosses
# the plane is `u - cx = fx X / Z`: similar triangles. Seen from the side (right), the same with fy and v.
# The plane's width is the image's, 640 px, so the two outer rays show the field of view (section 3).

# %%
fig, (top, side) = plt.subplots(1, 2, figsize=(13, 4.8))
colours = ["tab:blue", "tab:orange", "tab:green", "tab:red"]
for ax, axis, f, c, half, name in ((top, 0, fx, cx, 320, "X"), (side, 1, fy, cy, 240, "Y")):
    ax.plot([0, 0], [0, 0], "k^", markersize=10)
    ax.plot([-half, half], [f, f], color="0.3", linewidth=3)  # the image plane, at depth f
    ax.plot([0, -half * 2200 / f], [0, 2200], ":", color="0.5")  # the field of view's edges
    ax.plot([0, half * 2200 / f], [0, 2200], ":", color="0.5")
    ax.text(half, f, f"  image plane at\n  depth f = {f:.0f}", va="center", fontsize=8)
    for k, (p, uv) in enumerate(zip(points_camera, by_hand)):
        if p[axis] == 0 and k > 0:
            continue  # nothing to see in this view
        crossing = f * p[axis] / p[2]  # similar triangles
        assert np.isclose(crossing, uv[axis] - c)  # = u - cx (or v - cy), px
        ax.plot([0, p[axis]], [0, p[2]], color=colours[k], linewidth=1)
        ax.plot(
            p[axis],
            p[2],
            "o",
            color=colours[k],
            label=f"point {k}: {name} = {p[axis]:.0f}, Z = {p[2]:.0f} mm: crosses at {crossing:+.0f} px",
        )
        ax.plot(crossing, f, "s", color=colours[k], markersize=6)
    ax.set_xlabel(f"{name} (mm; pixels on the image plane)" + (", pointing down" if axis == 1 else ""))
    ax.set_ylabel("Z, forward (mm)")
    ax.set_xlim(-900, 900)
    ax.set_ylim(-100, 2250)
    ax.legend(loc="lower left", fontsize=8)
top.set_title("from above: u - cx = fx X / Z")
side.set_title("from the side: v - cy = fy Y / Z")
fig.tight_layout()
plt.show()

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

fig, axes = plt.subplots(1, 2, figsize=(12, 4.4))
for ax, f in zip(axes, (600.0, 1200.0)):
    cam_f = Camera([[f, 0, cx], [0, f, cy], [0, 0, 1]], None, (640, 480))
    # corner names only where the markers are big enough for them not to overlap
    corners_px = plotting.draw_projected_markers(ax, wall, cam_f, T_world_camera, corner_labels=f > 1000)
    side_px = np.linalg.norm(corners_px[0][1] - corners_px[0][0])
    ax.set_title(f"fx = {f:.0f} px: hfov {cam_f.fov_deg[0]:.1f} deg\nmarker 0 is {side_px:.1f} px wide", fontsize=10)
    print(f"fx = {f:.0f} px: hfov {cam_f.fov_deg[0]:.1f} deg, marker 0 is {side_px:.1f} px wide")
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
# centre. `Camera.undistort_points` inverts the model numerically (Newton steps, exact to about 1e-9 px; `exact=False`
# is OpenCV's faster `cv2.undistortPoints`, which stops early), giving back the pinhole pixels:

# %%
shift_px = np.linalg.norm(distorted_cv - by_hand, axis=1)
print("distortion moved the points by", shift_px.round(2), "px")
assert shift_px[0] < 1e-9 and shift_px[3] > shift_px[1] > 0

undistorted = lens.undistort_points(distorted_cv)
print("undistorted:\n", undistorted)
assert np.allclose(undistorted, by_hand, rtol=0, atol=1e-6)  # Newton steps to machine precision

# %% [markdown]
# Straight lines in the world stay straight in a pinhole image; with distortion they bend:

# %%
fig, axes = plt.subplots(1, 3, figsize=(13, 3.6), sharey=True)
for ax, (title, k1_demo) in zip(
    axes, [("pinhole (k1 = 0)", 0.0), ("barrel (k1 = -0.3)", -0.3), ("pincushion (k1 = +0.3)", 0.3)]
):
    for line in widgets.intrinsics_view_polylines(554, 554, 319.5, 239.5, k1=k1_demo):
        ax.plot(line[:, 0], line[:, 1], color="tab:blue", linewidth=0.8)
    ax.set_xlim(-0.5, 639.5)
    ax.set_ylim(479.5, -0.5)
    ax.set_aspect("equal")
    ax.set_title(title)
plt.show()

# %% [markdown]
# ### What ignoring the distortion costs
#
# Suppose the lens distorts but the code passes `dist = 0` to `cv2.solvePnP` (notebook 06). The corners are
# then off by the distortion, and the solver finds the pose that fits those wrong corners best: it **absorbs**
# the error into a wrong pose, with a small reprojection error that does not warn you. Measure it with exact
# projections (no detection noise) of the wall's markers, seen 0.9 m away near the edge of the picture, for
# the strong lens above and for a mild one (a typical webcam), with the distortion modelled and ignored:

# %%
wall_points = np.vstack(list(wall.corners().values()))  # the 12 corners of the wall's markers, mm
T_near_edge = look_at([900, -100, 400], [0, 350, 250])  # the markers land in the left half of the picture
print("lens                   corners moved by   distortion   position error  reprojection RMS")
ignored_error_mm = {}
for lens_name, lens_dist in (("strong (k1 = -0.28)", dist), ("mild (k1 = -0.06)", np.array([-0.06, 0.08, 0, 0, 0]))):
    seen_px = Camera(K, lens_dist, (640, 480)).project(wall_points, T_near_edge)  # what the camera sees
    pinhole_px = Camera(K, None, (640, 480)).project(wall_points, T_near_edge)
    moved = np.linalg.norm(seen_px - pinhole_px, axis=1)
    for how, model_dist in (("modelled", lens_dist), ("ignored", np.zeros(5))):
        ok, r, t = cv2.solvePnP(wall_points, seen_px, K, model_dist, flags=cv2.SOLVEPNP_IPPE)
        r, t = cv2.solvePnPRefineLM(wall_points, seen_px, K, model_dist, r, t)
        projected, _ = cv2.projectPoints(wall_points, r, t, K, model_dist)
        rms = np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - seen_px) ** 2, axis=1)))
        R, _ = cv2.Rodrigues(r)
        position = (-R.T @ t).ravel()  # the camera's position in the world (notebook 07)
        err = np.linalg.norm(position - T_near_edge[:3, 3])
        if how == "ignored":
            ignored_error_mm[lens_name] = err
        print(f"{lens_name:22s} {moved.min():6.1f} to {moved.max():4.1f} px   {how:9s} {err:10.1f} mm {rms:15.2f} px")
        if how == "modelled":
            assert err < 0.5 and rms < 0.01
assert ignored_error_mm["strong (k1 = -0.28)"] > 10 and ignored_error_mm["mild (k1 = -0.06)"] > 2

# %% [markdown]
# With the distortion modelled the pose is exact. Ignored, the camera lands centimetres off with the strong
# lens and millimetres off with the mild one, while the reprojection error stays around a pixel or less: small
# enough to look like ordinary detection noise. Calibrate the distortion (notebook 02) and pass it on.
#
# ### Removing the distortion from a picture: `cv2.undistort`
#
# `cv2.undistort(image, K, dist)` resamples a whole picture as the pinhole camera would have taken it. Here a
# rendered picture of a checkerboard through the strong lens above (`fidlearn.synthetic` knows the true corner
# pixels), and the same picture undistorted. The rows of corners bend in the first and are straight in the
# second; measured on the true corners (`cv2.undistortPoints` moves points the way `cv2.undistort` moves
# pixels), the largest distance of a corner from its row's straight line:

# %%
board_view = render_calibration_views(lens, n_views=1, seed=3, fill_range=(0.85, 0.9), tilt_range_deg=(5, 10))
distorted_image = board_view.images[0]
undistorted_image = cv2.undistort(distorted_image, K, dist)


def row_bend_px(points, pattern=(9, 6)):
    """Largest distance (px) of a corner from the straight line fitted to its row of the board."""
    worst = 0.0
    for row in points.reshape(pattern[1], pattern[0], 2):
        centre = row - row.mean(axis=0)
        normal = np.linalg.svd(centre)[2][1]  # the direction across the row
        worst = max(worst, float(np.abs(centre @ normal).max()))
    return worst


corners_distorted = board_view.image_points[0]
corners_straight = cv2.undistortPoints(corners_distorted.reshape(-1, 1, 2), K, dist, P=K).reshape(-1, 2)
print(
    f"rows of corners bend by up to {row_bend_px(corners_distorted):.2f} px in the picture, "
    f"{row_bend_px(corners_straight):.3f} px after undistortion"
)
assert row_bend_px(corners_distorted) > 2 and row_bend_px(corners_straight) < 0.05
plotting.show_images(
    [distorted_image, undistorted_image],
    ["through the lens (k1 = -0.28)", "cv2.undistort(image, K, dist)"],
    ncols=2,
    width_in=12,
)
plt.show()

# %% [markdown]
# The undistorted picture loses a little at its edges (pixels that came from outside the sensor are black) and
# is resampled, so detect markers in the **original** picture and give the distortion to `solvePnP`, as
# fidlearn does; `cv2.undistort` is for looking, and for algorithms that need a pinhole picture.

# %% [markdown]
# ## Try it
#
# An 80 mm marker, 1.5 m in front of a camera with fx = 600 px. If you move the camera twice as far away, or
# zoom to twice the focal length, how wide is the marker in the picture? And with half the field of view?
# **Write your prediction down first**, then change the numbers and run the cell.

# %%
SIDE_MM = 80.0  # the marker's side
DISTANCE_MM = 1500.0  # try 3000
FX_PX = 600.0  # try 1200, or the fx of a 30 degree field of view

marker = np.array([[-SIDE_MM / 2, 0, DISTANCE_MM], [SIDE_MM / 2, 0, DISTANCE_MM]])  # its left and right edge
px, _ = cv2.projectPoints(
    marker, np.zeros(3), np.zeros(3), np.array([[FX_PX, 0, 319.5], [0, FX_PX, 239.5], [0, 0, 1]]), None
)
width_px = float(np.linalg.norm(px[1] - px[0]))
print(
    f"{SIDE_MM:.0f} mm at {DISTANCE_MM:.0f} mm with fx = {FX_PX:.0f} px: {width_px:.1f} px wide "
    f"(fx * side / Z = {FX_PX * SIDE_MM / DISTANCE_MM:.1f}); "
    f"field of view {math.degrees(2 * math.atan(320 / FX_PX)):.1f} deg"
)

# %% [markdown]
# ## Summary
#
# * A camera maps a point (X, Y, Z) of its own frame to `u = fx X/Z + cx`, `v = fy Y/Z + cy`: the
#   intrinsic matrix K holds fx, fy, cx, cy, all in **pixels**.
# * The field of view is `2 atan(w / 2fx)`; a marker of side s at distance Z is about `fx s / Z` pixels wide.
# * `cv2.projectPoints` (and `Camera.project`) add lens distortion, on normalized coordinates, with
#   `dist = [k1, k2, p1, p2, k3]`; `Camera.undistort_points` (and `cv2.undistortPoints`) removes it from points,
#   `cv2.undistort` from a whole picture. Ignoring a real lens's distortion moves the pose by millimetres to
#   centimetres with a reprojection error that does not warn you (measured above).
# * K and the distortion belong to one camera **at one resolution**: notebook 02 measures them.
#
# **Exercises**: [exercises/01_pinhole.ipynb](exercises/01_pinhole.ipynb), with automatic feedback
# (or `from fidlearn import exercises; ex = exercises.lesson("01")` in a new cell).
#
# Next: [02 Calibration](02_calibration.ipynb).

# %% [markdown]
# ## References
#
# * OpenCV, "Camera Calibration and 3D Reconstruction" (calib3d): the pinhole model, K and the distortion
#   model, `projectPoints`, `undistort`, `undistortPoints`: https://docs.opencv.org/4.x/d9/d0c/group__calib3d.html
# * R. Hartley and A. Zisserman, *Multiple View Geometry in Computer Vision*, 2nd ed., Cambridge University
#   Press, 2004, chapter 6 (camera models).
# * Z. Zhang, "A flexible new technique for camera calibration", IEEE Transactions on Pattern Analysis and
#   Machine Intelligence 22(11), 2000: where K and the distortion come from (notebook 02).
