# %% [markdown]
# # 12 Your own camera
#
# **What you will learn**
#
# * how to bring your laptop's camera into the notebook, even when the kernel runs on a server far away;
# * how to calibrate it live: hold a printed checkerboard up, watch the corners found and the picture fill up,
#   capture views, and read the per-view table and the warnings;
# * whether your calibration is good enough: the coach of notebook 02, live, saying which photo to take next;
# * how to print markers and watch your camera's pose, live, in a 3D view of the world (`MarkerTracker`).
#
# On JupyterHub or Binder the camera is on your laptop but Python runs on a server: `cv2.VideoCapture(0)`
# would look for a camera on the server. The `Webcam` widget asks *your browser* for the camera
# (`getUserMedia`) and sends its frames to Python.
#
# **No camera?** Every cell still runs: where a camera is missing the notebook uses the bundled pictures
# (`data/calibration` for the calibration, `data/trajectory` for the live pose).
#
# Run the cells from top to bottom (Shift-Enter).

# %%
# %matplotlib inline
import json
import os
from pathlib import Path

import cv2
import ipywidgets as w
import matplotlib.pyplot as plt
import numpy as np
from IPython.display import display

from fidlearn import (
    Board,
    Camera,
    MarkerMap,
    MarkerTracker,
    board_pdf,
    calibrate_checkerboard,
    data_path,
    locate,
    look_at,
    markers_pdf,
    plotting,
)
from fidlearn.detection import load_image
from fidlearn.errors import FidlearnError, NoMarkersError, PoseError
from fidlearn.planning import coach_calibration
from fidlearn.planning.coach import GOOD_UNCERTAINTY_PX
from fidlearn.planning.figure import coach_figure
from fidlearn.synthetic import render_scene
from fidlearn.widgets import Webcam, figure_png

np.set_printoptions(precision=3, suppress=True)

# %% [markdown]
# ## 1. Is there a camera?
#
# `HAVE_CAMERA` says whether this notebook may use a camera. It is `True` when JupyterLab was started with the
# environment variable `FIDLEARN_WEBCAM=1` (`FIDLEARN_WEBCAM=1 jupyter lab`); **if you have a camera, set it to
# `True` here yourself**. When it is `False` (the automatic checks, or no camera) the camera cells say so and the
# bundled pictures stand in.
#
# Everything the notebook writes goes to `out/my_camera/` next to the `notebooks` folder (git ignores `out/`).

# %%
HAVE_CAMERA = os.environ.get("FIDLEARN_WEBCAM") == "1"
OUT = Path("..", "out", "my_camera")
OUT.mkdir(parents=True, exist_ok=True)
print("camera cells run:", HAVE_CAMERA)

# %% [markdown]
# The widget below shows what your camera sees. The first time, the browser asks whether this page may use
# the camera: allow it. It asks for 640 x 480 pixels (`width`, `height`); a camera that cannot deliver that
# gives the nearest size it can, shown under the picture and kept in `cam.actual_width`, `cam.actual_height`.
# If the camera is refused or missing, the widget says why and what to do (`docs/teaching.md` has more).

# %%
if HAVE_CAMERA:
    cam = Webcam(width=640, height=480, max_fps=5)
    display(cam)
else:
    cam = None
    print("No camera in this run: the notebook uses the bundled pictures.")

# %% [markdown]
# One picture: `await cam.snapshot()` returns a BGR image like `cv2.imread` does. (The `await` lets the
# notebook receive the picture from the browser while the cell waits.)

# %%
if HAVE_CAMERA:
    frame = await cam.snapshot(timeout_s=30)  # noqa: F704 (top-level await: a notebook cell)
    print(f"a {frame.shape[1]} x {frame.shape[0]} picture from the camera (status: {cam.status})")
else:
    frame = load_image(data_path("calibration", "view_00.png"))
    print(f"a {frame.shape[1]} x {frame.shape[0]} bundled picture (data/calibration/view_00.png)")
