# %% [markdown]
# # 04 Fiducial markers and the world map
#
# **What you will learn**
#
# * what an ArUco marker is, and how dictionaries (ARUCO_ORIGINAL, 4X4_50, 6X6_250, AprilTag) differ;
# * why a marker needs its white **quiet zone**;
# * how big to print a marker for a given distance (pixels per cell), measured;
# * how to write down where markers are: the world map file, its **units** (feet to mm) and rotations
#   for markers on walls and on the floor;
# * how a placement becomes the four 3D corners TL, TR, BR, BL, with `MarkerMap` and by hand;
# * coplanar and non-coplanar maps, and a 3D picture of a room.

# %%
# %matplotlib inline
import json
import math

import cv2
import matplotlib.pyplot as plt
import numpy as np

from fidlearn import Camera, MapError, MarkerMap, data_path, frames, look_at, plotting, render_scene
from fidlearn.detection import detect_markers

np.set_printoptions(precision=3, suppress=True)

# %% [markdown]
# ## 1. Markers and dictionaries
#
# An ArUco marker is a square grid of black and white **cells**: an inner pattern of n x n bits inside a
# black border one cell wide, so (n + 2) x (n + 2) cells in all. A **dictionary** is a list of such
# patterns, chosen far apart from each other so a misread bit is caught; the marker's **id** is its
# position in the list. The detector must be told the dictionary: a marker from another one is not found.
#
# | dictionary | bits | markers | when |
# | --- | --- | --- | --- |
# | `ARUCO_ORIGINAL` | 5x5 | 1024 | the original ArUco set; the seed map uses it |
# | `4X4_50` | 4x4 | 50 | few markers, big cells: readable from furthest away |
# | `6X6_250` | 6x6 | 250 | OpenCV's tutorials, ChArUco boards |
# | `APRILTAG_36h11` | 6x6 | 587 | robust AprilTag family, widely used in robotics |
#
# Fewer, bigger cells are read from further away; more bits give more ids and fewer false detections.

# %%
names = ["ARUCO_ORIGINAL", "4X4_50", "6X6_250", "APRILTAG_36h11"]
dictionaries = {name: cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, "DICT_" + name)) for name in names}
for name, d in dictionaries.items():
    print(f"{name:15s} {d.markerSize}x{d.markerSize} bits, {len(d.bytesList):4d} markers")
assert len(dictionaries["ARUCO_ORIGINAL"].bytesList) == 1024 and dictionaries["ARUCO_ORIGINAL"].markerSize == 5
assert len(dictionaries["4X4_50"].bytesList) == 50 and dictionaries["4X4_50"].markerSize == 4

original = dictionaries["ARUCO_ORIGINAL"]
images = [cv2.aruco.generateImageMarker(d, 0, 140) for d in dictionaries.values()] + [
    cv2.aruco.generateImageMarker(original, i, 140) for i in (1, 2, 3)
]
titles = [f"{name} id 0" for name in names] + [f"ARUCO_ORIGINAL id {i}" for i in (1, 2, 3)]
fig = plotting.show_images([np.pad(im, 20, constant_values=255) for im in images], titles, ncols=7, width_in=14)
plt.show()

# %% [markdown]
# `fidlearn markers --ids 0-9 --size-mm 80 -o markers.pdf` prints markers at their exact physical size.
#
# ## 2. The quiet zone
#
# The detector looks for a dark square outline on a lighter background. Without white paper around the
# black border, the outline merges with whatever dark thing touches it and the marker is lost: a dark
# wall, or just a cable or a door frame against one edge. Keep a white margin of at least one cell
# (more is better) all around, and measure the marker's size on the **black square only**, margin
# excluded.

# %%
marker = cv2.aruco.generateImageMarker(original, 0, 140)  # 7 cells of 20 px
with_margin = np.pad(marker, 40, constant_values=255)  # 2 cells of white all round
cable = with_margin.copy()
cable[60:80, :41] = 0  # a dark cable touching the left edge
cases = {
    "white margin all round": with_margin,
    "no margin, dark wall": np.pad(marker, 40, constant_values=0),
    "dark cable touches an edge": cable,
}
found = {name: [d.id for d in detect_markers(img, "ARUCO_ORIGINAL")] for name, img in cases.items()}
for name, ids in found.items():
    print(f"{name:27s} -> detected ids {ids}")
