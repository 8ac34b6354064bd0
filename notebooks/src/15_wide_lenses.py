# %% [markdown]
# # 15 Wide lenses: the fisheye model
#
# **What you will learn**
#
# * why the pinhole model cannot hold a lens much wider than 100 degrees, and the model that can: the
#   equidistant projection and its Kannala-Brandt polynomial (OpenCV's `cv2.fisheye`);
# * how to calibrate a real fisheye lens, let the held-out error choose the model (`model="auto"`), and check
#   the result against a published calibration;
# * how to undistort a wide picture (`cv2.getOptimalNewCameraMatrix` and its `alpha`, the fisheye's
#   `balance`, `initUndistortRectifyMap` and `remap`) and what is lost at the edges;
# * how to tell whether two calibrations differ by more than their noise, and what that says about the model
#   and the lens;
# * what the right model is worth for a pose from markers at the edge of a fisheye picture.
#
# Notebook 01 met lens distortion as a small correction to the pinhole. A fisheye is no small correction:
# it sees half the world. Run the cells from top to bottom (Shift-Enter).

# %%
# %matplotlib inline
import json
import os

import cv2
import matplotlib.pyplot as plt
import numpy as np

from fidlearn import (
    Board,
    Camera,
    MarkerMap,
    calibrate_checkerboard,
    compare_calibrations,
    data_path,
    detect_markers,
    estimate_pose,
    frames,
    render_scene,
)
from fidlearn.calibration import Calibration
from fidlearn.errors import PoseError
from fidlearn.ros import load_camera_info

np.set_printoptions(precision=3, suppress=True)

# %% [markdown]
# ## 1. Why the pinhole model fails past about 100 degrees
#
# A pinhole camera puts a ray that comes in at an angle $\theta$ from the optical axis at a distance
# $r = f \tan\theta$ from the principal point. As $\theta$ nears 90 degrees, $\tan\theta$ runs off to
# infinity: a pinhole picture of a 160 degree view would need a sensor many times wider than its middle.
# Distortion coefficients cannot rescue it, since $k_1 r^2 + k_2 r^4 + \dots$ bends a radius that has already
# exploded. A fisheye lens is built the other way round: the **equidistant** projection $r = f\theta$ gives
# every degree the same number of pixels, and 90 degrees lands at $r = f\pi/2$, a finite place on the sensor.
#
# Real fisheye lenses are close to equidistant but not exactly. OpenCV's `cv2.fisheye` (the
# **Kannala-Brandt** model) writes the angle on the sensor as an odd polynomial of the true angle,
#
# $$\theta_d = \theta\,(1 + k_1\theta^2 + k_2\theta^4 + k_3\theta^6 + k_4\theta^8), \qquad
# (u, v) = (c_x, c_y) + f\,\theta_d\,\frac{(x, y)}{\sqrt{x^2 + y^2}}$$
#
# for a point $(x, y, z)$ in the camera's frame, $\theta = \operatorname{atan2}(\sqrt{x^2+y^2}, z)$: four
# coefficients, and a ray at 90 degrees or beyond (behind the lens's plane) still has a pixel.

# %%
f = 290.0  # px: the focal length of the lens in this notebook's photos
theta_deg = np.linspace(0, 95, 200)
theta = np.radians(theta_deg)
with np.errstate(divide="ignore"):
    r_pinhole = np.where(theta_deg < 90, f * np.tan(theta), np.nan)
r_equidistant = f * theta

fig, ax = plt.subplots(figsize=(7, 3.6))
ax.plot(theta_deg, r_pinhole, label=r"pinhole $r = f\tan\theta$")
ax.plot(theta_deg, r_equidistant, label=r"equidistant $r = f\theta$")
ax.axhline(400, color="gray", ls="--", lw=1, label="half the picture's width (400 px)")
ax.set_ylim(0, 1200)
ax.set_xlabel("angle from the optical axis (degrees)")
ax.set_ylabel("distance from the principal point (px)")
ax.legend()
plt.show()

half_pinhole_deg = np.degrees(np.arctan(400 / f))
half_fisheye_deg = np.degrees(400 / f)
print(
    f"across 800 px at f = {f:.0f} px: pinhole {2 * half_pinhole_deg:.0f} deg, fisheye {2 * half_fisheye_deg:.0f} deg"
)