ax = plotting.show_image(None, frame, title="a snapshot")
plt.show()

# %% [markdown]
# ## 2. Calibrate your camera live
#
# Print `board.pdf` (written below: a 9 x 6 inner-corner checkerboard) at 100 % scale (no "fit to page"),
# measure a square with a ruler and write its side in `SQUARE_MM`. Glue it to something flat.
#
# Then run the next cell and hold the board in front of the camera. Each frame shows the corners it finds
# (coloured lines) and, in red, the cells of the picture no captured view has covered yet. Press **Capture**
# when the board is found (still, sharp, fully in view); move it: near and far, tilted left, right, up and
# down, in every corner of the picture. From the sixth view on, each capture calibrates what you have and the
# coach (notebook 02) says where to put the board next. 15 to 25 views is plenty.

# %%
PATTERN = (9, 6)  # inner corners (columns, rows)
SQUARE_MM = 25.0  # measure your print!
board_pdf(OUT / "board.pdf", Board.checkerboard(PATTERN, SQUARE_MM))
print("printed board:", OUT / "board.pdf")
COVERAGE_CELLS = (8, 6)  # the picture cut into 8 x 6 cells


def find_board(gray, fast=True):
    """The board's inner corners in a gray picture ((N, 2) px), or None."""
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE | (cv2.CALIB_CB_FAST_CHECK if fast else 0)
    found, corners = cv2.findChessboardCorners(gray, PATTERN, flags=flags)
    return corners.reshape(-1, 2) if found else None


def coverage_map(corner_sets, image_size, cells=COVERAGE_CELLS):
    """Which cells of the picture (rows, cols) contain a board corner of some view: bool array."""
    width, height = image_size
    covered = np.zeros((cells[1], cells[0]), bool)
    for corners in corner_sets:
        col = np.clip((corners[:, 0] / width * cells[0]).astype(int), 0, cells[0] - 1)
        row = np.clip((corners[:, 1] / height * cells[1]).astype(int), 0, cells[1] - 1)
        covered[row, col] = True
    return covered


def annotate(frame_bgr, corners, covered):
    """The frame with the uncovered cells tinted red and the board's corners drawn."""
    out = frame_bgr.copy()
    height, width = out.shape[:2]
    tint = np.zeros_like(out)
    rows, cols = covered.shape
    for r, c in zip(*np.nonzero(~covered)):
        y0, y1, x0, x1 = r * height // rows, (r + 1) * height // rows, c * width // cols, (c + 1) * width // cols
        tint[y0:y1, x0:x1] = (0, 0, 160)
    out = cv2.addWeighted(out, 1.0, tint, 0.35, 0)
    if corners is not None:
        cv2.drawChessboardCorners(out, PATTERN, corners.reshape(-1, 1, 2).astype(np.float32), True)
    return out


def jpeg(image_bgr):
    return cv2.imencode(".jpg", image_bgr, [cv2.IMWRITE_JPEG_QUALITY, 85])[1].tobytes()


# %%
captured = []  # (frame, corners) of every view captured
COACH_FROM = 6  # views captured before the coach speaks
if HAVE_CAMERA:
    latest = {"frame": None, "corners": None}
    preview = w.Image(format="jpeg", width=480)
    capture = w.Button(description="Capture", icon="camera", button_style="primary")
    info = w.HTML()

    def show_calibration_frame(frame_bgr):
        gray = cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2GRAY)
        corners = find_board(gray)
        latest.update(frame=frame_bgr, corners=corners)
        covered = coverage_map([c for _, c in captured], (frame_bgr.shape[1], frame_bgr.shape[0]))
        preview.value = jpeg(annotate(frame_bgr, corners, covered))
        info.value = f"{len(captured)} views captured, {covered.mean():.0%} of the picture covered; " + (
            "<b>board found</b>: capture!" if corners is not None else "board not found"
        )

    advice = w.HTML()

    def on_capture(_button):
        if latest["corners"] is None:
            return
        captured.append((latest["frame"], latest["corners"]))
        if len(captured) >= COACH_FROM:
            try:
                views_so_far = [f for f, _ in captured]
                so_far = coach_calibration(calibrate_checkerboard(views_so_far, PATTERN, SQUARE_MM, model="auto"))
                advice.value = "<br>".join(so_far.report().splitlines())
            except FidlearnError as e:  # a set the calibration refuses says why
                advice.value = f"not yet: {e}"

    capture.on_click(on_capture)
    cam.on_frame(show_calibration_frame)
    cam.start()
    display(w.VBox([w.HBox([capture, info]), preview, advice]))