assert found["white margin all round"] == [0]
assert found["no margin, dark wall"] == [] and found["dark cable touches an edge"] == []

# the same image, read with another dictionary: nothing
assert detect_markers(with_margin, "4X4_50") == []

fig = plotting.show_images(list(cases.values()), [f"{n}: {found[n]}" for n in cases], ncols=3, width_in=10)
plt.show()

# %% [markdown]
# ## 3. How big should a marker be?
#
# A marker of side s mm at distance Z mm is about `fx s / Z` pixels wide (notebook 01), so each of its
# n + 2 cells spans
#
# $$\text{pixels per cell} = \frac{f_x\, s}{Z\,(n + 2)}$$
#
# Let us measure how many pixels per cell detection needs. `render_scene` draws an 80 mm ARUCO_ORIGINAL
# marker seen by a 60 degree, 640 x 480 camera at several distances and angles, with a little blur and
# sensor noise, and tells the true corners; we count the detections and the corner error.

# %%
camera = Camera.from_fov(60, (640, 480))
one = MarkerMap.from_dict({"0": {"translation": [0, -40, 1040], "rotation": [0, 0, 0]}}, units="mm", marker_size_mm=80)
cells = original.markerSize + 2
views = [(0, 1), (25, 2), (-35, 3), (45, 4)]  # (yaw of the view in degrees, noise seed)
distances_mm = [750, 1000, 1500, 2000, 2500, 3000, 3500, 4000, 4500, 5000, 6000, 7000]

rate, error_px, ppc = [], [], []
for Z in distances_mm:
    hits, errors = 0, []
    for yaw_deg, seed in views:
        a = math.radians(yaw_deg)
        T = look_at([Z * math.cos(a), Z * math.sin(a), 1000], [0, 0, 1000])
        scene = render_scene(one, camera, T, blur_px=0.6, noise_std_gray=2.0, seed=seed)
        image, truth = scene.image, scene.truth
        seen = [d for d in detect_markers(image, "ARUCO_ORIGINAL") if d.id == 0]
        if seen:
            hits += 1
            errors.append(np.sqrt(np.mean(np.sum((seen[0].corners_px - truth[0]) ** 2, axis=1))))
    ppc.append(camera.fx * 80 / Z / cells)
    rate.append(hits / len(views))
    error_px.append(np.mean(errors) if errors else np.nan)

ppc, rate, error_px = np.array(ppc), np.array(rate), np.array(error_px)
print("pixels per cell:", ppc.round(1))
print("detected      :", rate.round(2))
assert np.all(rate[ppc >= 2.5] == 1.0)  # always found with 2.5 px per cell or more
assert np.all(rate[ppc < 1.0] == 0.0)  # never with less than 1
assert np.nanmax(error_px[ppc >= 4]) < 0.2  # and accurate corners when cells are big

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 3.5))
ax1.plot(ppc, rate, "o-")
ax1.set_xlabel("pixels per cell")
ax1.set_ylabel("fraction of views detected")
ax2.plot(ppc, error_px, "o-", color="tab:red")
ax2.set_xlabel("pixels per cell")
ax2.set_ylabel("corner error, RMS (px)")
for ax in (ax1, ax2):
    ax.axvline(4, color="0.6", linestyle="--")
    ax.set_xlim(0, 9)
fig.suptitle("80 mm ARUCO_ORIGINAL marker, 60 deg camera, 640 x 480 (synthetic)")
fig.tight_layout()
plt.show()

# %% [markdown]
# Detection survives down to about 2 pixels per cell in these clean synthetic pictures, but the corners
# get worse well before the marker is lost (the few far detections that still succeed are the lucky
# ones, which is why the error curve falls again at the very left). Real photos add motion blur, glare
# and focus. A safe rule: **at least 4 pixels per cell** at the furthest distance you
# need. Then the side to print follows:


# %%
def marker_side_mm(distance_mm, fx_px, cells, px_per_cell=4.0):
    """Black-square side (mm) that gives px_per_cell pixels per cell at distance_mm."""
    return px_per_cell * cells * distance_mm / fx_px


for Z in (1000, 3000, 5000):
    print(
        f"to be read at {Z / 1000:.0f} m by this camera: print ARUCO_ORIGINAL markers at least "
        f"{marker_side_mm(Z, camera.fx, cells):.0f} mm wide"
    )