def kannala_brandt(points, K, D):
    """Pixels (N, 2) of camera-frame points (N, 3) through the Kannala-Brandt model, written out."""
    x, y, z = np.asarray(points, dtype=float).T
    rho = np.hypot(x, y)
    th = np.arctan2(rho, z)
    th_d = th * (1 + D[0] * th**2 + D[1] * th**4 + D[2] * th**6 + D[3] * th**8)
    return np.column_stack([K[0, 0] * th_d * x / rho + K[0, 2], K[1, 1] * th_d * y / rho + K[1, 2]])


K_demo = np.array([[f, 0.0, 399.5], [0.0, f, 251.0], [0.0, 0.0, 1.0]])
D_demo = np.array([-0.03, -0.02, 0.002, 0.001])
rays = np.array([[0.2, 0.1, 1.0], [1.0, 0.5, 0.3], [1.0, -0.2, 0.05]])  # 13, 75 and 87 degrees off the axis
ours = kannala_brandt(rays, K_demo, D_demo)
opencv = cv2.fisheye.projectPoints(rays.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K_demo, D_demo)[0].reshape(-1, 2)
assert np.allclose(ours, opencv, atol=1e-6)
print("Kannala-Brandt by hand and cv2.fisheye.projectPoints agree:")
print(ours)
print(
    "a ray 95 degrees off the axis, behind the lens's plane, lands at",
    kannala_brandt([[-1.0, 0.0, -0.0875]], K_demo, D_demo),
)

# %% [markdown]
# At this focal length the pinhole model covers {{ 2 * half_pinhole_deg:.0f }} degrees across the picture's
# 800 pixels, the equidistant one {{ 2 * half_fisheye_deg:.0f }} degrees. The cell checked the polynomial
# against `cv2.fisheye.projectPoints` up to 87 degrees off the axis. OpenCV's function divides by $z$ on the way,
# so it stops at 90 degrees; the formula itself (with $\operatorname{atan2}$) goes on, and puts a ray from behind
# the lens's plane inside the picture, which no pinhole can do.
#
# ## 2. Calibrating a real fisheye
#
# `data/real/fisheye_checkerboard/` holds photos of a fisheye lens (800 x 503, about 180 degrees across)
# and a checkerboard of 6 x 8 inner corners, in three independent sets with the calibrations ROS's fisheye
# calibrator made from them (provenance in `data/README.md`). `calibrate_checkerboard(..., model="auto")`
# calibrates both models on all but a fifth of the views and measures each on the fifth it did not see, in
# turn: a pinhole stretched over a fisheye fits its own views by bending wrong elsewhere, and that shows on
# views it never saw. The square size was never published; 25 mm stands in (it scales the board's poses,
# never K).

# %%
REAL = data_path("real", "fisheye_checkerboard")
BOARD = Board.checkerboard((6, 8), 25.0)
mono = [os.path.relpath(p) for p in sorted((REAL / "mono").glob("*.png"))]
auto = calibrate_checkerboard(mono, board=BOARD, model="auto")
pinhole = calibrate_checkerboard(mono, board=BOARD, model="pinhole")
print({m: round(e, 3) for m, e in auto.held_out_rms_px.items()}, "px held out: auto chose", auto.camera.model)
print(auto.table())
print(f"fisheye RMS {auto.rms_px:.3f} px on its own views")
print(
    f"pinhole fit to the same views: RMS {pinhole.rms_px:.3f} px, per view",
    np.round(list(pinhole.per_view_rms_px.values()), 3),
)

ros = load_camera_info(REAL / "mono" / "ost.yaml")  # ROS labels its 4 fisheye coefficients plumb_bob
reference = Camera(ros.K, ros.dist, ros.image_size, model="fisheye")
for name, cam in (
    ("fisheye, 6 photos", auto.camera),
    ("pinhole, 6 photos", pinhole.camera),
    ("ROS, 24 photos", reference),
):
    print(f"{name:18s} fx {cam.fx:6.1f}  fy {cam.fy:6.1f}  cx {cam.cx:6.1f}  cy {cam.cy:6.1f}")