else:
    print("No camera: section 3 calibrates from the bundled views in data/calibration instead.")

# %% [markdown]
# ## 3. Calibrate
#
# When you have captured your views, run the next cell: it stops the live preview and calibrates
# (`calibrate_checkerboard`, notebook 02). It needs at least `MIN_VIEWS` views; with fewer it says so and you
# can capture more (run the cell above again) first. Without a camera the bundled views stand in.
#
# Many webcams have a wide lens, some a fisheye. `model="auto"` fits both OpenCV's pinhole model (k1, k2, p1,
# p2, k3) and the fisheye model (`cv2.fisheye`, k1..k4) and keeps the fisheye only when its RMS reprojection
# error on views **held out** of the fit is at least 10 % below the pinhole's: on the views it was fitted to,
# the model with more freedom would always look better. The camera it returns carries the model it picked, and
# everything after this cell (the coach, `camera.json`, `locate`, `MarkerTracker`) uses that camera.

# %%
MIN_VIEWS = 10
if HAVE_CAMERA:
    cam.stop()
    cam.on_frame(show_calibration_frame, remove=True)
    views = [frame for frame, _ in captured]
    source = "your camera"
else:
    views = [Path(os.path.relpath(p)) for p in sorted(data_path("calibration").glob("view_*.png"))]
    source = "the bundled views (data/calibration)"
calibration = None
if len(views) >= MIN_VIEWS:
    calibration = calibrate_checkerboard(views, PATTERN, SQUARE_MM, model="auto")
    print(f"calibrated from {len(calibration.used)} of {len(views)} views of {source}")
    held_out = ", ".join(f"{m} {e:.2f} px" for m, e in calibration.held_out_rms_px.items())
    print(f"lens model: {calibration.camera.model} (RMS reprojection error on held-out views: {held_out})")
    print(calibration.table())
else:
    print(
        f"{len(views)} views captured from {source}: at least {MIN_VIEWS} are needed. Capture more views in "
        "section 2, then run this cell again."
    )

# %% [markdown]
# ## 4. Is your calibration good enough? Ask the coach
#
# Notebook 02 showed why a low RMS is not enough (a wrong K can hide behind a tiny reprojection error) and taught
# the coach: the **reprojection uncertainty** over the whole picture, what is wrong with the set in words, and
# the photo to take next. Your calibration is good enough when the coach has no warning and the uncertainty is
# under its threshold over nearly all the picture (here: 90 %). Otherwise take the photo it asks for, calibrate
# again, and ask again.

# %%
GOOD_FRACTION = 0.90


def good_enough(coached):
    """The verdict: no warning from the coach, and the uncertainty small over GOOD_FRACTION of the picture."""
    return not coached.flags and coached.good_fraction >= GOOD_FRACTION


print(f"good enough: no warning, under {GOOD_UNCERTAINTY_PX} px over {GOOD_FRACTION:.0%} of the picture")

if calibration is not None:
    coached = coach_calibration(calibration)
    print(coached.report())
    print(
        "Good enough: use this camera.json."
        if good_enough(coached)
        else "Not good enough yet: fix what the coach says, take the photo it asks for, and calibrate again."
    )
    display(coach_figure(coached, calibration.camera))