assert math.isclose(marker_side_mm(1000, camera.fx, 7), 4 * 7 * 1000 / camera.fx)

# %% [markdown]
# ### Print at 100 %, then measure with calipers
#
# The map tells the solver how big a marker is, and the solver turns apparent size into distance. A printer set
# to "fit to page" shrinks the page by a few per cent, and every distance comes out short by the same factor.
# Print at **100 % ("actual size")**, then measure the black square with calipers (or a steel rule) and write
# what you measured in the map's `marker_size_mm`. What a scale error costs, computed: the corners an 80 mm
# marker printed at another scale would give a camera 1.5 m from it, given to `cv2.solvePnP` (notebook 06)
# with the map's 80 mm:


# %%
def marker_square_mm(side_mm):
    """A marker's corners TL, TR, BR, BL in its own frame (mm): the object points of cv2.SOLVEPNP_IPPE_SQUARE."""
    h = side_mm / 2
    return np.array([[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]])


def distance_with_map_size(printed_mm, map_mm=80.0, distance_mm=1500.0):
    """Camera distance (mm) that solvePnP finds from the exact corners of a marker printed at printed_mm, told
    it is map_mm; the camera looks at the marker from distance_mm, a little off its axis."""
    rvec, tvec = np.array([0.3, 0.2, 0.0]), np.array([0.0, 0.0, distance_mm])
    seen_px, _ = cv2.projectPoints(marker_square_mm(printed_mm), rvec, tvec, camera.K, camera.dist)
    ok, r, t = cv2.solvePnP(marker_square_mm(map_mm), seen_px, camera.K, camera.dist, flags=cv2.SOLVEPNP_IPPE_SQUARE)
    return float(np.linalg.norm(t))  # notebook 06: tvec is the marker's centre in the camera frame


print("printed side    scale   distance found (true 1500 mm)   error")
for printed_mm in (80.0, 79.9, 79.2, 77.6):
    found_mm = distance_with_map_size(printed_mm)
    print(
        f"{printed_mm:8.1f} mm {printed_mm / 80:9.3f} {found_mm:17.1f} mm {found_mm - 1500:+22.1f} mm "
        f"({100 * (found_mm / 1500 - 1):+.1f} %)"
    )
assert abs(distance_with_map_size(79.2) - 1500 * 80 / 79.2) < 0.5  # 1 % too small a print: 1 % too far

# %% [markdown]
# ## 4. The world map
#
# The world map says where each marker is. The world frame is right-handed with **Z up**; in the seed
# room the **north wall is the YZ plane**: X comes out of the wall into the room, Y runs along the wall
# (with X pointing south, Y points east). Each marker has
#
# * `"translation"`: the world position of its **top-left corner**, in the map's units;
# * `"rotation"`: `[roll, pitch, yaw]` in degrees about the fixed world X, Y, Z axes, applied about that corner.
#
# With rotation `[0, 0, 0]` a marker hangs on the north wall, facing +X (into the room), and its corners
# are, with s its side:
#
# `TL = translation`, `TR = TL + s Y`, `BR = TL + s Y - s Z`, `BL = TL - s Z`.
#
# Here is the seed's map, `data/world_map.json`: feet, 80 mm markers, three on the north wall.

# %%
print(data_path("world_map.json").read_text())
wall = MarkerMap.load(data_path("world_map.json"))
print(wall)

# %% [markdown]
# ## 5. Units: feet to millimetres
#
# Everything inside fidlearn is in millimetres. The seed's file measures positions in **feet** (1 ft =
# 304.8 mm) and marker sizes in mm. Marker 0 sits at [0, 0, 1] ft, so its top-left corner is at
# 304.8 mm height and its bottom edge 80 mm lower:

# %%
corners = wall.corners()
print("marker 0 corners (mm), TL TR BR BL:\n", corners[0])
assert np.allclose(corners[0], [[0, 0, 304.8], [0, 80, 304.8], [0, 80, 224.8], [0, 0, 224.8]])

# the same by hand: feet to mm for the corner, then the marker's side along +Y and -Z
tl = np.array([0, 0, 1]) * 304.8
s = 80.0
by_hand = np.array([tl, tl + s * np.array([0, 1, 0]), tl + s * np.array([0, 1, -1]), tl + s * np.array([0, 0, -1])])
assert np.allclose(by_hand, corners[0])

