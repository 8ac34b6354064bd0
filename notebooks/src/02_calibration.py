# %% [markdown]
# # 02 Calibration: measuring K and the lens distortion
#
# **What you will learn**
#
# * how photos of a checkerboard give the camera's K and distortion (`cv2.calibrateCamera`);
# * how to find the board's corners (`cv2.findChessboardCorners`, `cornerSubPix`, the `SB` variant);
# * why the printed square size scales the board poses but **never K**;
# * how to read per-view errors, and which views to reject;
# * calibrating a synthetic set (true camera known) and real photos (published numbers known);
# * saving and loading `camera.json`;
# * the trap of calibrating at one resolution and running at another, measured, and its fixes;
# * why a small RMS is not enough: the **reprojection uncertainty** across the picture, the calibration coach's
#   warnings, and following its advice for the next photo against taking random ones.
#
# Notebook 01 explains K and the distortion coefficients.

# %%
# %matplotlib inline
import json
import os
import tempfile
import warnings

import cv2
import matplotlib.pyplot as plt
import numpy as np
from IPython.display import display

from fidlearn import (
    Camera,
    CameraError,
    FidlearnWarning,
    MarkerMap,
    calibrate_checkerboard,
    data_path,
    frames,
    locate,
    plotting,
    synthetic,
)
from fidlearn.detection import detect_markers, load_image
from fidlearn.planning import coach, coach_calibration
from fidlearn.planning.figure import coach_figure

np.set_printoptions(precision=3, suppress=True)


def rel(path):
    """A data file's path relative to this notebook's folder: short, and the same on every machine."""
    return os.path.relpath(path)


# %% [markdown]
# ## 1. The checkerboard
#
# A checkerboard is a flat target whose geometry we know exactly: its **inner corners** (where four
# squares meet) form a grid with the printed square size as spacing. OpenCV counts inner corners, so a
# board of 10 x 7 squares is a **9 x 6** pattern. Put the board's frame on it (corner (i, j) at
# (i s, j s, 0) mm, s the square size): every photo pairs these 54 known 3D points with their pixels.
#
# `data/calibration/` holds 20 synthetic photos of a 9 x 6 board with 25 mm squares, taken by a camera
# whose K and distortion are known (`camera_true.json`): we can check the answer.

# %%
views = [rel(p) for p in sorted(data_path("calibration").glob("view_*.png"))]
record = json.loads(data_path("calibration", "views.json").read_text())
true_camera = Camera.load(data_path("calibration", "camera_true.json"))
pattern = (9, 6)  # inner corners (columns, rows)
square_size_mm = 25.0
print(len(views), "views; the true camera:", true_camera)

fig = plotting.show_images([load_image(v) for v in views[:4]], [os.path.basename(v) for v in views[:4]], ncols=4)
plt.show()

# %% [markdown]
# ## 2. Finding the corners
#
# `cv2.findChessboardCorners` finds the pattern and orders its corners row by row; `cv2.cornerSubPix`
# then refines each to a fraction of a pixel using the image gradients in a small window (half-size 5 px
# here: the window must not reach the next corner). `cv2.findChessboardCornersSB` is a newer detector
# that refines by itself. The synthetic views record the true corners: let us measure both.
#
# Turned by 180 degrees, the 9 x 6 grid of inner corners lands on itself; only the colours of the squares
# swap. Does a detector number the corners from a corner of the *board* (it reads the colours) or of the
# *picture*? Find out: detect in every view upright and turned, and see which physical corner each
# detector calls corner 0 (the synthetic views record the true corners, true corner 0 first).


# %%
def physical_corner0(gray, sb):
    """Which end of the board a detector numbers from: 'first' (the true corner 0) or 'last' (corner 53)."""
    ok, c = (
        cv2.findChessboardCornersSB(gray, pattern)
        if sb
        else cv2.findChessboardCorners(gray, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    )
    assert ok
    return c.reshape(-1, 2)[0]


starts = {}  # (detector, turned) -> how many views it numbered from the true corner 0
for i, v in enumerate(views):
    g = load_image(v)
    h, w = g.shape[:2]
    true_px = np.array(record["views"][i]["corners_px"])
    for name, sb in (("classic", False), ("SB", True)):
        for turned in (False, True):
            c0 = physical_corner0(cv2.rotate(g, cv2.ROTATE_180) if turned else g, sb)
            if turned:
                c0 = np.array([w - 1, h - 1]) - c0  # back into the upright picture's pixels
            from_first = np.linalg.norm(c0 - true_px[0]) < np.linalg.norm(c0 - true_px[-1])
            starts[name, turned] = starts.get((name, turned), 0) + int(from_first)
n_views = len(views)
for (name, turned), n in starts.items():
    print(f"{name:7s} {'turned ' if turned else 'upright'}: numbered from the true corner 0 in {n} of {n_views} views")
assert starts["classic", False] == starts["classic", True] == n_views
assert starts["SB", False] == starts["SB", True] == 0

# %% [markdown]
# Both detectors read the colours: each numbers from the same physical corner of the board whichever way up
# the picture is ({{ starts["classic", True] }} of {{ n_views }} turned views for `findChessboardCorners`,
# like upright). But they disagree on *which* corner: `findChessboardCornersSB` starts at the other end in
# all {{ n_views - starts["SB", True] }}. So compare corner lists from two detectors only once their order
# agrees.

# %%
gray = load_image(views[0])
found, corners = cv2.findChessboardCorners(
    gray, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
)
assert found
criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 0.001)
refined = cv2.cornerSubPix(gray, corners.copy(), (5, 5), (-1, -1), criteria).reshape(-1, 2)  # it works in place