# %% [markdown]
# For comparison, the same judge on a careful set of real photos: OpenCV's 13 photos of a 9 x 6 board
# (`data/real/opencv_checkerboard_right`, notebook 02).

# %%
real_views = [
    Path(os.path.relpath(p)) for p in sorted(data_path("real", "opencv_checkerboard_right").glob("right*.jpg"))
]
reference = calibrate_checkerboard(real_views, PATTERN, 25.0)
reference_coached = coach_calibration(reference)
print(f"real photos: {len(reference.used)} views, RMS {reference.rms_px:.2f} px")
print(reference_coached.report())
print("good enough" if good_enough(reference_coached) else "not good enough yet")

# %% [markdown]
# {{ 100 * reference_coached.good_fraction:.0f }} % of that picture is under {{ GOOD_UNCERTAINTY_PX }} px of
# uncertainty, with {{ len(reference_coached.flags) }} warning(s) from the coach. The RMS alone
# ({{ reference.rms_px:.2f }} px) would not tell you either way.

# %% [markdown]
# Save it: `camera.json` records K, the distortion and the picture's size the camera delivered (the size you
# asked for may differ, see section 1). Without a camera the bundled views' calibration is saved under another
# name, so it is never mistaken for yours.

# %%
CAMERA_JSON = OUT / ("camera.json" if HAVE_CAMERA else "bundled_calibration.json")
if calibration is not None:
    calibration.camera.save(CAMERA_JSON)
    saved = json.loads(CAMERA_JSON.read_text())
    print(f"wrote {CAMERA_JSON}: image size {saved['image_size']}")
    if HAVE_CAMERA:
        assert saved["image_size"] == [cam.actual_width, cam.actual_height]

# %% [markdown]
# ## 5. Print the markers
#
# The seed's world (`data/world_map.json`) has three 80 mm markers on a wall. `markers_pdf` lays them out at
# their exact size (print at 100 %); tape them to a wall as the map says, or write a map of where you put them
# (notebook 04). The same from a terminal: `fidlearn markers --ids 0-2 --size-mm 80 -o markers.pdf`.

# %%
world_map = MarkerMap.load(data_path("world_map.json"))
sheet = markers_pdf(OUT / "markers.pdf", world_map.ids, world_map.marker_size_mm, dictionary=world_map.dictionary)
print(f"wrote {OUT / 'markers.pdf'}: markers {world_map.ids}, {world_map.marker_size_mm:g} mm, {world_map.dictionary}")

# %% [markdown]
# ## 6. Where is your camera? Live
#
# Point the camera at the markers and move it. Each frame goes through `MarkerTracker`: the pipeline of
# notebooks 05-07 (detection, `estimate_pose`, the inversion), frame after frame. What it adds for a live camera
# is speed: it looks for each marker only near where the last frame saw it (a window around its predicted
# corners), with a full-frame detection every 30 frames (about once a second) to find markers that come into
# view. It does not smooth the pose over time; that is `PoseTracker`'s job (notebook 10). The pose is printed
# and the 3D view shows the world, the markers and the camera. **ambiguous** means two poses explain the
# picture almost equally well (one marker, seen nearly face on, notebook 08): move so that two markers are in
# view, or look at the marker at an angle.
#
# With a camera, the pose uses your `camera.json` from section 3 (or one you made before with
# `fidlearn calibrate` and saved there). Without a camera, the bundled drive `data/trajectory` plays the part,
# with its own camera.

# %%
live_log = []  # the last frames' (gray frame, pose or None), for a look afterwards
if HAVE_CAMERA:  # the camera section 3 calibrated (the lens model it picked), else the one saved before
    camera = calibration.camera if calibration is not None else Camera.load(OUT / "camera.json")
else:
    camera = Camera.load(data_path("trajectory", "camera.json"))