# %% [markdown]
# The seed also wrote maps in a **bare** layout, just the markers, with no units and no marker size.
# fidlearn loads it as it is, but it never guesses the units: they must be given.

# %%
bare = {
    "0": {"translation": [0, 0, 1], "rotation": [0, 0, 0]},
    "1": {"translation": [0, 1, 1], "rotation": [0, 0, 0]},
    "2": {"translation": [0, 0.5, 0.75], "rotation": [0, 0, 0]},
}
try:
    MarkerMap.from_dict(bare, marker_size_mm=80)
except MapError as exc:
    print("MapError:", exc)
else:
    raise AssertionError("a map without units must be refused")

bare_map = MarkerMap.from_dict(bare, units="ft", marker_size_mm=80)
assert all(np.allclose(bare_map.corners()[i], corners[i]) for i in wall.ids)

# what `fidlearn corners world_map.json -o corners.json` writes: the corner file, mm
print(json.dumps(wall.corners_dict(), indent=None))

# %% [markdown]
# ## 6. Walls, floor and rotations
#
# A marker elsewhere is the north-wall marker turned about its top-left corner:
# `R = Rz(yaw) @ Ry(pitch) @ Rx(roll)`, and its corners are
#
# $$\text{corner}_k = TL + s\, R\, c_k, \qquad c = \{(0,0,0),\ (0,1,0),\ (0,1,-1),\ (0,0,-1)\}$$
#
# * **south wall** (facing north, -X): yaw 180;
# * **west wall** (the wall at Y = 0, facing +Y): yaw 90; **east wall** (facing -Y): yaw -90;
# * **floor** (facing up, +Z): pitch -90; a ceiling marker (facing down): pitch 90.
#
# TL is always the corner at the marker's top-left **as you look at its printed face**. Here is a
# 4 m x 3 m room with a marker on each wall and one on the floor, 150 mm markers, in mm.

# %%
room_dict = {
    "units": "mm",
    "marker_size_mm": 150,
    "dictionary": "ARUCO_ORIGINAL",
    "markers": {
        "0": {"translation": [0, 1400, 1300], "rotation": [0, 0, 0]},  # north wall, faces +X
        "1": {"translation": [4000, 1600, 1300], "rotation": [0, 0, 180]},  # south wall, faces -X
        "2": {"translation": [2100, 0, 1300], "rotation": [0, 0, 90]},  # west wall (Y = 0), faces +Y
        "3": {"translation": [1900, 3000, 1300], "rotation": [0, 0, -90]},  # east wall (Y = 3000), faces -Y
        "4": {"translation": [2500, 1700, 0], "rotation": [0, -90, 0]},  # floor, faces up
    },
}
room = MarkerMap.from_dict(room_dict)
LOCAL = np.array([[0, 0, 0], [0, 1, 0], [0, 1, -1], [0, 0, -1]], dtype=float)

for mid, placement in room.placements.items():
    R = frames.rotation_from_rpy_deg(*placement.rotation_deg)
    by_hand = np.asarray(placement.translation_mm) + room.marker_size_mm * LOCAL @ R.T
    assert np.allclose(by_hand, room.corners()[mid]), mid
    print(f"marker {mid}: rotation {placement.rotation_deg}, faces {room.normal(mid).round(3) + 0.0}")

assert np.allclose(room.normal(1), [-1, 0, 0]) and np.allclose(room.normal(2), [0, 1, 0])
assert np.allclose(room.normal(3), [0, -1, 0]) and np.allclose(room.normal(4), [0, 0, 1])
# on the south wall, seen from inside the room, TR is to the right of TL: towards -Y
assert np.allclose(room.corners()[1][1] - room.corners()[1][0], [0, -150, 0])

# %% [markdown]
# ## 7. Coplanar or not
#
# The seed's three markers lie in one plane (the wall); the room's do not. It matters for the pose
# (notebook 06): from one plane, OpenCV's planar solvers (IPPE) apply and a single small marker can
# look the same from two different poses (the *ambiguity*, notebook 08); markers on several walls pin
# the pose down much better.

# %%
print(f"seed wall: coplanar {wall.is_coplanar()}, {wall.planarity_mm():.3f} mm off a plane")
print(f"room     : coplanar {room.is_coplanar()}, {room.planarity_mm():.0f} mm off a plane")
assert wall.is_coplanar() and not room.is_coplanar()

