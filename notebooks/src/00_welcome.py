# %% [markdown]
# # 00 Welcome: where is the camera?
#
# This course teaches **camera localization from printed fiducial markers**: tape a few ArUco markers
# to the walls, write down where they are, take a picture, and compute where the camera stood and
# which way it looked, to a few millimetres.
#
# **What you will learn in this notebook**
#
# * the five steps of the pipeline the course builds, and which notebook teaches each;
# * how to run a notebook, and how to check that your installation works;
# * the conventions (units, frames, names) used everywhere.
#
# ## The pipeline
#
# 1. **Calibrate** the camera: its intrinsics K (focal lengths, principal point) and lens distortion,
#    from photos of a checkerboard (notebooks 01, 02).
# 2. **Map** the world: where each marker is taped, as a small JSON file (notebooks 03, 04).
# 3. **Corners**: turn the map into the 3D position of each marker's four corners, in mm (notebook 04).
# 4. **Detect** the markers in the picture: their ids and pixel corners (notebook 05).
# 5. **Solve PnP, then invert**: `cv2.solvePnP` matches 3D corners to pixels and gives the world as the
#    camera sees it (`T_camera_world`); its inverse is the camera's pose in the world (notebooks 06, 07).
#
# ```
# checkerboard photos --calibrate--> Camera (K, dist)
# world map (JSON)    --corners----> 3D corners, mm                 \
# picture             --detect-----> ids + pixel corners  --solvePnP--> T_camera_world --invert--> T_world_camera
# ```

# %% [markdown]
# ## What you need before you start
#
# * **Python**: functions, loops, lists and dicts, f-strings; reading a traceback.
# * **NumPy**: arrays and their `shape`, indexing and slicing (`a[:3, 3]`), `@` for matrix products,
#   `np.linalg.norm`. The NumPy quickstart (https://numpy.org/doc/stable/user/quickstart.html) covers it.
# * **Maths**: vectors and matrices (product, transpose, dot product), sine, cosine and arctangent, degrees
#   against radians, similar triangles. Rotations and 4 x 4 transforms are taught in notebook 03; chapter 3 of
#   *Modern Robotics* (Lynch and Park, free at http://modernrobotics.org) is the reference if you want more.
# * **OpenCV**: nothing; every call is introduced where it is first used.
# * **For the hands-on parts**: a printer that can print at 100 % ("actual size"), calipers or a steel rule to
#   measure what it printed, a tape measure for the room, stiff card to glue the calibration board on, and a
#   camera (a laptop's or a phone's). Everything else runs on the pictures bundled in `data/`.
#
# ## How to use the notebooks
#
# * Run the cells **from top to bottom**: click a cell and press **Shift-Enter** (run it and move on).
#   The first code cell of every notebook imports what it needs; a later cell may use what an earlier
#   one computed.
# * If something looks odd, restart: *Kernel > Restart Kernel and Run All Cells*.
# * Cells end with `assert` lines that compare a result with its known answer: if one fails, the step
#   above it went wrong (or you changed something: that is allowed, and how you learn).
# * The reusable code (loading, plotting, the pipeline itself) lives in the `fidlearn` package next to
#   these notebooks; the algorithm is always written out in the notebook first.
# * Every notebook ends with a link to its exercises, in `exercises/`: short tasks whose answers
#   `q.check()` marks for you.
#
# ## Is everything installed?
#
# `fidlearn doctor` (also on the command line) checks Python, NumPy, OpenCV (with the `aruco` module)
# and the notebook tools. The versions you see depend on your installation.

# %%
# NBVAL_IGNORE_OUTPUT
from fidlearn import doctor

lines, problems = doctor.report()
for line in lines:
    print(line.split(" (")[0])  # the versions, without the install paths

# %%
for problem in problems:
    print("problem:", problem)
assert problems == [], "fix the problems above (each line says how), then restart the kernel"
print("all good: the installation has everything the course needs")

# %% [markdown]
# ## A taste of the end result
#
# Here is the whole pipeline in four lines, on a picture from `data/scenes/`: three 80 mm markers on a
# wall, seen by a webcam whose true pose is known. By notebook 07 you will have written each step
# yourself.