# %% [markdown]
# On the views it was fitted to, the pinhole looks as good as the fisheye: RMS {{ pinhole.rms_px:.2f }} px
# against {{ auto.rms_px:.2f }} px, and a focal length close to ROS's. On views it did not see, the fisheye
# model misses by {{ auto.held_out_rms_px["fisheye"]:.2f }} px and the pinhole by
# {{ auto.held_out_rms_px["pinhole"]:.2f }} px, so `auto` keeps the fisheye. Six photos put the fisheye's focal
# length within {{ 100 * abs(auto.camera.fx / reference.fx - 1):.1f }} % of ROS's calibration from the whole set
# of 24. The pinhole's five coefficients can bend to fit six views of a board that stays well inside the
# picture; what they do between and beyond those views, only views they never saw can tell.
#
# ## 3. Undistortion: what a straight picture costs
#
# Undistorting maps the picture onto an ideal pinhole camera $K_{new}$. Its choice decides what is kept:
#
# * for the pinhole model, `cv2.getOptimalNewCameraMatrix(K, dist, size, alpha)`: `alpha = 0` keeps only
#   valid pixels (a crop), `alpha = 1` keeps every source pixel (black corners where nothing maps);
# * for the fisheye model, `cv2.fisheye.estimateNewCameraMatrixForUndistortRectify(K, D, size, R, balance=...)`:
#   `balance` 0 to 1 from a tight crop to the whole picture;
# * then `initUndistortRectifyMap` (`cv2.fisheye.initUndistortRectifyMap` for the fisheye) gives, for every
#   pixel of the new picture, where to read in the old one, and `cv2.remap` reads it.
#
# The undistorted picture is a pinhole picture: it can hold rays near 90 degrees only with a focal length
# near zero.

# %%
photo = cv2.imread(mono[2], cv2.IMREAD_GRAYSCALE)
size = reference.image_size
K, D = reference.K, reference.dist


def kept_fov_deg(K_new):
    """The field of view across the undistorted picture's width (degrees)."""
    return float(
        np.degrees(np.arctan(K_new[0, 2] / K_new[0, 0]) + np.arctan((size[0] - 1 - K_new[0, 2]) / K_new[0, 0]))
    )


def source_kept(map_x, map_y):
    """The share of the source picture's pixels that the undistorted picture reads."""
    ok = (map_x >= 0) & (map_x < size[0] - 1) & (map_y >= 0) & (map_y < size[1] - 1)
    hit = np.zeros(size[::-1], bool)
    hit[map_y[ok].astype(int), map_x[ok].astype(int)] = True
    return float(hit.mean())


views, kept = {}, {}


def show(name, K_new, maps):
    """Remap the photo with the maps; note the new camera's focal length, principal point, view and share read."""
    views[name] = cv2.remap(photo, maps[0], maps[1], cv2.INTER_LINEAR)
    kept[name] = (K_new[0, 0], K_new[0, 2], K_new[1, 2], kept_fov_deg(K_new), source_kept(*maps))


for balance in (0.0, 1.0):
    K_new = cv2.fisheye.estimateNewCameraMatrixForUndistortRectify(K, D, size, np.eye(3), balance=balance)
    show(f"fisheye, balance {balance:g}", K_new, cv2.fisheye.initUndistortRectifyMap(K, D, np.eye(3), K_new, size, 5))
K_hand = np.array([[399.5 / np.tan(np.radians(70.0)), 0.0, 399.5], [0.0, 0.0, 251.0], [0.0, 0.0, 1.0]])
K_hand[1, 1] = K_hand[0, 0]  # by hand: 140 degrees across the width, the principal point in the middle
show("fisheye, 140 deg by hand", K_hand, cv2.fisheye.initUndistortRectifyMap(K, D, np.eye(3), K_hand, size, 5))
pin_K, pin_dist = pinhole.camera.K, pinhole.camera.dist
for alpha in (0.0, 1.0):
    K_new, _ = cv2.getOptimalNewCameraMatrix(pin_K, pin_dist, size, alpha)
    show(f"pinhole fit, alpha {alpha:g}", K_new, cv2.initUndistortRectifyMap(pin_K, pin_dist, None, K_new, size, 5))

fig, axes = plt.subplots(2, 3, figsize=(14, 6))
axes = axes.ravel()
axes[0].imshow(photo, cmap="gray")
axes[0].set_title("the photo")
for ax, (name, img) in zip(axes[1:], views.items()):
    ax.imshow(img, cmap="gray")
    ax.set_title(name)
for ax in axes:
    ax.axis("off")
