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

camera = Camera.load(data_path("scenes", "camera.json"))       # step 1: a calibrated camera
world_map = MarkerMap.load(data_path("world_map.json"))          # steps 2-3: where the markers are
image = load_image(data_path("scenes", "scene_00.png"))
pose = locate(image, world_map, camera)                          # steps 4-5: detect, solvePnP, invert

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