# %%
# %matplotlib inline
import json

import matplotlib.pyplot as plt
import numpy as np

from fidlearn import Camera, MarkerMap, data_path, locate, plotting
from fidlearn.detection import detect_markers, load_image

np.set_printoptions(precision=3, suppress=True)

camera = Camera.load(data_path("scenes", "camera.json"))  # step 1: a calibrated camera
world_map = MarkerMap.load(data_path("world_map.json"))  # steps 2-3: where the markers are
image = load_image(data_path("scenes", "scene_00.png"))
pose = locate(image, world_map, camera)  # steps 4-5: detect, solvePnP, invert

truth = json.loads(data_path("scenes", "poses.json").read_text())["images"][0]
T_true = np.array(truth["T_world_camera"])
error_mm = np.linalg.norm(pose.position_mm - T_true[:3, 3])
print("markers used            :", pose.marker_ids)
print("camera position (cm)    :", np.round(pose.position_mm / 10).astype(int))
print("true position (cm)      :", np.round(T_true[:3, 3] / 10).astype(int))
assert error_mm < 10, f"the pose is {error_mm:.1f} mm off"

ax = plotting.show_image(None, image, title="scene_00.png: the markers found, with their ids and corners")
plotting.plot_detections(ax, detect_markers(image, world_map.dictionary))
plt.show()

# %% [markdown]
# **Try it.** `data/scenes/` holds ten pictures, `scene_00.png` to `scene_09.png`; scenes 6 to 9 show markers on
# two walls (another map, `two_walls_map.json`, named in `poses.json`). Will the position error be larger when
# the camera stands further from the wall, and how much larger at twice the distance? **Predict first**, then
# change `SCENE`, run, and compare a few scenes (notebook 08 explains what you see).

# %%
SCENE = 3  # 0 to 9

record = json.loads(data_path("scenes", "poses.json").read_text())["images"][SCENE]
scene_map = MarkerMap.load(data_path(record["map"]))
found = locate(load_image(data_path("scenes", record["image"])), scene_map, camera)
true_xyz = np.array(record["T_world_camera"])[:3, 3]
print(
    f"{record['image']}: camera {true_xyz[0] / 1000:.1f} m out from the north wall, markers used "
    f"{found.marker_ids}, position error {np.linalg.norm(found.position_mm - true_xyz):.1f} mm"
)

# %% [markdown]
# And the same in 3D: the wall's markers, and the camera at the pose found (the orange pyramid points
# where the camera looks).

# %%
fig = plotting.plot_scene(world_map, poses=[pose], camera=camera, scale_mm=250, labels=["camera (found)"])
plt.show()