plt.show()


def angle_deg(px):
    """How far off the axis (degrees) the lens sees each pixel (N, 2): the polynomial of section 1 inverted."""
    th = np.linspace(0.0, 1.8, 20001)
    th_d = th * (1 + D[0] * th**2 + D[1] * th**4 + D[2] * th**6 + D[3] * th**8)  # rising over this range
    r = np.hypot(*((np.asarray(px, float) - [reference.cx, reference.cy]) / [reference.fx, reference.fy]).T)
    return np.degrees(np.interp(r, th_d, th))


edges = np.array([[0.0, 251.0], [799.0, 251.0]])  # the middles of the left and right edges
edge_deg = angle_deg(edges)
lens_fov_deg = float(edge_deg.sum())
print(f"the lens sees {edge_deg[0]:.1f} and {edge_deg[1]:.1f} deg off the axis at the middles of the left and right")
print(f"edges: {lens_fov_deg:.0f} deg across the width (maps: 5 = cv2.CV_32FC1)")
for name, (fx_new, cx_new, cy_new, fov, share) in kept.items():
    print(
        f"{name:24s} fx {fx_new:5.1f} px, centre ({cx_new:5.1f}, {cy_new:5.1f}), {fov:5.1f} deg across, "
        f"reads {100 * share:2.0f} % of the photo"
    )
opencv_xy = cv2.fisheye.undistortPoints(edges.reshape(1, -1, 2), K, D).reshape(-1, 2)
print("the edges' middles through cv2.fisheye.undistortPoints, as x/z, y/z:", opencv_xy.ravel())

# %% [markdown]
# `balance = 1` keeps {{ kept["fisheye, balance 1"][3]:.0f }} degrees across with a focal length of
# {{ kept["fisheye, balance 1"][0]:.0f }} px: the middle becomes a dot and the picture is all stretched edge,
# reading {{ 100 * kept["fisheye, balance 1"][4]:.0f }} % of the photo's pixels. `balance = 0` should be the tight
# crop, yet it puts the new principal point at ({{ kept["fisheye, balance 0"][1]:.0f }},
# {{ kept["fisheye, balance 0"][2]:.0f }}), far from the middle. OpenCV chooses the new camera from where the
# picture's edges undistort to, with `cv2.fisheye.undistortPoints`, as points $(x/z, y/z)$ on an ideal pinhole's
# picture; this lens sees the middles of its left and right edges {{ edge_deg[0]:.0f }} and
# {{ edge_deg[1]:.0f }} degrees off the axis, where $x/z$ is infinite or behind the camera, and the last line
# shows what comes back: {{ opencv_xy[0, 0]:.0f }} and {{ opencv_xy[1, 0]:.0f }}, numbers that mean nothing. Check
# what `estimateNewCameraMatrixForUndistortRectify` gives before using it on a lens this wide, or choose the new
# camera by hand: a focal length of
# {{ K_hand[0, 0]:.0f }} px keeps {{ kept["fisheye, 140 deg by hand"][3]:.0f }} of the lens's {{ lens_fov_deg:.0f }}
# degrees and reads {{ 100 * kept["fisheye, 140 deg by hand"][4]:.0f }} % of its pixels; the lens's own focal
# length would keep only {{ np.degrees(2 * np.arctan(399.5 / reference.fx)):.0f }} degrees. A straight picture
# either throws the edges away or spends its pixels on them, because $\tan\theta$ runs away.
#
# The pinhole fit undistorts into pictures that look plausible and are wrong near the edges: it does not know
# the lens. This is why fidlearn works on the fisheye's own pixels and undistorts only the detected corners,
# exactly (`Camera.undistort_points`), never the picture.
#
# ## 4. Do two calibrations agree?
#
# Two calibrations never give the same numbers. `compare_calibrations(a, b)` asks where each puts a ray on
# the picture, across the whole picture (after the small turn that best maps one camera's frame onto the
# other's, which moves every pose but no measurement), and how large that difference should be from both
# calibrations' own uncertainty. Its verdict: **differ beyond noise** (more than twice the expected size),
# **agree** (within it, and the expected size under `tolerance_px`, 2 px below), or **cannot tell** (within it, but the
# calibrations are too uncertain to say more).
#
# The whole sets are 116 photos (20 MB); `corners.json` holds the checkerboard corners found in every one of
# them. The cell below calibrates from those corners with OpenCV directly. `cv2.fisheye.calibrate` must start
# from a guess when the lens is this wide (its own start, f from the picture's size, fails): an equidistant
# lens spanning 180 degrees across the width. It wraps each result in a `Calibration` so that
# `compare_calibrations` can measure its uncertainty from its views.