tracker = MarkerTracker(world_map, camera)
pose_text = w.HTML()
scene_view = w.Image(format="png", width=520)


def show_pose(frame_bgr):
    try:
        pose, why = tracker.locate(frame_bgr), ""
    except (NoMarkersError, PoseError) as e:  # a frame without a pose raises, as fidlearn.locate does
        pose, why = None, "no marker of the map in view" if isinstance(e, NoMarkersError) else "no pose in this frame"
    live_log.append((cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2GRAY) if frame_bgr.ndim == 3 else frame_bgr, pose))
    del live_log[:-60]
    if pose is None:
        pose_text.value = why
        return
    x, y, z = pose.position_mm
    flag = " <b style='color:#c00'>ambiguous</b>" if pose.ambiguous else ""
    pose_text.value = (
        f"camera at x {x:.0f}, y {y:.0f}, z {z:.0f} mm; roll/pitch/yaw {np.round(pose.rpy_deg, 1)} deg; "
        f"markers {list(pose.marker_ids)}, RMS {pose.reprojection_rms_px:.2f} px{flag}"
    )
    fig = plotting.plot_scene(world_map, [pose], camera=camera, title="world, markers and your camera")
    scene_view.value = figure_png(fig, dpi=60)
    plt.close(fig)


if HAVE_CAMERA:
    stop = w.Button(description="Stop the camera", icon="stop")
    stop.on_click(lambda _button: cam.stop())
    cam.on_frame(show_pose)
    cam.start()
    display(w.VBox([stop, pose_text, scene_view]))
else:
    drive = json.loads(data_path("trajectory", "poses.json").read_text())
    for k in (0, 20, 39):
        show_pose(load_image(data_path("trajectory", drive["frames"][k]["image"])))
        error_mm = np.linalg.norm(live_log[-1][1].position_mm - np.array(drive["frames"][k]["T_world_camera"])[:3, 3])
        print(f"frame {k}: {pose_text.value}; {error_mm:.1f} mm from the truth")
    display(w.VBox([pose_text, scene_view]))

# %% [markdown]
# What the windows save, on the bundled drive's 40 frames: how many frames needed a full-frame detection, and
# whether the poses are the ones `fidlearn.locate` finds on each whole frame.

# %%
drive = json.loads(data_path("trajectory", "poses.json").read_text())
drive_camera = Camera.load(data_path("trajectory", "camera.json"))
replay = MarkerTracker(world_map, drive_camera)
gap_mm = []
for f in drive["frames"]:
    image = load_image(data_path("trajectory", f["image"]))
    gap_mm.append(np.linalg.norm(replay.locate(image).position_mm - locate(image, world_map, drive_camera).position_mm))
print(
    f"{replay.frames} frames, {replay.full_detections} full-frame detections; windowed and whole-frame poses differ "
    f"by at most {max(gap_mm):.2f} mm"
)

# %% [markdown]
# ### A fisheye webcam, without one
#
# The same two steps with a fisheye lens: `model="auto"` on six photos of a 180-degree lens
# (`data/real/fisheye_checkerboard/mono`, a 6 x 8 board), then a picture of the three markers drawn through the
# camera it returned (`render_scene`, at a known pose) and located with that camera. The fisheye camera goes
# into `locate` (and `MarkerTracker`) as it is: the corners are undistorted exactly through its own model.