found_sb, corners_sb = cv2.findChessboardCornersSB(gray, pattern, flags=cv2.CALIB_CB_ACCURACY)
assert found_sb
corners_sb = corners_sb.reshape(-1, 2)

true_px = np.array(record["views"][0]["corners_px"])
rms = lambda a, b: float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))  # noqa: E731
if rms(corners_sb[::-1], true_px) < rms(corners_sb, true_px):
    print("SB numbered the corners from the other end of the board")
    corners_sb = corners_sb[::-1]
print(
    f"corner error vs truth: findChessboardCorners alone {rms(corners.reshape(-1, 2), true_px):.3f} px, "
    f"+ cornerSubPix {rms(refined, true_px):.3f} px, SB {rms(corners_sb, true_px):.3f} px"
)
assert rms(refined, true_px) < 0.1

ax = plotting.show_image(None, gray, title=f"{os.path.basename(views[0])}: 54 inner corners, in order 0 to 53")
plotting.draw_points(ax, refined, color="tab:red")
plotting.draw_points(ax, refined[[0, 8, 53]], labels=["0", "8", "53"], color="tab:red", marker="o", markersize=30)
plt.show()

# %% [markdown]
# The same on a real photo, OpenCV's `right01.jpg` (one of 13 in `data/real/opencv_checkerboard_right/`):

# %%
real_views = [rel(p) for p in sorted(data_path("real", "opencv_checkerboard_right").glob("right*.jpg"))]
real = load_image(real_views[0])
real_gray = cv2.cvtColor(real, cv2.COLOR_BGR2GRAY) if real.ndim == 3 else real
found, c = cv2.findChessboardCorners(
    real_gray, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
)
assert found
c = cv2.cornerSubPix(real_gray, c, (11, 11), (-1, -1), criteria).reshape(-1, 2)
ax = plotting.show_image(None, real, points=c, title=f"{os.path.basename(real_views[0])}: {len(c)} corners found")
plt.show()
assert len(c) == 54

# %% [markdown]
# ## 3. Calibrating, by hand
#
# For every view: the board points (mm) and their pixels. `cv2.calibrateCamera` searches K, the
# distortion and one board pose per view (rvec, tvec: `T_camera_board`) that together reproject the
# board points closest to the detected pixels, in the least-squares sense. Its first return value is
# the RMS **reprojection error** in pixels.

# %%
board_mm = np.zeros((pattern[0] * pattern[1], 3), np.float32)
board_mm[:, :2] = np.mgrid[0 : pattern[0], 0 : pattern[1]].T.reshape(-1, 2) * square_size_mm  # (i s, j s, 0)