# %%
sets = json.loads((REAL / "corners.json").read_text())["sets"]
board_mm = BOARD.object_points()
print({name: len(v) for name, v in sets.items()}, "photos with corners")


def fisheye_flag(name):
    """A cv2.fisheye.calibrate flag: cv2.fisheye.CALIB_* in OpenCV 4, cv2.CALIB_* in OpenCV 5."""
    return getattr(cv2.fisheye, name, getattr(cv2, name, 0))


def calibrate_corners(views, model):
    """A Calibration of the views' corners {name: (48, 2) px} with cv2.fisheye.calibrate or cv2.calibrateCamera."""
    names = list(views)
    img = [np.asarray(views[n], np.float64).reshape(-1, 1, 2) for n in names]
    obj = [board_mm.reshape(-1, 1, 3)] * len(img)
    if model == "fisheye":
        f0 = size[0] / np.pi  # 180 degrees across the width
        K0 = np.array([[f0, 0.0, (size[0] - 1) / 2], [0.0, f0, (size[1] - 1) / 2], [0.0, 0.0, 1.0]])
        flags = sum(
            fisheye_flag(n) for n in ("CALIB_RECOMPUTE_EXTRINSIC", "CALIB_FIX_SKEW", "CALIB_USE_INTRINSIC_GUESS")
        )
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-10)
        obj1, img1 = [o.reshape(1, -1, 3) for o in obj], [p.reshape(1, -1, 2) for p in img]  # the shapes it takes
        _, K_, D_, rvecs, tvecs = cv2.fisheye.calibrate(obj1, img1, size, K0, np.zeros(4), flags=flags, criteria=crit)
    else:
        obj32, img32 = [o.astype(np.float32) for o in obj], [p.astype(np.float32) for p in img]
        _, K_, D_, rvecs, tvecs = cv2.calibrateCamera(obj32, img32, size, None, None)
    cam = Camera(K_, np.ravel(D_), size, model=model)
    T = {n: frames.transform_from_rvec_tvec(np.ravel(r), np.ravel(t)) for n, r, t in zip(names, rvecs, tvecs)}
    err = {
        n: np.sqrt(np.mean(np.sum((cam.project(board_mm, frames.invert_transform(T[n])) - views[n]) ** 2, 1)))
        for n in names
    }
    return Calibration(
        camera=cam,
        rms_px=float(np.sqrt(np.mean(np.square(list(err.values()))))),
        per_view_rms_px=err,
        used=names,
        std_intrinsics=None,
        rejected=[],
        T_camera_board=T,
        image_points_px={n: np.asarray(views[n], float) for n in names},
        board_points_mm={n: board_mm for n in names},
    )


def half(name, k):
    """Every other photo of a set, from the k-th."""
    return dict(list(sets[name].items())[k::2])


cals = {}
for model in ("fisheye", "pinhole"):
    for name in sets:
        cals[model, name] = calibrate_corners(sets[name], model)
    for k in (0, 1):
        cals[model, f"left {'even' if k == 0 else 'odd'}"] = calibrate_corners(half("left", k), model)
for name in sets:
    cam = cals["fisheye", name].camera
    rms = cals["fisheye", name].rms_px
    print(f"fisheye {name:5s}: fx {cam.fx:6.2f}, cx {cam.cx:6.1f}, cy {cam.cy:6.1f}, RMS {rms:.3f} px")
ros_files = {"mono": "ost.yaml", "left": "left.yaml", "right": "right.yaml"}
worst_fx_percent = 100 * max(
    abs(cals["fisheye", n].camera.fx / load_camera_info(REAL / n / ros_files[n]).K[0, 0] - 1) for n in sets
)
assert worst_fx_percent < 0.5  # each whole set: ROS's answer

pairs = [("left even", "left odd"), ("mono", "left"), ("left", "right"), ("mono", "right")]
verdicts = {}
for model in ("fisheye", "pinhole"):
    for a, b in pairs:
        c = compare_calibrations(cals[model, a], cals[model, b], tolerance_px=2.0)
        verdicts[model, a, b] = c
        print(f"{model:7s} {a:9s} vs {b:8s}: {c}")