# %% [markdown]
# ## 8. The room in 3D, and what a camera sees
#
# The red dot on each marker is its top-left corner. A camera stands in the room's north-west corner,
# 1.6 m up, looking south-east and down; `render_scene` then draws what it sees (with the true corners),
# and the detector finds the markers.

# %%
T_world_camera = look_at([300, 300, 1600], [3000, 2500, 700])
fig = plotting.plot_scene(
    room,
    poses=[T_world_camera],
    camera=camera,
    scale_mm=500,
    room_mm=[[0, 0, 0], [4000, 3000, 2000]],
    azim=-60,
    elev=25,
    title="4 m x 3 m room, 150 mm markers on four walls and the floor",
)
plt.show()

# %%
scene = render_scene(room, camera, T_world_camera, blur_px=0.5, noise_std_gray=1.5, seed=4)
image, truth = scene.image, scene.truth
detections = detect_markers(image, "ARUCO_ORIGINAL")
print("markers in view (truth):", sorted(truth), " detected:", [d.id for d in detections])
assert sorted(truth) == [d.id for d in detections] == [1, 3, 4]
for d in detections:
    assert np.abs(d.corners_px - truth[d.id]).max() < 0.5  # pixels

ax = plotting.show_image(None, image, title="the camera's view: detected markers with their corner names")
plotting.plot_detections(ax, detections)
plt.show()

# %% [markdown]
# A 1 % scale error is a 1 % distance error: 15 mm at 1.5 m, whatever the camera and however good the corners.
# A print scaled to 97 % ("fit to page") costs 3 %. Calipers read the side to a tenth of a millimetre, which is
# 0.1 % of an 80 mm marker (the 79.9 mm line). `fidlearn markers` prints a 100 mm ruler
# beside the markers: measure it before you cut.
#
# ## Try it
#
# A marker printed for 4 pixels per cell at 3 m (section 3): how wide must it be for 5 m, and for the same 3 m
# seen by a camera with half the focal length (a wider lens)? **Predict first** from `side = 4 (n + 2) Z / fx`,
# then change the numbers and run.

# %%
DISTANCE_MM = 3000.0  # try 5000
FX_PX = camera.fx  # try camera.fx / 2

side_mm = marker_side_mm(DISTANCE_MM, FX_PX, cells)
print(
    f"at {DISTANCE_MM / 1000:.1f} m with fx = {FX_PX:.0f} px: print the ARUCO_ORIGINAL black square at least "
    f"{side_mm:.0f} mm wide ({side_mm * FX_PX / DISTANCE_MM / cells:.1f} px per cell)"
)

# %% [markdown]
# ## Summary
#
# * A dictionary is a set of bit patterns; detect with the dictionary you printed. Keep a white quiet
#   zone around the black border, and measure the side on the black square.
# * Plan for at least ~4 pixels per cell: side ≥ 4 (n + 2) Z / fx. Print at 100 % and measure the printed
#   square with calipers: a 1 % scale error is a 1 % distance error.
# * A placement is the top-left corner (in the map's units) and `[roll, pitch, yaw]` in degrees;
#   corners are `TL + s R c_k`, in mm, TL, TR, BR, BL. Units are declared, never guessed.
# * North wall: rotation 0; south: yaw 180; west/east: yaw ±90; floor: pitch -90.
#
# **Exercises**: [exercises/04_world_map.ipynb](exercises/04_world_map.ipynb), with automatic feedback
# (or `from fidlearn import exercises; ex = exercises.lesson("04")` in a new cell).
#
# Next: [05 Detecting markers](05_detection_winding_order.ipynb).

# %% [markdown]
# ## References
#
# * OpenCV, "Detection of ArUco Markers" (dictionaries, printing markers):
#   https://docs.opencv.org/4.x/d5/dae/tutorial_aruco_detection.html
# * S. Garrido-Jurado, R. Muñoz-Salinas, F. J. Madrid-Cuevas and M. J. Marín-Jiménez, "Automatic generation and
#   detection of highly reliable fiducial markers under occlusion", Pattern Recognition 47(6), 2014: ArUco.
# * K. M. Lynch and F. C. Park, *Modern Robotics*, Cambridge University Press, 2017, chapter 3 (rotations and
#   rigid-body transforms, for the map's placements): http://modernrobotics.org