# %% [markdown]
# ## The notebooks
#
# | notebook | what | exercises |
# | --- | --- | --- |
# | [00 Welcome](00_welcome.ipynb) | this page | |
# | [01 The pinhole camera and K](01_pinhole_intrinsics.ipynb) | projection by hand and with OpenCV, field of view, distortion, an interactive view of K | [01](exercises/01_pinhole.ipynb) |
# | [02 Calibration](02_calibration.ipynb) | checkerboards, finding corners, per-view errors, square size, the resolution trap | [02](exercises/02_calibration.ipynb) |
# | [03 Extrinsics and transforms](03_extrinsics_transforms.ipynb) | rotations, 4x4 matrices, Rodrigues vectors, composing frames, Z-up vs Y-up | [03](exercises/03_extrinsics.ipynb) |
# | [04 Fiducials and the world map](04_fiducials_world_map.ipynb) | dictionaries, quiet zone, marker size, map files, units, walls and floors | [04](exercises/04_world_map.ipynb) |
# | [05 Detecting markers](05_detection_winding_order.ipynb) | finding markers and their corners in a picture, the winding order TL, TR, BR, BL | [05](exercises/05_detection.ipynb) |
# | [06 PnP: the pose from several markers](06_pose_solvepnp.ipynb) | matching 3D corners to pixels with `cv2.solvePnP`, reprojection error | [06](exercises/06_pnp.ipynb) |
# | [07 Where is the camera?](07_inverting_the_transform.ipynb) | inverting the extrinsics: the camera's pose in the world | [07](exercises/07_inversion.ipynb) |
# | [08 Accuracy and pitfalls](08_accuracy_pitfalls.ipynb) | ambiguity of planar targets, noise, outliers, how sure the pose is | [08](exercises/08_accuracy.ipynb) |
# | [09 Localizing a robot](09_localizing_a_robot.ipynb) | a moving camera, frame after frame | [09](exercises/09_robot.ipynb) |
# | [10 Tracking over time](10_tracking_over_time.ipynb) | a Kalman filter on the pose, flips undone by continuity, odometry, ROS output | [10](exercises/10_tracking.ipynb) |
# | [11 From localization to mapping](11_from_localization_to_mapping.ipynb) | the map from photos and the tape: bundle adjustment, the gauge, a moved marker found; two photos and no map, the start of monocular SLAM | [11](exercises/11_mapping.ipynb) |
# | [12 Your own camera](12_your_own_camera.ipynb) | your webcam in JupyterLab: calibrate it with the coach, then localize it live | [12](exercises/12_own_camera.ipynb) |
# | [13 The robot's truth](13_robot_truth_hand_eye.ipynb) | real photos judged by an industrial robot: hand-eye calibration, leave-one-out | [13](exercises/13_hand_eye.ipynb) |
# | [14 ChArUco boards](14_charuco_boards.ipynb) | chess corners named by markers: calibration, `refineDetectedMarkers`, the pose judged by the robot | [14](exercises/14_charuco.ipynb) |
# | [15 Wide lenses](15_wide_lenses.ipynb) | fisheye and wide-angle cameras: the fisheye model, undistortion and what it loses, two calibrations cross-validated, a pose at the edge | [15](exercises/15_wide_lenses.ipynb) |
#
# ## Conventions (used in every notebook and in `fidlearn`)
#
# | what | convention |
# | --- | --- |
# | lengths | **millimetres** inside the library; other units only in files that declare them (`"units": "ft"`) |
# | angles | radians inside the maths; degrees only at the edges, in names ending `_deg` |
# | world frame | right-handed, **Z up** (ROS); the seed room's north wall is the YZ plane, X points into the room |
# | camera frame | OpenCV's: x right, y **down**, z forward (out of the lens) |
# | pixels | the centre of the top-left pixel is (0, 0) |
# | transforms | `T_a_b` is frame b's pose in frame a: `p_a = T_a_b @ p_b`; names chain, `T_a_b @ T_b_c = T_a_c` |
# | solvePnP | its `rvec, tvec` are `T_camera_world`; the camera's pose is `T_world_camera`, the inverse |
# | marker corners | always TL, TR, BR, BL (the order ArUco reports); a marker with rotation [0, 0, 0] faces +X |
#
# ## Summary
#
# * The course builds calibrate -> map -> corners -> detect -> solvePnP -> invert, one notebook at a time.
# * Run cells top to bottom with Shift-Enter; the `assert` lines check each step against a known answer.
# * Millimetres, Z up, OpenCV's camera frame, `T_a_b` names, corners TL, TR, BR, BL.
#
# **Exercises** start with notebook 01: [exercises/01_pinhole.ipynb](exercises/01_pinhole.ipynb).
# Next: [01 The pinhole camera](01_pinhole_intrinsics.ipynb).

# %% [markdown]
# ## References
#
# * K. M. Lynch and F. C. Park, *Modern Robotics: Mechanics, Planning, and Control*, Cambridge University Press,
#   2017, chapter 3 (rigid-body motions): http://modernrobotics.org
# * OpenCV, "Detection of ArUco Markers": https://docs.opencv.org/4.x/d5/dae/tutorial_aruco_detection.html
# * OpenCV, "Perspective-n-Point (PnP) pose computation": https://docs.opencv.org/4.x/d5/d1f/calib3d_solvePnP.html
# * T. Collins and A. Bartoli, "Infinitesimal Plane-based Pose Estimation", International Journal of Computer
#   Vision 109(3), 2014.
# * Z. Zhang, "A flexible new technique for camera calibration", IEEE Transactions on Pattern Analysis and
#   Machine Intelligence 22(11), 2000.