# %% [markdown]
# The fisheye model calibrates each whole set to within {{ worst_fx_percent:.2f }} % of ROS's focal length for
# that set. Now read the verdicts:
#
# * **The halves of one set** (the left set's even and odd photos) and **two sets of one camera** (`mono` and
#   `left`: both sets' files are named `left-*`, most likely one camera on two occasions) differ by
#   {{ verdicts["fisheye", "left even", "left odd"].ratio:.1f }} and {{ verdicts["fisheye", "mono", "left"].ratio:.1f }}
#   times their expected size: they agree, as two samples of one lens should.
# * **`left` against `right`**: {{ verdicts["fisheye", "left", "right"].ratio:.1f }} times the noise. The right
#   set is the other camera of a stereo pair, a second copy of the lens: its principal point sits a few pixels
#   away. The comparison tells two copies of one lens apart, which the focal lengths alone
#   ({{ cals["fisheye", "left"].camera.fx:.1f }} and {{ cals["fisheye", "right"].camera.fx:.1f }} px) would not.
#   `mono` against `right` differs by more pixels ({{ verdicts["fisheye", "mono", "right"].rms_difference_px:.1f }}
#   px RMS) but only {{ verdicts["fisheye", "mono", "right"].ratio:.1f }} times its expected size: with the 24
#   photos of `mono` the difference expected from noise alone is
#   {{ np.nanmedian(verdicts["fisheye", "mono", "right"].expected_px):.1f }} px (median), against
#   {{ np.nanmedian(verdicts["fisheye", "left", "right"].expected_px):.1f }} px for two sets of 46: too much to
#   tell these two lenses apart. **Noise** shrinks with more views.
# * **The pinhole model** fitted to the same corners: every comparison "cannot tell", with differences of
#   {{ verdicts["pinhole", "left even", "left odd"].rms_difference_px:.0f }} to
#   {{ max(v.rms_difference_px for k, v in verdicts.items() if k[0] == "pinhole"):.0f }} px RMS and expected sizes
#   of several pixels (the halves' {{ np.nanmedian(verdicts["pinhole", "left even", "left odd"].expected_px):.0f }}
#   px): a model that cannot describe the lens pins down nothing, whatever the number of views. **Model error**
#   does not shrink with more views; it shows as calibrations too uncertain to tell anything, or as
#   calibrations of one lens that disagree (the Try-it below), never as a large RMS on the views it was fitted
#   to.
#
# The heat maps show where two calibrations of one camera part: in the middle, where every view had the
# board, they agree to a fraction of a pixel; towards the edges, where few corners were, both the difference
# and its expected size grow. (Blank cells: rays the lens model cannot bring back, past its edge.)

# %%
verdicts["fisheye", "mono", "left"].plot()
plt.show()

# %% [markdown]
# ## 5. A pose from markers at the edge of a fisheye picture
#
# A rendered picture has a known truth. `render_scene` draws a room of markers through ROS's fisheye
# calibration of this lens, from a camera turned away from the wall of markers, so that they sit towards the
# picture's edge, more than 80 degrees off the axis. The pose is then estimated twice from the same detections: with the
# fisheye camera, and with the pinhole camera fitted in section 2 to the same lens (as one would get by
# calibrating a fisheye with `cv2.calibrateCamera`).

# %%
walls = MarkerMap.load(data_path("two_walls_map.json"))
T_world_camera = frames.look_at([500.0, 150.0, 300.0], [329.0, 620.0, 300.0])
scene = render_scene(walls, reference, T_world_camera, seed=3, blur_px=0.5, noise_std_gray=1.0)
found = [d for d in detect_markers(scene.image, walls.dictionary) if d.id in scene.truth]
in_camera = frames.invert_transform(T_world_camera)
off_axis = {}
for d in found:
    centre = in_camera[:3, :3] @ walls.marker_corners(d.id).mean(axis=0) + in_camera[:3, 3]
    off_axis[d.id] = float(np.degrees(np.arccos(centre[2] / np.linalg.norm(centre))))
print(f"{len(found)} markers found, {min(off_axis.values()):.0f} to {max(off_axis.values()):.0f} deg off the axis")