object_points, image_points = [], []
for v in views:
    g = load_image(v)
    ok, c = cv2.findChessboardCorners(g, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if ok:
        object_points.append(board_mm)
        image_points.append(cv2.cornerSubPix(g, c, (5, 5), (-1, -1), criteria))

rms_px, K, dist, rvecs, tvecs = cv2.calibrateCamera(object_points, image_points, (640, 480), None, None)
print(f"{len(image_points)} views, RMS {rms_px:.3f} px")
print("K =\n", K)
print("dist =", dist.ravel())
print("true K =\n", true_camera.K)

assert abs(K[0, 0] / true_camera.fx - 1) < 0.005 and abs(K[1, 1] / true_camera.fy - 1) < 0.005
assert np.allclose(K[:2, 2], [true_camera.cx, true_camera.cy], atol=2.0)

# %% [markdown]
# `fidlearn.calibrate_checkerboard` does the same (with a corner window that adapts to the square's size
# in pixels), and reports each view, rejecting the ones that fail:

# %%
cal = calibrate_checkerboard(views, pattern, square_size_mm)
print(cal)
assert np.allclose(cal.camera.K, K, atol=1.0)
assert abs(cal.camera.fx / true_camera.fx - 1) < 0.005

# %% [markdown]
# ## 4. The square size scales the poses, never K
#
# Calibrate the same photos saying the squares are 50 mm instead of 25. A board twice as big, seen at
# the same pixels, must be twice as far away: every board pose's translation doubles, and K (in pixels)
# does not change at all. A wrong square size is invisible in K, and shows only when you measure
# distances. (The real photos' square size was never published: we use 25 mm as a stand-in below, and
# only their K is compared.)

# %%
cal_50 = calibrate_checkerboard(views, pattern, 50.0)
name = cal.used[0]
t_25 = cal.T_camera_board[name][:3, 3]
t_50 = cal_50.T_camera_board[name][:3, 3]
print("K with 25 mm squares:\n", cal.camera.K, "\nK with 50 mm squares:\n", cal_50.camera.K)
print(
    f"board distance in {os.path.basename(name)}: {np.linalg.norm(t_25):.1f} mm (25 mm squares), "
    f"{np.linalg.norm(t_50):.1f} mm (50 mm squares)"
)
assert np.allclose(cal_50.camera.K, cal.camera.K, rtol=1e-6)
assert np.allclose(t_50, 2 * t_25, rtol=1e-6)

# %% [markdown]
# ## 5. Per-view errors, and rejecting bad views
#
# A calibration is only as good as its worst views. Three kinds of bad photo:
#
# * the board is **not found** (cut off, blurred, glare): the view gives nothing, it is skipped;
# * a photo at **another resolution**: K is in pixels, so views must share one size;
# * a photo taken with **another camera setting** (zoom moved, autofocus changed K): the board is found,
#   but no single K explains it. Its reprojection error stands out.
#
# fidlearn rejects a view whose RMS exceeds `max(3 x median, median + 0.5 px)` and calibrates again.
# Let us add one photo of each kind to the 20 good views.

# %%
zoomed = Camera([[1100, 0, 321.7], [0, 1098, 243.4], [0, 0, 1]], true_camera.dist, (640, 480))
zoomed_view = synthetic.render_calibration_views(zoomed, n_views=1, seed=3).images[0]
empty_wall = np.full((480, 640), 128, np.uint8)
half_size = cv2.resize(load_image(views[0]), (320, 240), interpolation=cv2.INTER_AREA)

cal_bad = calibrate_checkerboard(views + [zoomed_view, empty_wall, half_size], pattern, square_size_mm)
print(cal_bad.summary())
statuses = [v.status for v in cal_bad.views[20:]]
assert statuses == ["outlier", "not found", "other size"], statuses
assert np.allclose(cal_bad.camera.K, cal.camera.K)  # the bad views left no trace

# %%
fig, ax = plt.subplots(figsize=(10, 3))
names = [os.path.basename(v.name) if v.name.endswith(".png") else v.name for v in cal_bad.views]
errors = [v.rms_px if v.rms_px is not None else 0.0 for v in cal_bad.views]
colors = ["tab:blue" if v.status == "used" else "tab:red" for v in cal_bad.views]
ax.bar(range(len(names)), errors, color=colors)
ax.set_xticks(range(len(names)), names, rotation=90, fontsize=7)
ax.set_ylabel("RMS reprojection error (px)")
ax.set_title("per-view error: used (blue), rejected (red; not found and other size have no error)")
plt.show()

# %% [markdown]
# ## 6. Real photos
#
# OpenCV's 13 `right*.jpg` photos (640 x 480, 9 x 6 inner corners). Their published result, a plain
# `cv2.calibrateCamera` on all 13: RMS about 0.46 px, fx about 542, fy about 542, cx about 328, cy
# about 247. We reproduce it, then let fidlearn reject outlier views.

# %%
cal_all = calibrate_checkerboard(real_views, pattern, 25.0, reject_outliers=False)
cal_real = calibrate_checkerboard(real_views, pattern, 25.0)
print("all 13 views    :", cal_all)
print("outliers removed:", cal_real)
assert len(cal_all.used) == 13 and abs(cal_all.rms_px - 0.46) < 0.02
assert abs(cal_all.camera.fx - 542) < 3 and abs(cal_all.camera.fy - 542) < 3
assert abs(cal_all.camera.cx - 328) < 3 and abs(cal_all.camera.cy - 247) < 3
assert abs(cal_real.camera.fx / cal_all.camera.fx - 1) < 0.01  # one view fewer, K within 1 %

# %% [markdown]
# Real photos have larger errors than synthetic ones (0.3 to 0.5 px instead of 0.05): printing, paper
# that is not flat, focus, compression. An RMS below about 0.5 px with 10 or more well-spread views is
# a good calibration.
#
# ## 7. Saving and loading `camera.json`
#
# `Camera.save` writes fidlearn's JSON (K, distortion, the image size it belongs to, and what produced
# it); `Camera.load` reads it back, and also reads OpenCV's YAML/XML calibration files.
# On the command line: `fidlearn calibrate photos/*.jpg --pattern 9x6 --square-mm 25 -o camera.json`.

# %%
with tempfile.TemporaryDirectory() as folder:
    path = os.path.join(folder, "camera.json")
    cal_real.camera.save(path)
    with open(path) as f:
        saved = json.load(f)
    loaded = Camera.load(path)
print(sorted(saved))
print("image_size:", saved["image_size"])
assert np.allclose(loaded.K, cal_real.camera.K) and np.allclose(loaded.dist, cal_real.camera.dist)
assert loaded.image_size == (640, 480)

# %% [markdown]
# ## 8. The resolution trap
#
# K is in **pixels of the calibration images**. Run the camera at another resolution and every pixel
# coordinate changes meaning. This is the classic Raspberry Pi mistake: calibrate at 1280 x 720, then
# switch the stream to 640 x 360 (or to a 4:3 mode) for speed.
#
# `data/scenes/` holds 1280 x 720 pictures of the seed wall taken by a camera whose K is known, from
# known poses. Here is the pose computation (notebooks 05 to 07 explain each step): detect the markers,
# `cv2.solvePnP` with their 3D corners, invert.

# %%
scene_camera = Camera.load(data_path("scenes", "camera.json"))
wall = MarkerMap.load(data_path("world_map.json"))
scene = load_image(data_path("scenes", "scene_00.png"))
T_true = np.array(json.loads(data_path("scenes", "poses.json").read_text())["images"][0]["T_world_camera"])


def camera_pose(image, camera):
    """T_world_camera (4, 4) from the markers in image, and the reprojection RMS (px)."""
    detections = [d for d in detect_markers(image, wall.dictionary) if d.id in wall]
    points_world = np.vstack([wall.corners()[d.id] for d in detections])
    points_px = np.vstack([d.corners_px for d in detections])
    ok, rvec, tvec = cv2.solvePnP(points_world, points_px, camera.K, camera.dist, flags=cv2.SOLVEPNP_ITERATIVE)
    T_world_camera = frames.invert_transform(frames.transform_from_rvec_tvec(rvec, tvec))
    residual = camera.project(points_world, T_world_camera) - points_px
    return T_world_camera, float(np.sqrt(np.mean(np.sum(residual**2, axis=1))))


def report(label, image, camera):
    T, rms_px = camera_pose(image, camera)
    error_mm = np.linalg.norm(T[:3, 3] - T_true[:3, 3])
    print(
        f"{label:42s} image {image.shape[1]}x{image.shape[0]}, camera {camera.width}x{camera.height}: "
        f"position error {error_mm:7.1f} mm, reprojection RMS {rms_px:.2f} px"
    )
    return error_mm


print(scene_camera)
err_ok = report("as calibrated", scene, scene_camera)
assert err_ok < 5

# %% [markdown]
# Now the same picture at half the resolution (the stream switched to 640 x 360), with the 1280 x 720
# camera file:

# %%
small = cv2.resize(scene, (640, 360), interpolation=cv2.INTER_AREA)
err_small_wrong = report("half resolution, K of 1280x720", small, scene_camera)
err_small_fixed = report("half resolution, Camera.scaled((640, 360))", small, scene_camera.scaled((640, 360)))
print(scene_camera.scaled((640, 360)))
assert err_small_wrong > 500 and err_small_fixed < 20

# %% [markdown]
# The camera appears twice as far away: fx is twice too big for these pixels. The same aspect ratio means
# the same sensor area read out at a lower resolution, so K scales exactly with the image
# (`Camera.scaled`). The fixed result is a little less accurate than at full resolution: the markers have
# half as many pixels. `fidlearn.locate` notices the size difference, scales the camera, and warns you:

# %%
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    pose_small = locate(small, wall, scene_camera)
for w in caught:
    print(f"{w.category.__name__}: {w.message}")
assert [w.category for w in caught] == [FidlearnWarning]
assert np.linalg.norm(pose_small.position_mm - T_true[:3, 3]) < 20

# %% [markdown]
#
# A **4:3 mode** on a 16:9 sensor is different: it crops the sensor's sides (here 960 x 720, the middle of
# the 1280 x 720 frame). Nothing scales, but the principal point is no longer where K says:

# %%
crop = scene[:, 160:1120]  # the middle 960 columns
err_crop_wrong = report("4:3 crop, K of 1280x720", crop, scene_camera)
try:
    scene_camera.scaled((960, 720))
except CameraError as exc:
    print("Camera.scaled refuses:", exc)
assert err_crop_wrong > 100

# %% [markdown]
# More than 10 cm off, and look at the reprojection error: still tiny. **A wrong K does not show in the
# reprojection error**, because the pose bends to fit. Here we happen to know the crop exactly (160
# columns off the left), so moving the principal point by 160 px would repair it; a real camera mode
# usually crops *and* bins in ways nobody documents, so the safe fix is: **calibrate at the resolution
# and mode you run at.** Here that is what a calibration at 960 x 720 would find:

# %%
K_crop = scene_camera.K.copy()
K_crop[0, 2] -= 160  # the principal point, in the cropped image's pixels
crop_camera = Camera(
    K_crop, scene_camera.dist, (960, 720), source="the 1280x720 camera, cropped to the middle 960 columns"
)
err_crop_fixed = report("4:3 crop, camera of the 4:3 mode", crop, crop_camera)
assert err_crop_fixed < 5

# %% [markdown]
# ## 9. Is the calibration good enough? Why RMS is not enough
#
# The RMS says how well the board points fit the model **on the photos you took**. It does not say whether the
# model is right: section 8 showed a wrong K behind a tiny reprojection error. Ask a calibration another
# question: *if I calibrated again with new photos of the same kind, how far would the pixel of a point move?*
# That is the **reprojection uncertainty**. As mrcal does, it is computed from the covariance of the fitted
# intrinsics (how the corner noise spreads into fx, fy, cx, cy and the distortion, with every view's board pose
# unknown too), carried to the pixels all over the picture. What a small turn of the camera would absorb is
# left out: a principal point one pixel off moves every pixel alike, and a pose found with that camera simply
# turns by as much.
#
# `fidlearn.planning.coach_calibration` computes this map for a `Calibration`, says in words what is wrong with
# the set of photos, and which photo to take next (`fidlearn calibrate ... --report report.png` prints and
# draws the same). The 20 bundled views first:

# %%
coached = coach_calibration(cal)
print(coached.report())
print(f"fx = {cal.camera.fx:.2f} ± {coached.fx_std_px:.2f} px; the true fx is {true_camera.fx:.2f} px")
assert not coached.flags and coached.good_fraction > 0.99
assert abs(cal.camera.fx - true_camera.fx) < 3 * coached.fx_std_px
display(coach_figure(coached, cal.camera))

# %% [markdown]
# Under 0.3 px everywhere and no warning: these 20 views are enough. The uncertainty is largest toward the
# picture's corners, farthest from most board points.
#
# ### A bad subset: the same photos, one part of the picture
#
# Keep only the views whose board stays in the left half of the picture, and calibrate again:

# %%
left_views = [v for v in cal.used if cal.image_points_px[v][:, 0].max() < true_camera.width / 2]
cal_left = calibrate_checkerboard(left_views, pattern, square_size_mm)
coached_left = coach_calibration(cal_left)
for label, c, k in (("all 20 views", cal, coached), (f"the {len(left_views)} left views", cal_left, coached_left)):
    fx_error_pct = 100 * (c.camera.fx / true_camera.fx - 1)
    print(
        f"{label:17s}: RMS {c.rms_px:.3f} px, fx {c.camera.fx:.2f} px ({fx_error_pct:+.2f} % from the truth), "
        f"worst uncertainty {k.uncertainty_px.max():.2f} px"
    )
print(coached_left.report())
assert abs(cal_left.rms_px - cal.rms_px) < 0.005  # the RMS does not see it
assert abs(cal_left.camera.fx / true_camera.fx - 1) > 5 * abs(cal.camera.fx / true_camera.fx - 1)
assert any("right" in f for f in coached_left.flags) and any("views" in f for f in coached_left.flags)

fig, axes = plt.subplots(1, 2, figsize=(12, 4), layout="constrained")
for ax, (label, c, k) in zip(axes, (("all 20 views", cal, coached), ("the left views only", cal_left, coached_left))):
    im = ax.imshow(
        k.uncertainty_px,
        extent=[-0.5, true_camera.width - 0.5, true_camera.height - 0.5, -0.5],
        cmap="magma_r",
        vmin=0,
        vmax=0.3,
    )
    points = np.vstack(list(c.image_points_px.values()))
    ax.plot(points[:, 0], points[:, 1], ".", color="tab:cyan", markersize=1.5)
    ax.set_title(f"{label}: RMS {c.rms_px:.3f} px, fx {100 * (c.camera.fx / true_camera.fx - 1):+.2f} %", fontsize=10)
    ax.set_xlabel("u (px)")
axes[0].set_ylabel("v (px)")
fig.colorbar(im, ax=list(axes), label="reprojection uncertainty (px)")
fig.suptitle("the coach's map (dots: every board corner used)")
plt.show()

# %% [markdown]
# The RMS is the same; the focal length is several times further from the truth (0.10 % against 0.01 %), the
# uncertainty has more than doubled, most on the right, and the coach says why in words: too few views, and
# nothing on the right side of the picture. The map stays under 0.3 px because the lens model is symmetric about
# the picture's centre (the left side tells it about the right) and because these renders have very clean
# corners (0.045 px). A real lens need not be symmetric, which is why the coach warns about coverage whatever
# the map says; and real corners are noisier.
#
# ### Same RMS, another camera: sets with the noise of good real photos
#
# For the calibration a photo of the board is its 54 corner pixels. So we can simulate photos without rendering
# them: place the board (a pose `T_camera_board`), project its corners with the true camera, add 0.1 px of
# noise per axis (an RMS near 0.14 px: careful photos of a well-printed board). Three kinds of set:
#
# * **spread and tilted**: 20 photos, the board visiting each ninth of the picture in turn, tilted 10 to 40
#   degrees;
# * **face-on**: 20 photos all over the picture, but the board always square to the camera's axis (tilted less
#   than 3 degrees);
# * **only 6 photos**, spread and tilted.
#
# Each set is taken five times (new poses, new noise), as five people following the same advice would: how far
# apart are their cameras, and did the coach predict it?

# %%
board = board_mm.astype(float)  # the 54 corners on the board, (54, 3) mm
noise_px = 0.1
cv2.setNumThreads(1)  # calibrateCamera's threads add up in a varying order: one thread repeats to the last digit


def corner_pixels(T_camera_board, rng=None):
    """The board's corners seen by the true camera from T_camera_board (54, 2) px, with noise if rng is given."""
    rvec, tvec = frames.rvec_tvec_from_transform(T_camera_board)
    px = cv2.projectPoints(board, rvec, tvec, true_camera.K, true_camera.dist)[0].reshape(-1, 2)
    return px if rng is None else px + rng.normal(0.0, noise_px, px.shape)


def board_pose(rng, u=(0.1, 0.9), v=(0.1, 0.9), tilt_deg=(0.0, 40.0)):
    """A random T_camera_board with every corner in the picture: the board's centre on the ray through a pixel
    drawn in the fractions u, v of the picture, 400 to 800 mm away, tilted about a random axis of the image plane."""
    while True:
        pixel = np.array([[[rng.uniform(*u) * true_camera.width, rng.uniform(*v) * true_camera.height]]])
        ray = cv2.undistortPoints(pixel, true_camera.K, true_camera.dist).reshape(2)
        centre = np.array([ray[0], ray[1], 1.0]) * rng.uniform(400, 800)
        a = rng.uniform(0, 2 * np.pi)
        R = cv2.Rodrigues(np.array([np.cos(a), np.sin(a), 0.0]) * np.radians(rng.uniform(*tilt_deg)))[0]
        T = frames.make_transform(R, centre - R @ board.mean(axis=0))
        px = corner_pixels(T)
        if np.all(px >= 0) and np.all(px <= [true_camera.width - 1, true_camera.height - 1]):
            return T


def calibrate_and_coach(photos):
    """cv2.calibrateCamera on corner lists, then the coach on the result: (RMS px, Camera, CalibrationCoach)."""
    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(
        [board_mm] * len(photos), [p.astype(np.float32) for p in photos], true_camera.image_size, None, None
    )
    camera = Camera(K, dist.ravel(), true_camera.image_size)
    names = [f"photo {i}" for i in range(len(photos))]
    T = {n: frames.transform_from_rvec_tvec(r, t) for n, r, t in zip(names, rvecs, tvecs)}
    # the coach wants the corner noise per axis; OpenCV's RMS is over both axes at once
    verdict = coach(camera, dict.fromkeys(names, board), dict(zip(names, photos)), T, corner_sigma_px=rms / np.sqrt(2))
    return rms, camera, verdict


rng = np.random.default_rng(2)
thirds = ((0.05, 0.35), (0.35, 0.65), (0.65, 0.95))
ninths = [(u, v) for v in thirds for u in thirds]  # (u range, v range) of each ninth of the picture, row by row
make_set = {
    "spread and tilted": lambda: [board_pose(rng, *ninths[k % 9], tilt_deg=(10, 40)) for k in range(20)],
    "face-on": lambda: [board_pose(rng, tilt_deg=(0, 3)) for _ in range(20)],
    "only 6 photos": lambda: [board_pose(rng, *ninths[k], tilt_deg=(10, 40)) for k in (0, 2, 4, 6, 8, 1)],
}
results = {}  # per set, per repetition: (RMS px, fx error %, the coach's fx std %, the coach's verdict)
for name, make in make_set.items():
    results[name] = []
    for _ in range(5):
        rms, camera, verdict = calibrate_and_coach([corner_pixels(T, rng) for T in make()])
        results[name].append(
            (rms, 100 * (camera.fx / true_camera.fx - 1), 100 * verdict.fx_std_px / true_camera.fx, verdict)
        )
    rms, fx_err, fx_std, verdicts = zip(*results[name])
    print(
        f"{name}: RMS {min(rms):.3f} to {max(rms):.3f} px; fx from {min(fx_err):+.2f} % to {max(fx_err):+.2f} % "
        f"of the truth, the coach's std {np.median(fx_std):.2f} %; uncertainty median "
        f"{np.median([v.uncertainty_px for v in verdicts]):.2f} px"
    )
    for flag in verdicts[0].flags:
        print("   warning:", flag)

rms_median = [np.median([r[0] for r in rows]) for rows in results.values()]
spread = {name: np.ptp([r[1] for r in rows]) for name, rows in results.items()}
assert max(rms_median) - min(rms_median) < 0.02  # the same RMS, every kind of set
assert spread["face-on"] > 50 * spread["spread and tilted"]  # not the same cameras at all
well_posed = results["spread and tilted"] + results["only 6 photos"]
assert all(abs(r[1]) < 3 * r[2] for r in well_posed)  # within the coach's 3 std, every one
# face-on, fx is not determined at all: the coach says so with a std of several per cent (the fit may even
# stop in a far-off minimum: OpenCV 4.x takes one of these five sets to an fx 2.5 times too long)
assert all(r[2] > 5 for r in results["face-on"])
assert all(not r[3].flags for r in results["spread and tilted"])
assert all(any("face-on" in f for f in r[3].flags) for r in results["face-on"])
assert all(any("views" in f for f in r[3].flags) for r in results["only 6 photos"])

fig, axes = plt.subplots(1, 3, figsize=(13, 3.6), layout="constrained")
for ax, (name, rows) in zip(axes, results.items()):
    fx_err = [r[1] for r in rows]
    two_std = 2 * np.median([r[2] for r in rows])
    ax.axhspan(-two_std, two_std, color="tab:blue", alpha=0.2, label="the coach: ±2 std")
    ax.plot(range(1, 6), fx_err, "o", color="tab:red", label="each calibration")
    ax.axhline(0, color="0.3", lw=1)
    ax.set_xticks(range(1, 6))
    ax.set_xlabel("repetition")
    ax.set_title(f"{name}: RMS {min(r[0] for r in rows):.2f} to {max(r[0] for r in rows):.2f} px", fontsize=10)
axes[0].set_ylabel("fx error against the truth (%)")
axes[0].legend(loc="lower left", fontsize=8)
fig.suptitle("five calibrations of each kind: the RMS is the same, the camera is not (mind each panel's scale)")
plt.show()

# %% [markdown]
# Every calibration here has an RMS of 0.13 to 0.14 px; by the RMS they are all equally good. But the
# face-on sets give focal lengths about 20 % off, either way: seen square on, a board twice as far with twice
# the focal length makes the same picture, so nothing in the photos fixes fx (tilted views break the tie, their
# near and far edges shrinking differently). Six photos fit with a small RMS too, and the coach expects twice
# the scatter of twenty (a standard deviation of 0.26 % against 0.13 %). The coach predicted each scatter (the
# blue band) from one set of photos alone, and said what was wrong in words.
#
# ### Following the coach's advice against random photos
#
# Start from 4 random photos; calibrate, and take one more, either **where the coach says** (its
# `next_view`: a place in the picture and a tilt) or **at random** (anywhere in the picture, tilted up to 40
# degrees, 40 to 80 cm away, as a person waving a board would). Stop when fx is within 0.1 % of the truth and
# the coach's map is under 0.3 px over 90 % of the picture. Four runs of each, each pair from the same first 4
# photos:


# %%
def photos_needed(strategy, seed, most=30):
    """Calibrate, ask the coach, take one more photo, until fx is within 0.1 % of the truth and the map is under
    0.3 px over 90 % of the picture (or `most` photos). Start from 4 random photos; each next one where the coach
    says ("coach") or at random ("random"). Returns the history, [(photos, |fx error| %, fraction under 0.3 px)],
    and the coach's requests in words."""
    rng = np.random.default_rng(seed)
    photos = [corner_pixels(board_pose(rng), rng) for _ in range(4)]
    history, asked = [], []
    while True:
        rms, camera, verdict = calibrate_and_coach(photos)
        history.append((len(photos), 100 * abs(camera.fx / true_camera.fx - 1), verdict.good_fraction))
        if (history[-1][1] < 0.1 and verdict.good_fraction >= 0.9) or len(photos) == most:
            return history, asked
        if strategy == "coach":
            T = verdict.next_view.T_camera_board  # the board where the coach says (a person puts it about there)
            asked.append(
                f"{verdict.next_view.where}, {verdict.next_view.tilt}, {verdict.next_view.distance_mm:.0f} mm away"
            )
        else:
            T = board_pose(rng)
        taken[strategy].append(T)
        photos.append(corner_pixels(T, rng))


def tilt_and_distance(T_camera_board):
    """The board's tilt from square-on (degrees) and its centre's distance from the camera (mm)."""
    tilt_deg = np.degrees(np.arccos(abs(T_camera_board[2, 2])))  # the board's normal against the optical axis
    return tilt_deg, np.linalg.norm(frames.transform_points(T_camera_board, board.mean(axis=0, keepdims=True)))


taken = {"coach": [], "random": []}  # every photo taken after the first 4, per strategy: T_camera_board


runs = {(strategy, seed): photos_needed(strategy, seed) for seed in range(4) for strategy in ("coach", "random")}
histories = {key: history for key, (history, asked) in runs.items()}
needed = {s: [histories[s, seed][-1][0] for seed in range(4)] for s in ("coach", "random")}
for s, n in needed.items():
    print(f"{s:6s}: photos needed {n} (30: the goal not reached), median {np.median(n):.1f}")
for s in ("coach", "random"):
    tilt, distance = np.array([tilt_and_distance(T) for T in taken[s]]).T
    print(
        f"{s:6s}: the photos it took are tilted {np.mean(tilt):.0f} deg on average, {np.median(distance):.0f} mm away "
        f"(median), {100 * np.mean(distance < 500):.0f} % of them under half a metre"
    )
print("what the coach asked for in the second run:")
for k, request in enumerate(runs["coach", 1][1], start=5):
    print(f"  photo {k}: the board {request}")
assert np.median(needed["coach"]) <= 0.7 * np.median(needed["random"])  # at least 30 % fewer photos

fig, axes = plt.subplots(1, 2, figsize=(12, 4), layout="constrained")
for (strategy, seed), history in histories.items():
    n, fx_err, good = np.array(history).T
    color = "tab:blue" if strategy == "coach" else "tab:orange"
    label = ("the coach's next photo" if strategy == "coach" else "a random next photo") if seed == 0 else None
    axes[0].semilogy(n, fx_err, "-", color=color, alpha=0.8, label=label)
    axes[1].plot(n, 100 * good, "-", color=color, alpha=0.8, label=label)
axes[0].axhline(0.1, color="0.4", ls="--", lw=1)
axes[0].set_ylabel("fx error against the truth (%)")
axes[1].axhline(90, color="0.4", ls="--", lw=1)
axes[1].set_ylabel("picture under 0.3 px of uncertainty (%)")
for ax in axes:
    ax.set_xlabel("photos taken")
    ax.legend(loc="best")
fig.suptitle("four runs of each; dashed: the goal")
plt.show()

# %% [markdown]
# The coach's photos reach the goal in about 10 photos; random ones need about three times as many, or never
# get there within 30. The coach asks for what the set lacks: the board tilted strongly one way, then another
# way not yet seen, and close to the camera (mostly under half a metre), so it fills most of the picture; random
# photos are tilted less and further away (the tilts and distances are printed above). The benchmark
# (`benchmarks/bench_planning.py`) runs the same race with more seeds. With your own camera:
# `fidlearn calibrate photos/*.jpg --pattern 9x6 --square-mm 25 -o camera.json --report report.png`, then take
# the photo it names, and calibrate again.

# %% [markdown]
# ## 10. How many photos? Calibration error against the number of views
#
# The seed's advice was "at least 14, about 25 photos". Why? Take board photos as a careful person would
# (`synthetic.render_calibration_views`: the board visits every part of the picture, tilted 10 to 45 degrees)
# with the true camera of `data/calibration`, give their corners 0.1 px of noise as in section 9, and calibrate
# with the first 5, 8, 12, ... 30 of them. Then use each calibrated camera as you would: to find the board's
# pose in **10 new photos** (`cv2.solvePnP` on their exact corners), and measure how far the camera's position
# is from the truth. Three sets of 40 photos (three seeds); the RMS of each calibration is printed too:

# %%
view_counts = [5, 8, 12, 16, 20, 25, 30]
board_points = board_mm.astype(np.float32)
count_results = {n: [] for n in view_counts}  # per number of views, per seed: (RMS px, |fx error| %, position mm)
for seed in range(3):
    rendered = synthetic.render_calibration_views(true_camera, n_views=40, seed=seed, supersample=1)
    assert np.allclose(rendered.object_points, board_points)  # the same board, corners in the same order
    rng = np.random.default_rng(seed)
    noisy = [(p + rng.normal(0.0, noise_px, p.shape)).astype(np.float32) for p in rendered.image_points[:30]]
    for n in view_counts:
        rms, K_n, dist_n, _, _ = cv2.calibrateCamera([board_points] * n, noisy[:n], true_camera.image_size, None, None)
        position_err = []
        for px, T_true in zip(rendered.image_points[30:], rendered.T_world_camera[30:]):  # the 10 new photos
            ok, r, t = cv2.solvePnP(board_points, px, K_n, dist_n)
            r, t = cv2.solvePnPRefineLM(board_points, px, K_n, dist_n, r, t)
            position = -cv2.Rodrigues(r)[0].T @ t.ravel()  # the camera in the board's frame (notebook 07)
            position_err.append(np.linalg.norm(position - T_true[:3, 3]))
        count_results[n].append(
            (rms, 100 * abs(K_n[0, 0] / true_camera.fx - 1), np.sqrt(np.mean(np.square(position_err))))
        )

print("views   calibration RMS (px)   |fx error| (%)   camera position error in new photos (mm RMS; each seed)")
for n in view_counts:
    rms, fx_err, pos_err = np.array(count_results[n]).T
    print(
        f"{n:5d} {np.median(rms):16.3f} {np.median(fx_err):18.3f} {np.median(pos_err):16.2f}      "
        f"{np.round(pos_err, 2)}"
    )
position_median = {n: np.median([r[2] for r in count_results[n]]) for n in view_counts}
assert position_median[5] > 2 * position_median[25]  # few views: a worse camera...
assert np.ptp([r[0] for n in view_counts for r in count_results[n]]) < 0.02  # ...with the same RMS

fig, ax = plt.subplots(figsize=(7, 3.5))
for seed in range(3):
    ax.plot(view_counts, [count_results[n][seed][2] for n in view_counts], "o-", alpha=0.7, label=f"seed {seed}")
ax.axvspan(14, 25, color="tab:green", alpha=0.1, label="the seed's advice: 14 to 25 photos")
ax.set_ylim(bottom=0)
ax.set_xlabel("photos used for the calibration")
ax.set_ylabel("camera position error (mm RMS)")
ax.legend(fontsize=8)
ax.set_title("what the calibration costs the pose, against the number of views")
fig.tight_layout()
plt.show()

# %% [markdown]
# Every calibration has the same RMS, a little under 0.14 px: the RMS cannot tell you that you took too few
# photos. The poses can: with 5 photos the camera found in new photos is several times further from the truth
# than with 25 (the table above), and after about 20 to 25 more photos change little. Each photo must also add
# something new (section 9: photos that repeat each other do not count), which is why the seed asked for about
# 25 and the coach asks for particular ones.
#
# ## Try it
#
# **Predict first**: calibrated from only 3 photos, or from 6, will fx be within 1 % of the truth? Within
# 0.1 %? Will the RMS warn you? Then change `N_VIEWS` (3 to 30) and run.

# %%
N_VIEWS = 6  # try 3, 10, 30

rendered = synthetic.render_calibration_views(true_camera, n_views=N_VIEWS, seed=0, supersample=1)
rng = np.random.default_rng(0)
noisy = [(p + rng.normal(0.0, noise_px, p.shape)).astype(np.float32) for p in rendered.image_points]
rms, K_n, dist_n, _, _ = cv2.calibrateCamera([board_points] * N_VIEWS, noisy, true_camera.image_size, None, None)
print(
    f"{N_VIEWS} views: RMS {rms:.3f} px, fx {K_n[0, 0]:.1f} px against the true {true_camera.fx:.1f} "
    f"({100 * (K_n[0, 0] / true_camera.fx - 1):+.2f} %), k1 {dist_n.ravel()[0]:+.3f} against {true_camera.dist[0]:+.3f}"
)

# %% [markdown]
# ## Summary
#
# * Photos of a flat board of known geometry give K and the distortion: `cv2.findChessboardCorners` +
#   `cornerSubPix`, then `cv2.calibrateCamera` (or `fidlearn.calibrate_checkerboard` /
#   `fidlearn calibrate`), which minimizes the reprojection error.
# * Count **inner** corners; measure the printed square: it scales poses, never K.
# * Read the per-view errors; drop views that are not found, have another size, or stand out.
#   Synthetic views reach 0.05 px; real photos 0.3 to 0.5 px.
# * K belongs to one resolution and one sensor mode. Same aspect ratio: `Camera.scaled`. Another
#   mode or crop: calibrate again. A wrong K hides behind a small reprojection error.
# * The RMS does not tell a good set from a bad one: face-on views, one part of the picture, too few views all
#   fit as well. The reprojection uncertainty does (`coach_calibration`, `fidlearn calibrate --report`): how far
#   a pixel would move with new photos of the same kind. The coach names what the set lacks, and its next
#   photos reach a good calibration with about a third of the photos that random ones need.
# * Few views give a worse camera with the same RMS; the pose error it causes settles after about 20 to 25
#   views of a board that visits the whole picture, tilted (section 10).
#
# **Exercises**: [exercises/02_calibration.ipynb](exercises/02_calibration.ipynb), with automatic
# feedback (or `from fidlearn import exercises; ex = exercises.lesson("02")` in a new cell). Also try:
# calibrate with 5 views, or with the `SB` corner finder, and compare with `camera_true.json`.
#
# Next: [03 Extrinsics and transforms](03_extrinsics_transforms.ipynb).

# %% [markdown]
# ## References
#
# * Z. Zhang, "A flexible new technique for camera calibration", IEEE Transactions on Pattern Analysis and
#   Machine Intelligence 22(11):1330-1334, 2000: the method inside `cv2.calibrateCamera`.
# * OpenCV, "Camera calibration with OpenCV" tutorial: https://docs.opencv.org/4.x/d4/d94/tutorial_camera_calibration.html
#   and `calibrateCamera`, `findChessboardCorners` in https://docs.opencv.org/4.x/d9/d0c/group__calib3d.html