# %%
fisheye_views = [
    Path(os.path.relpath(p)) for p in sorted(data_path("real", "fisheye_checkerboard", "mono").glob("*.png"))
]
fisheye_calibration = calibrate_checkerboard(fisheye_views, (6, 8), 25.0, model="auto")
fisheye = fisheye_calibration.camera
held_out = ", ".join(f"{m} {e:.2f} px" for m, e in fisheye_calibration.held_out_rms_px.items())
print(f"{len(fisheye_views)} photos of a 180-degree lens: lens model {fisheye.model} (held-out RMS: {held_out})")
T_true = look_at([400.0, 150.0, 270.0], [0.0, 150.0, 270.0], roll_deg=10.0)
fisheye_scene = render_scene(world_map, fisheye, T_true, seed=0, blur_px=0.5, noise_std_gray=1.0)
fisheye_pose = locate(fisheye_scene.image, world_map, fisheye)
print(
    f"markers {list(fisheye_pose.marker_ids)}: the camera {fisheye_pose.position_mm.round(1)} mm, truth "
    f"{T_true[:3, 3]} mm, {np.linalg.norm(fisheye_pose.position_mm - T_true[:3, 3]):.2f} mm off "
    f"(predicted standard deviations {fisheye_pose.position_std_mm.round(2)} mm)"
)

# %% [markdown]
# The held-out error picked the fisheye ({{ fisheye_calibration.held_out_rms_px["fisheye"]:.2f }} px against the
# pinhole's {{ fisheye_calibration.held_out_rms_px["pinhole"]:.2f }} px); for the bundled views of section 3 it kept
# the pinhole. Your webcam's calibration says which it is in section 3's output.

# %% [markdown]
# Press **Stop the camera** when you are done (the browser's camera light goes out when you close the
# notebook). `cam.frames_received` counts the frames Python handled, and `cam.pacer.measured_fps` their rate:
# never more than `max_fps`, and less when the pose and the drawing take longer than a frame's time.
#
# ## What you have learnt
#
# * The camera is the browser's, not the server's: the widget carries its frames to Python, one at a time, no
#   faster than Python keeps up with.
# * A calibration is as good as its views: enough of them, over the whole picture, tilted, sharp. The coach
#   judges the set by its uncertainty over the picture, not by the RMS, and says which photo to take next.
# * `model="auto"` picks the lens model (pinhole or fisheye) by the error on views held out of the fit; the camera
#   it returns goes into the coach, `camera.json`, `locate` and `MarkerTracker` as it is.
# * `MarkerTracker` runs the pipeline frame after frame, searching only where the markers were.
# * With a calibrated camera and printed markers, the pose is a few lines (notebooks 05-09), live.

# %% [markdown]
# ## Try it (no camera needed)
#
# * The cell below calibrates from only the first `N_VIEWS` bundled views and asks the coach. With 6 views,
#   what does it flag, and where does it want the next photo? Raise `N_VIEWS` until it is good enough: how many
#   views did it take?
# * Set `full_every=1` in the `MarkerTracker(...)` of the drive above (a full detection on every frame): do the
#   poses change?

# %%
N_VIEWS = 6
bundled = [Path(os.path.relpath(p)) for p in sorted(data_path("calibration").glob("view_*.png"))]
few = coach_calibration(calibrate_checkerboard(bundled[:N_VIEWS], PATTERN, 25.0))
print(few.report())
print("good enough" if good_enough(few) else "not good enough yet")

# %% [markdown]
# **Exercises**: [exercises/12_own_camera.ipynb](exercises/12_own_camera.ipynb), with automatic feedback (or
# `from fidlearn import exercises; ex = exercises.lesson("12")` in a new cell): they run on the bundled pictures.

# %% [markdown]
# ## References
#
# * Z. Zhang, "A flexible new technique for camera calibration", IEEE Transactions on Pattern Analysis and
#   Machine Intelligence 22(11), 2000.
# * OpenCV, "Camera calibration with OpenCV": https://docs.opencv.org/4.x/d4/d94/tutorial_camera_calibration.html
# * OpenCV, "Detection of ArUco Markers": https://docs.opencv.org/4.x/d5/dae/tutorial_aruco_detection.html
# * MDN, `MediaDevices.getUserMedia()` (how the browser lends its camera):
#   https://developer.mozilla.org/en-US/docs/Web/API/MediaDevices/getUserMedia