results = {}
for name, cam in (("fisheye model", reference), ("pinhole fit", pinhole.camera)):
    try:
        pose = estimate_pose(found, walls, cam)
    except PoseError as e:  # a wrong lens model may fit no pose at all
        print(f"{name:14s}: no pose: {str(e)[:100]}...")
        continue
    err_mm = float(np.linalg.norm(pose.position_mm - T_world_camera[:3, 3]))
    err_deg = frames.rotation_angle_deg(pose.T_world_camera[:3, :3], T_world_camera[:3, :3])
    results[name] = (err_mm, err_deg, len(pose.marker_ids))
    print(f"{name:14s}: {len(pose.marker_ids)} markers, position error {err_mm:6.1f} mm, rotation {err_deg:5.2f} deg")

fig, ax = plt.subplots(figsize=(6, 3.8))
ax.imshow(scene.image, cmap="gray")
for d in found:
    ax.plot(*np.vstack([d.corners_px, d.corners_px[:1]]).T, "r-", lw=1)
    ax.text(*d.corners_px.mean(axis=0), f"{off_axis[d.id]:.0f} deg", color="yellow", fontsize=8)
ax.axis("off")
plt.show()

# %% [markdown]
# With the fisheye model the camera is found within {{ results["fisheye model"][0]:.1f }} mm and
# {{ results["fisheye model"][1]:.2f }} degrees of the truth, from {{ results["fisheye model"][2] }} markers. The
# pinhole fitted to the same lens keeps {{ results["pinhole fit"][2] }} of them (it undistorts the others' corners
# so wrongly that `estimate_pose` rejects them as misfits) and misses by {{ results["pinhole fit"][0]:.0f }} mm and
# {{ results["pinhole fit"][1]:.1f }} degrees. Its reprojection error on its own calibration photos was half a
# pixel: small, because those photos had the board well inside the picture. At the edges, where a wide lens is
# most useful, the wrong model is worst; another pinhole fit (OpenCV 4's, from the same six photos) finds no pose
# at all here: `estimate_pose` says the corners do not fit the map.
#
# ## What you have learnt
#
# * The pinhole's $r = f\tan\theta$ runs away near 90 degrees; a fisheye follows $r \approx f\theta$, and
#   OpenCV's Kannala-Brandt model writes its departure from that as a polynomial in $\theta$.
# * Calibrate a wide lens with both models and let views they did not see choose (`model="auto"`); check it
#   against an independent calibration.
# * Undistorting a fisheye picture trades the edges against the middle (`balance`, `alpha`); undistort the
#   corners instead.
# * Two calibrations agree when their difference is within its expected size; a wrong model, or another copy
#   of the lens, shows as a difference beyond it.
# * At a fisheye's edge, only the fisheye model gives the right pose.
#
# **Exercises**: [exercises/15_wide_lenses.ipynb](exercises/15_wide_lenses.ipynb), with automatic feedback
# (or `from fidlearn import exercises; ex = exercises.lesson("15")` in a new cell).
#
# ## Try it
#
# * The cell below compares the fisheye and the pinhole calibration of the left set with each other: where on
#   the picture do they part, and by how much?
# * Calibrate the halves of the `mono` set (12 photos each) in place of the left set's: which verdict do you
#   get, and why?
# * Turn the camera of section 5 so that the markers sit in the middle of the picture (aim it at
#   `[0.0, 150.0, 260.0]`): how far off is the pinhole fit there?

# %%
models = compare_calibrations(cals["fisheye", "left"], cals["pinhole", "left"], tolerance_px=2.0)
print(models)
models.plot()
plt.show()

# %% [markdown]
# ## References
#
# * J. Kannala, S. S. Brandt, "A generic camera model and calibration method for conventional, wide-angle,
#   and fish-eye lenses", *IEEE Transactions on Pattern Analysis and Machine Intelligence* 28(8), 2006.
# * OpenCV, the fisheye camera model: https://docs.opencv.org/4.x/db/d58/group__calib3d__fisheye.html
# * mrcal, "Differencing" and "Projection uncertainty" (comparing calibrations across the picture):
#   https://mrcal.secretsauce.net/differencing.html
# * ros-perception, `image_pipeline` (the photos and ROS's fisheye calibrations):
#   https://github.com/ros-perception/image_pipeline
