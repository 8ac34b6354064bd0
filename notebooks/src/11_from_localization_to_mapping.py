# %% [markdown]
# # 11 From localization to mapping
#
# **What you will learn**
#
# * why a map made with a tape measure limits every pose `locate` gives, and by how much;
# * how photos of the markers from several places can measure the map itself: the unknowns (one pose per photo,
#   one placement per marker) and the residuals (every corner's reprojection, and the tape as a prior);
# * why the problem's Jacobian is sparse, and what that buys;
# * the gauge freedom: why photos alone cannot say where the room is, and how the tape or one fixed marker pins it;
# * how a robust loss and a chi-square test find a marker that was moved after it was measured;
# * how to measure your printer's scale from one photo, and what to write in the map;
# * how the map's accuracy grows with the number of photos;
# * how two photos and no map start a monocular SLAM map: the essential matrix, triangulation, the scale from one
#   marker's size, one bundle adjustment over every photo; and what full SLAM adds on top.
#
# This is the first step from localization (a known map, notebooks 06-09) towards SLAM (the map and the
# camera at once). Run the cells from top to bottom (Shift-Enter).

# %%
# %matplotlib inline
import json
import warnings

import cv2
import matplotlib.pyplot as plt
import numpy as np
from scipy import sparse

from fidlearn import Camera, Detection, MarkerMap, data_path, detect_markers, estimate_pose, locate, survey
from fidlearn.detection import load_image
from fidlearn.frames import look_at, rpy_deg_from_rotation
from fidlearn.markermap import MARKER_CORNERS_LOCAL
from fidlearn.survey import check_print
from fidlearn.synthetic import (
    board_survey_room,
    render_scene,
    survey_room,
    survey_walk,
    tape_measured,
    visible_markers,
)

np.set_printoptions(precision=3, suppress=True)

# %% [markdown]
# ## 1. The problem: a map only as good as the tape
#
# `data/survey/` is a walk of 24 photos (1280 x 720) through a 5 m x 4 m room with 12 markers of 160 mm on three
# walls and the floor. `true_map.json` is where the markers really are; `tape_map.json` is what a careful person
# with a tape measure wrote down: every top-left corner off by about 20 mm per coordinate, every rotation by about
# a degree, and marker 7 moved 100 mm along its wall after it was measured. `poses.json` holds the true pose of
# every photo, so we can see what the tape's errors cost `estimate_pose`.

# %%
camera = Camera.load(data_path("survey", "camera.json"))
true_map = MarkerMap.load(data_path("survey", "true_map.json"))
tape_map = MarkerMap.load(data_path("survey", "tape_map.json"))
walk = json.loads(data_path("survey", "poses.json").read_text())
paths = sorted(data_path("survey").glob("photo_*.jpg"))
images = [load_image(p) for p in paths]
T_true = [np.array(ph["T_world_camera"]) for ph in walk["photos"]]
detections = [detect_markers(image, tape_map.dictionary) for image in images]


def corner_error_mm(m, ids=None):
    """Each marker's top-left corner in map m minus the truth, mm."""
    return {
        i: np.linalg.norm(np.subtract(m.placements[i].translation_mm, true_map.placements[i].translation_mm))
        for i in (ids or true_map.ids)
    }


tape_err = corner_error_mm(tape_map)
print(
    f"{len(images)} photos, {len(true_map)} markers of {true_map.marker_size_mm:.0f} mm; the tape map is in "
    f"{tape_map.units}"
)
print("tape error of each top-left corner (mm):", {i: round(e) for i, e in tape_err.items()})


def locate_error_mm(m):
    """Median position error (mm) of estimate_pose over the 24 photos with map m."""
    return float(
        np.median(
            [np.linalg.norm(estimate_pose(d, m, camera).position_mm - T[:3, 3]) for d, T in zip(detections, T_true)]
        )
    )


loc_true, loc_tape = locate_error_mm(true_map), locate_error_mm(tape_map)
print(
    f"estimate_pose on the same photos: median position error {loc_true:.1f} mm with the true map, "
    f"{loc_tape:.1f} mm with the tape map"
)
assert len(images) == 24 and tape_err[7] > 80
assert loc_tape > 5 * loc_true

# %% [markdown]
# The detector and the pose are not the problem: with the true map the photos locate the camera to a few mm.
# The tape costs {{ loc_tape / loc_true:.0f }} times more. We cannot measure the room better with the tape, but we
# already have something far more precise: the photos. Each one shows where the markers are *relative to each
# other* to a fraction of a pixel.
#
# ## 2. The unknowns and the residuals
#
# Let the photos measure the map. Unknowns, 6 each (a rotation and a translation):
#
# * every photo's camera pose, $T^{\text{camera}}_{\text{world},c}$ for $c = 1 \dots m$;
# * every marker's placement, $(R_j, \mathbf p_j)$: its rotation and its top-left corner in the world.
#
# Residuals, each divided by its standard deviation ("whitened", so all are in sigmas):
#
# * for every corner $k$ of every marker $j$ seen in photo $c$, two numbers (u and v):
#   $$\mathbf r_{cjk} = \big(\pi(K, d; R_c (\mathbf p_j + R_j L_k)+\mathbf t_c) - \mathbf u_{cjk}\big) / \sigma_{px}$$
#   where $L_k$ is the corner in the marker's own frame (`MARKER_CORNERS_LOCAL` times the size), $\pi$ the
#   projection with distortion (notebook 01) and $\mathbf u_{cjk}$ the detected pixel;
# * for every marker with a tape placement, six numbers: $\log(R_j R_{\text{tape},j}^\top)/\sigma_{rot}$ and
#   $(\mathbf p_j - \mathbf p_{\text{tape},j})/\sigma_{mm}$: the tape as a *prior*, trusted to its sigma.
#
# A least-squares solver moves the unknowns to make the sum of squared residuals smallest. This is **bundle
# adjustment**: the "bundles" of rays from every camera adjusted until they meet. Count them for our photos:

# %%
n_photos = len(detections)
n_markers = len(tape_map)
n_unknowns = 6 * n_photos + 6 * n_markers
n_corners = sum(4 * sum(d.id in tape_map for d in dets) for dets in detections)
n_residuals = 2 * n_corners + 6 * n_markers
print(f"unknowns : {n_photos} photos x 6 + {n_markers} markers x 6 = {n_unknowns}")
print(f"residuals: {n_corners} corners x 2 + {n_markers} tape placements x 6 = {n_residuals}")
print(f"{n_residuals / n_unknowns:.1f} residuals per unknown")
assert n_residuals > n_unknowns

# %% [markdown]
# ## 3. One residual, by hand
#
# Take marker 2 in the first photo, with the true poses. The corner's world point is the marker's top-left corner
# plus the rotated local corner; the camera's pose moves it into the camera frame; divide by depth, distort
# (k1, k2, p1, p2, k3), then apply K. Then check the hand-made pixel against `Camera.project` (OpenCV's
# `projectPoints`), and the residual against the detector.


# %%
def project_by_hand(X_world, T_world_camera, K, dist):
    """Pixels (n, 2) of world points (n, 3), mm, with the 5-coefficient distortion."""
    T_cw = np.linalg.inv(T_world_camera)
    P = X_world @ T_cw[:3, :3].T + T_cw[:3, 3]
    x, y = P[:, 0] / P[:, 2], P[:, 1] / P[:, 2]
    k1, k2, p1, p2, k3 = dist
    r2 = x**2 + y**2
    radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x**2)
    yd = y * radial + p1 * (r2 + 2 * y**2) + 2 * p2 * x * y
    return np.column_stack([K[0, 0] * xd + K[0, 2], K[1, 1] * yd + K[1, 2]])


marker_id, photo = 2, 0
place = true_map.placements[marker_id]
X = np.asarray(place.translation_mm) + (MARKER_CORNERS_LOCAL * true_map.marker_size_mm) @ place.R_world_marker.T
dist = np.asarray(camera.dist, float).ravel()[:5]
by_hand = project_by_hand(X, T_true[photo], camera.K, dist)
by_opencv = camera.project(X, T_true[photo])
detected = next(d.corners_px for d in detections[photo] if d.id == marker_id)
residual = by_hand - detected
print("projected by hand (px):\n", by_hand)
print(f"largest difference from Camera.project: {np.abs(by_hand - by_opencv).max():.1e} px")
print("residual, projected minus detected (px):\n", residual)
assert np.abs(by_hand - by_opencv).max() < 1e-6
assert np.abs(residual).max() < 1.0

# %% [markdown]
# The residual is a few hundredths of a pixel: the detector's noise. The same arithmetic, at the survey's
# solution, gives the survey's own reprojection error: we check that below, after running it (section 6).
#
# ## 4. The sparse Jacobian
#
# A corner's two residuals depend on only 12 of the unknowns: its photo's 6 and its marker's 6. A tape residual
# depends on its marker's 6 alone. So nearly every entry of the Jacobian $J = \partial \mathbf r / \partial \mathbf x$
# is zero. Here is its pattern for our photos, built from the detections with `scipy.sparse`:

# %%
slot = {i: k for k, i in enumerate(tape_map.ids)}
rows, cols = [], []
row = 0
for c, dets in enumerate(detections):
    for d in dets:
        if d.id not in slot:
            continue
        for _ in range(4 * 2):  # 4 corners x (u, v)
            rows += [row] * 12
            cols += list(6 * c + np.arange(6)) + list(6 * n_photos + 6 * slot[d.id] + np.arange(6))
            row += 1
for j in range(n_markers):  # the tape priors
    for _ in range(6):
        rows += [row] * 6
        cols += list(6 * n_photos + 6 * j + np.arange(6))
        row += 1
pattern = sparse.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(row, n_unknowns)).tocsr()
pattern.sum_duplicates()
fill = pattern.nnz / np.prod(pattern.shape)
print(f"Jacobian {pattern.shape[0]} x {pattern.shape[1]}: {pattern.nnz} nonzeros, {100 * fill:.1f} % of the entries")

fig, ax = plt.subplots(figsize=(7, 9))
ax.spy(pattern, markersize=0.6, aspect="auto")
ax.axvline(6 * n_photos - 0.5, color="tab:red", linewidth=1)
ax.axhline(2 * n_corners - 0.5, color="tab:red", linewidth=1)
ax.set_xlabel(f"unknowns: {n_photos} camera poses | {n_markers} marker placements")
ax.set_ylabel("residuals: corners (u, v), then the tape priors")
ax.set_title("the survey's Jacobian: black = may be nonzero")
plt.show()
assert pattern.nnz == 12 * 2 * n_corners + 36 * n_markers

# %% [markdown]
# Each corner row has a stripe in its photo's block (left) and one in its marker's block (right); the tape rows at
# the bottom are a diagonal of 6 x 6 blocks. `scipy.optimize.least_squares` accepts such a pattern
# (`jac_sparsity`) or a sparse Jacobian, and then never builds the dense matrix: the cost of one step grows with
# the number of nonzeros, not with (residuals x unknowns). That is what lets bundle adjustment reach thousands of
# photos (Triggs et al. 2000, section 6).
#
# ## 5. The gauge freedom
#
# Move the whole room and every camera by the same rigid motion: every corner projects to the same pixel. So the
# photos alone cannot tell where the room is: 6 directions (3 of translation, 3 of rotation) in which the
# residuals do not change. Scale *is* fixed, by the markers' known size. In the normal matrix $J^\top J$ (the
# Gauss-Newton step solves $J^\top J\, \Delta\mathbf x = -J^\top \mathbf r$) those directions are a null space: a
# rank deficiency of 6, and no unique answer.
#
# Let us see it on a small problem: the first 4 photos and the markers they see, with a Jacobian by finite
# differences of the hand-made residual of section 3 (small rotations as rotation vectors).


# %%
def rotvec_matrix(w):
    """Rotation matrix of a rotation vector (Rodrigues)."""
    a = np.linalg.norm(w)
    if a < 1e-15:
        return np.eye(3)
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / a
    return np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k


small_photos = [0, 2, 13, 14]  # photos that share markers (photo 1 sees none of photo 0's)
small_ids = sorted({d.id for c in small_photos for d in detections[c]} & set(tape_map.ids))
L = MARKER_CORNERS_LOCAL * true_map.marker_size_mm


def reprojection(x):
    """Whitened corner residuals (sigma 0.1 px) of the small problem at increments x from the true poses."""
    out = []
    for n, c in enumerate(small_photos):
        dc = x[6 * n : 6 * n + 6]
        T = T_true[c].copy()
        T[:3, :3] = rotvec_matrix(dc[:3]) @ T[:3, :3]
        T[:3, 3] += dc[3:]
        for d in detections[c]:
            if d.id not in small_ids:
                continue
            k = 6 * len(small_photos) + 6 * small_ids.index(d.id)
            p = true_map.placements[d.id]
            R = rotvec_matrix(x[k : k + 3]) @ p.R_world_marker
            Xw = np.asarray(p.translation_mm) + x[k + 3 : k + 6] + L @ R.T
            out.append((project_by_hand(Xw, T, camera.K, dist) - d.corners_px).ravel() / 0.1)
    return np.concatenate(out)


n_small = 6 * (len(small_photos) + len(small_ids))
h = 1e-6
J = np.column_stack([(reprojection(h * e) - reprojection(-h * e)) / (2 * h) for e in np.eye(n_small)])
N = J.T @ J
prior = np.zeros_like(N)  # the tape's information: 1 / sigma^2 on each marker's 6 unknowns
for j in range(len(small_ids)):
    k = 6 * len(small_photos) + 6 * j
    prior[k : k + 3, k : k + 3] = np.eye(3) / np.radians(1.0) ** 2
    prior[k + 3 : k + 6, k + 3 : k + 6] = np.eye(3) / 20.0**2
free = np.ones(n_small, bool)
free[6 * len(small_photos) : 6 * len(small_photos) + 6] = False  # hold the first marker


def rank(A):
    """Numerical rank of a normal matrix, its unknowns first scaled to a unit diagonal (radians and mm differ)."""
    d = 1 / np.sqrt(np.diag(A))
    s = np.linalg.svd(A * d[:, None] * d[None, :], compute_uv=False)
    return int(np.sum(s > s[0] * 1e-9))


r_photos, r_tape, r_fixed = rank(N), rank(N + prior), rank(N[np.ix_(free, free)])
print(f"{len(small_photos)} photos, markers {small_ids}: {n_small} unknowns")
print(f"photos alone        : rank {r_photos}, deficiency {n_small - r_photos}")
print(f"photos + tape prior : rank {r_tape}, deficiency {n_small - r_tape}")
print(f"photos, marker {small_ids[0]} fixed: rank {r_fixed} of {free.sum()}, deficiency {free.sum() - r_fixed}")
assert n_small - r_photos == 6 and r_tape == n_small and r_fixed == free.sum()

# %% [markdown]
# Two cures, both in `fidlearn.survey`:
#
# * **the tape as a prior** (`map_sigma_mm`): every marker pulled gently towards its tape placement. The room's
#   position is then the average of the tape's, which is better than any one tape reading: the photos give the
#   shape, the tape the place.
# * **a fixed marker** (`fixed_ids=[0]`): its placement taken as exact, removed from the unknowns. Everything is
#   then measured relative to it (the usual choice when the room's frame *is* a reference marker).
#
# ## 6. The robust loss and the suspect test
#
# Marker 7's tape placement is 100 mm off: five tape sigmas. With plain squares its prior would pull hard and drag
# the photos' solution. `fidlearn.survey` first solves with a **soft-L1 loss** on the tape residuals,
# $\rho(z) = 2c^2(\sqrt{1 + z/c^2} - 1)$ for a squared residual $z$ with $c = 3$ sigmas: like squares for small
# residuals, growing only linearly for large ones, so one bad tape reading cannot drag the rest.
#
# Then it tests each taped marker: where do the *photos alone* put it, and how far is that from the tape, measured
# in sigmas of the difference (the Mahalanobis distance, photos' covariance plus the tape's)? For a correctly taped
# marker the squared distance is chi-square with 3 degrees of freedom; above its 99 % point (3.37 sigmas) the
# marker is named a suspect and its tape prior dropped.

# %%
z = np.linspace(0, 100, 200)
c2 = 3.0**2
fig, ax = plt.subplots(figsize=(6, 3.2))
ax.plot(np.sqrt(z), z, label="squares: $z$")
ax.plot(np.sqrt(z), 2 * c2 * (np.sqrt(1 + z / c2) - 1), label="soft-L1, $c = 3$")
ax.set_xlabel("residual (sigmas)")
ax.set_ylabel("its cost")
ax.legend()
plt.show()

result = survey(detections, tape_map, camera, map_sigma_mm=20)
print("each taped marker: where the photos put it, from the tape")
for i, (mm, sig) in result.tests.items():
    print(f"  marker {i:2d}: {mm:6.1f} mm = {sig:4.1f} sigmas{'   <- suspect' if i in result.suspect_ids else ''}")
for s in result.suspects:
    print(f"marker {s.id} is {s.distance_mm:.0f} mm from where the map says ({s.sigmas:.1f} sigma): measure it again")
assert result.suspect_ids == [7]
runner_up = max((i for i in result.tests if i not in result.suspect_ids), key=lambda i: result.tests[i][0])

# %% [markdown]
# Marker 7 stands out in sigmas, not only in millimetres: marker {{ runner_up }}'s tape is
# {{ result.tests[runner_up][0]:.0f }} mm off too but that is within
# what 20 mm per coordinate allows, with the photos' uncertainty. And the survey's reprojection residuals are the
# hand-made residual of section 3, at its solution: recompute photo 0's RMS from the surveyed poses and map.

# %%
sm = result.marker_map
res_all = []
for d in detections[0]:
    p = sm.placements[d.id]
    Xw = np.asarray(p.translation_mm) + L @ p.R_world_marker.T
    res_all.append(project_by_hand(Xw, result.camera_poses["photo 0"], camera.K, dist) - d.corners_px)
rms_hand = float(np.sqrt(np.mean(np.sum(np.concatenate(res_all) ** 2, axis=1))))
print(f"photo 0: reprojection RMS by hand {rms_hand:.4f} px, the survey's {result.photo_rms_px['photo 0']:.4f} px")
assert abs(rms_hand - result.photo_rms_px["photo 0"]) < 1e-4

survey_err = corner_error_mm(sm)
print(
    f"top-left corners from the truth: tape RMS {np.sqrt(np.mean(np.square(list(tape_err.values())))):.1f} mm, "
    f"surveyed {np.sqrt(np.mean(np.square(list(survey_err.values())))):.1f} mm; "
    f"marker 7: tape {tape_err[7]:.0f} mm, surveyed {survey_err[7]:.1f} mm"
)
loc_survey = locate_error_mm(sm)
print(
    f"estimate_pose's median error: tape map {loc_tape:.1f} mm, surveyed map {loc_survey:.1f} mm, "
    f"true map {loc_true:.1f} mm"
)

# %% [markdown]
# The surveyed map is still off by the average of the tape's errors (the gauge of section 5 is held by the tape,
# so the room as a whole is only as well placed as 12 tape readings average out), but its *shape* is right to a
# millimetre, and marker 7 is back where it belongs. `locate` with it is {{ loc_tape / loc_survey:.0f }} times better.
#
# ### What you do not know: how good was the tape?
#
# Above we told the survey the tape's accuracy (`map_sigma_mm=20`), which a user cannot know. Left out (the
# default, `map_sigma_mm=None`), the survey **learns it from the data**: once the photos have placed the markers,
# the tape readings' residuals show how far the tape really was off, as a variance component (the robust loss
# keeps marker 7's 100 mm from inflating it). It also checks the printed markers' common scale (a printer at
# 98.7 % is common), which would shrink every distance the photos measure.

# %%
learnt = survey(detections, tape_map, camera)  # no map_sigma_mm: learnt from the tape's residuals
print(
    f"tape sigma learnt: {learnt.map_sigma_mm:.1f} +/- {learnt.map_sigma_se_mm:.1f} mm per coordinate "
    f"(learnt: {learnt.map_sigma_learnt}); suspects {learnt.suspect_ids}"
)
print(f"printed markers at {100 * learnt.print_scale:.2f} +/- {100 * learnt.print_scale_se:.2f} % of the map's size")
learnt_err = corner_error_mm(learnt.marker_map)
print(f"top-left corners from the truth: surveyed RMS {np.sqrt(np.mean(np.square(list(learnt_err.values())))):.1f} mm")
assert learnt.map_sigma_learnt and learnt.suspect_ids == [7]
assert abs(learnt.print_scale - 1) < learnt.print_scale_se  # the sentence below says so

# %% [markdown]
# The tape was off by 20 mm per coordinate (the way the data set was made); the survey, never told, says
# {{ learnt.map_sigma_mm:.0f }} mm, give or take {{ learnt.map_sigma_se_mm:.0f }}, and names the same marker.
# The markers printed at {{ 100 * learnt.print_scale:.1f }} % (100 % is within one standard error,
# {{ 100 * learnt.print_scale_se:.1f }} %: these renders print true). A number a user cannot know is learnt from
# the data and reported with its uncertainty: `learnt.map_sigma_se_mm` says how far to trust it.
#
# ### Your printer's scale
#
# These renders print true; your printer may not. Printers often scale the page ("fit to page" gives about
# 98.7 %), and then every marker is smaller than the map says. A smaller marker looks like one farther away: a
# pose from one marker stretches its distance by 1/0.987, 13 mm per metre. One photo of four or more markers whose
# top-left corners you taped tells the scale: `check_print` (`fidlearn check-print` on the command line) places
# each marker alone from its corners and its map size, and lays those top-left corners on the tape's with a
# similarity; its scale is the print's. Eight 80 mm markers on a wall, printed at 98.7 %, one photo:

# %%
wall = {str(i): {"translation": [0, 250 * (i % 4), 1600 - 250 * (i // 4)]} for i in range(8)}
asked = MarkerMap.from_dict({"units": "mm", "marker_size_mm": 80, "markers": wall})  # the map: 80 mm asked
printed = MarkerMap.from_dict({"units": "mm", "marker_size_mm": 80 * 0.987, "markers": wall})  # what came out
T_photo = look_at([1300, 500, 1500], [0, 375, 1350], roll_deg=4)
photo = render_scene(printed, camera, T_photo, seed=3, noise_std_gray=2.0, blur_px=0.6).image
check = check_print(photo, asked, camera)
print(f"check_print: scale {check.scale:.4f} +/- {check.scale_std:.4f} from markers {list(check.marker_ids)}")
print(check.advice())
resized = MarkerMap.from_dict({"units": "mm", "marker_size_mm": round(80 * check.scale, 2), "markers": wall})
one = [d for d in detect_markers(photo, asked.dictionary) if d.id == 5]  # a pose from one marker


def off_mm(m, dets=None):
    """How far (mm) the camera's position from this photo is from the truth with map m (locate, or dets)."""
    pose = locate(photo, m, camera) if dets is None else estimate_pose(dets, m, camera)
    return float(np.linalg.norm(pose.position_mm - T_photo[:3, 3]))


far = np.linalg.norm(T_photo[:3, 3] - printed.marker_corners(5).mean(axis=0))
one_asked, one_resized = off_mm(asked, one), off_mm(resized, one)
print(
    f"marker 5 alone, {far:.0f} mm away: {one_asked:.1f} mm off with size_mm 80, "
    f"{one_resized:.1f} mm with size_mm {resized.marker_size_mm:g}"
)
print(f"all eight (locate): {off_mm(asked):.1f} mm off with size_mm 80, {off_mm(resized):.1f} mm with the printed size")
assert abs(check.scale - 0.987) < 3 * check.scale_std and one_resized < one_asked / 3

# %% [markdown]
# The photo says {{ 100 * check.scale:.2f }} % give or take {{ 100 * check.scale_std:.2f }} %. The pose from
# marker 5 alone is {{ one_asked:.0f }} mm off until the map has the printed size ({{ one_resized:.1f }} mm
# after); with all eight markers in view the taped top-left corners hold the distance, so the damage shows in
# views of one or two markers. Two mends: **set `size_mm`** to what the printer made (the map's
# `marker_size_mm`, or each marker's own `size_mm` in a map that mixes sizes: every size times the same scale),
# or **print again at 100 %** ("actual size", no fitting to the page) and keep the map. A ruler confirms either:
# 80 mm at 98.7 % is 78.96 mm, a millimetre you can see across the black square.
#
# The survey measures the same scale from all its photos (`print_scale`, against the tape's top-left corners).
# The room of section 1 printed at 98.7 %, its map still saying 160 mm, corners projected as in section 7 below:

# %%
room_printed = survey_room(marker_size_mm=160 * 0.987)  # top-left corners where they were taped
taped = tape_measured(room_printed, sigma_mm=20, sigma_deg=1, seed=5)
taped = MarkerMap(taped.placements, 160.0, dictionary=taped.dictionary, units=taped.units)  # the map says 160 mm
rng = np.random.default_rng(7)
printed_dets = [
    [Detection(i, c + rng.normal(0, 0.1, c.shape)) for i, c in visible_markers(room_printed, camera, T).items()]
    for T in survey_walk(room_printed, camera, n_photos=20, seed=3)
]
scaled = survey(printed_dets, taped, camera, corner_sigma_px=0.1)
for line in scaled.learnt():
    print(line)
assert scaled.print_scale_applied and abs(scaled.print_scale - 0.987) < 3 * scaled.print_scale_se

# %% [markdown]
# With the tape's sigma learnt, a scale more than 3 standard errors from 100 % is applied: the surveyed map says
# {{ scaled.marker_map.marker_size_mm:.1f }} mm. One exercise (q5) goes the other way round: a ruler's readings,
# and the `size_mm` to write for markers of several sizes.
#
# ### A board on the wall is one object
#
# A map may place a whole ChArUco board, or a few markers screwed to one plate (a robot's dock), by one pose: a
# **rigid entry** (`"boards"` and `"bundles"` in the map file: `docs/conventions.md`). The survey
# keeps it rigid: one placement (6 unknowns) for all its markers, whose corners sit where the board's geometry
# puts them; one tape prior; one suspect test. Why that matters: a board carries 17 markers but only one tape
# measurement. Surveyed as 17 single markers, its one error counts 17 times. The room of section 1 with a board in
# place of marker 1 and a dock in place of marker 8 (`board_survey_room`), the board taped 100 mm off:

# %%
board_room = board_survey_room()
rng = np.random.default_rng(13)
board_dets = [
    [Detection(i, c + rng.normal(0, 0.1, c.shape)) for i, c in visible_markers(board_room, camera, T).items()]
    for T in survey_walk(board_room, camera, n_photos=20, seed=3)
]
board_tape = tape_measured(board_room, sigma_mm=10, sigma_deg=1, moved={"wall board": (0.0, 60.0, -80.0)}, seed=5)
as_entry = survey(board_dets, board_tape, camera)
singles_tape = MarkerMap(board_tape.placements, board_tape.marker_size_mm, dictionary=board_tape.dictionary)
as_singles = survey(board_dets, singles_tape, camera)  # the same tape, the board's markers one by one
true_tl = np.asarray(board_room.placements[20].translation_mm)  # marker 20, the board's top-left marker
board_off = {
    name: float(np.linalg.norm(np.asarray(s.marker_map.placements[20].translation_mm) - true_tl))
    for name, s in (("entry", as_entry), ("singles", as_singles))
}
print(f"the board as an entry:  suspects {as_entry.suspect_ids}; marker 20 {board_off['entry']:.0f} mm off")
print(f"its markers one by one: suspects {as_singles.suspect_ids}; marker 20 {board_off['singles']:.0f} mm off")
assert set(as_entry.suspect_ids) == set(range(20, 37)) and board_off["entry"] < 15 < 50 < board_off["singles"]

# %% [markdown]
# As an entry the board is named, all its markers at once (`fidlearn survey` prints it as one line: "board 'wall
# board' (markers 20-36) is ... mm from where the map says"), and the photos put it back within
# {{ board_off["entry"]:.0f }} mm. One by one, its 17 markers agree with each other about the wrong place: they
# outvote the room, good markers ({{ len(as_singles.suspect_ids) }} of them, the most the survey names) are
# blamed instead, and the board stays {{ board_off["singles"]:.0f }} mm off.
#
# ## 7. Accuracy against the number of photos
#
# How many photos does a survey need? A quick sweep on a room that is not rendered (`survey_room`, the walks of
# `survey_walk`, corners projected from the true poses plus 0.1 px of noise instead of rendered photos, to stay
# fast). We measure the map's **shape**: the corners' RMS from the truth after the best rigid alignment (the part
# the photos decide; the placement of the whole is the tape's).


# %%
def shape_rms_mm(a, b):
    """RMS (mm) of points a from points b after the rigid motion that lays a best on b (Kabsch)."""
    ca, cb = a - a.mean(axis=0), b - b.mean(axis=0)
    u, _, vt = np.linalg.svd(ca.T @ cb)
    R = (u @ np.diag([1, 1, np.sign(np.linalg.det(u @ vt))]) @ vt).T
    return float(np.sqrt(np.mean(np.sum((ca @ R.T - cb) ** 2, axis=1))))


room = survey_room()
room_tape = tape_measured(room, sigma_mm=20, sigma_deg=1, seed=5)
truth_c = np.concatenate([room.marker_corners(i) for i in room.ids])
rng = np.random.default_rng(11)
counts = [6, 10, 16, 24]
shape_err = []
for n in counts:
    walk_poses = survey_walk(room, camera, n_photos=n, seed=3)
    dets = [
        [Detection(i, c + rng.normal(0, 0.1, c.shape)) for i, c in visible_markers(room, camera, T).items()]
        for T in walk_poses
    ]
    s = survey(dets, room_tape, camera, map_sigma_mm=20, corner_sigma_px=0.1)
    got_c = np.concatenate([s.marker_map.marker_corners(i) for i in room.ids])
    shape_err.append(shape_rms_mm(got_c, truth_c))
tape_shape = shape_rms_mm(np.concatenate([room_tape.marker_corners(i) for i in room.ids]), truth_c)
for n, e in zip(counts, shape_err):
    print(f"{n:2d} photos: the map's shape within {e:.2f} mm RMS")
print(f"(the tape's shape: {tape_shape:.1f} mm RMS)")

fig, ax = plt.subplots(figsize=(6, 3.2))
ax.plot(counts, shape_err, "o-")
ax.set_xlabel("photos")
ax.set_ylabel("shape RMS (mm)")
ax.set_title("the surveyed map's shape against the number of photos")
plt.show()
assert max(shape_err) < tape_shape / 3 and shape_err[-1] < shape_err[0] / 3

# %% [markdown]
# Six photos already beat the tape several times over, but some markers are then seen in only one or two photos
# and are placed poorly; by ten photos every marker is seen from several places and the shape is right to about a
# millimetre. More photos help more slowly after that (each marker seen more often, and from more different
# angles: an angle spread matters more than a count).
#
# ## 8. Two photos and no map: how monocular SLAM starts
#
# Everything so far started from a map, even a poor one. Monocular SLAM starts from nothing: two photos of the
# same things, taken from two places. The markers' ids tell which corner in one photo is which corner in the
# other (a SLAM system matches natural features by their descriptors instead), and that is enough:
#
# 1. each matched corner gives a **ray** from each camera: its pixel, undistorted, as a direction
#    (`cv2.undistortPoints` gives the normalized coordinates $(x/z,\ y/z)$);
# 2. the two rays of one point and the line between the cameras lie in one plane, so every match gives one
#    equation $\mathbf x_2^\top E\, \mathbf x_1 = 0$ on the **essential matrix** $E = [\mathbf t]_\times R$;
#    `cv2.findEssentialMat` solves it (Nistér's five-point method inside RANSAC) and `cv2.recoverPose` splits
#    $E$ into the rotation $R$ and the direction $\mathbf t$ of camera 1 as seen from camera 2, keeping the one of
#    four splits that puts the points in front of both cameras;
# 3. **triangulate**: every corner is where its two rays cross (`cv2.triangulatePoints`), in camera 1's frame;
# 4. the **scale** is still unknown: two photos of a room, and of a model of the room ten times smaller, are the
#    same pictures. $\mathbf t$ comes out of length 1; one known length fixes it, here a marker's side.
#
# Which two photos? They must see the same markers from places far enough apart (parallax), and those markers
# should not all lie on one wall: points exactly on a plane are explained as well by a second motion (the
# plane's homography has two decompositions), and near it the noise can choose between them. Photos 20 and 23 stood far
# apart and share markers on several surfaces; we solve them twice, with the markers of one wall only and with
# them all, and the truth (`poses.json`) says how far each answer is off.


# %%
seen = [{d.id: d.corners_px for d in dets} for dets in detections]


def rays(px):
    """Normalized image coordinates (x/z, y/z) of pixels: the rays through them, the lens's distortion undone."""
    return cv2.undistortPoints(np.asarray(px, np.float64).reshape(-1, 1, 2), camera.K, camera.dist).reshape(-1, 2)


def two_view(i, j, markers=None):
    """Photos i and j alone: the markers used (``markers``, or all they share), R and unit t of camera 2 from
    camera 1, the corners triangulated."""
    shared = sorted(set(seen[i]) & set(seen[j])) if markers is None else list(markers)
    x1 = rays(np.concatenate([seen[i][k] for k in shared]))
    x2 = rays(np.concatenate([seen[j][k] for k in shared]))
    E, inliers = cv2.findEssentialMat(x1, x2, np.eye(3), method=cv2.RANSAC, prob=0.999, threshold=1e-3)
    _, R, t, _ = cv2.recoverPose(E, x1, x2, np.eye(3), mask=inliers)
    X = cv2.triangulatePoints(np.eye(3, 4), np.hstack([R, t]), x1.T, x2.T)
    return shared, R, t, (X[:3] / X[3]).T.reshape(-1, 4, 3)


def motion_errors(i, j, R, t):
    """Rotation error (degrees) and direction error of t (degrees) against the truth of photos i and j."""
    T_21 = np.linalg.inv(T_true[j]) @ T_true[i]  # camera 1's frame to camera 2's
    rot = np.degrees(np.linalg.norm(cv2.Rodrigues(R @ T_21[:3, :3].T)[0]))
    true_dir = T_21[:3, 3] / np.linalg.norm(T_21[:3, 3])
    return rot, np.degrees(np.arccos(np.clip(float(t.ravel() @ true_dir), -1.0, 1.0)))


shared = sorted(set(seen[20]) & set(seen[23]))
north_wall = [k for k in shared if np.allclose(true_map.normal(k), [1, 0, 0])]
errors = {}
for name, markers in [("one wall", north_wall), ("all", shared)]:
    used, R, t, _ = two_view(20, 23, markers)
    surfaces = {tuple(np.round(true_map.normal(k), 3)) for k in used}
    errors[name] = motion_errors(20, 23, R, t)
    print(
        f"photos 20 and 23, markers {used} ({len(surfaces)} surface(s)): rotation off by {errors[name][0]:.2f} deg, "
        f"direction of travel off by {errors[name][1]:.1f} deg"
    )
one_wall_err, three_err = errors["one wall"], errors["all"]
assert one_wall_err[0] > 5 * three_err[0] and three_err[0] < 0.5 and three_err[1] < 1

# %% [markdown]
# The same two photos: with one wall's {{ len(north_wall) }} markers the rotation is {{ one_wall_err[0]:.2f }}
# degrees and the direction {{ one_wall_err[1]:.1f }} degrees off; with the {{ len(shared) }} markers of
# {{ len(surfaces) }} surfaces, {{ three_err[0]:.2f }} and {{ three_err[1]:.1f }} degrees. Both the number of points
# and their depth count: choose the pair that shares the most markers, spread over more than one wall.
#
# Now the scale, from what we know of the markers: each triangulated marker's four sides, in units of the
# baseline, against its printed {{ true_map.marker_size_mm:.0f }} mm.

# %%
shared, R, t, corners_1 = two_view(20, 23)
sides = np.linalg.norm(corners_1 - np.roll(corners_1, -1, axis=1), axis=2)  # TL-TR, TR-BR, BR-BL, BL-TL
scale = true_map.marker_size_mm / np.median(sides)
corners_1 = corners_1 * scale  # mm, in camera 1's frame
T_21 = np.linalg.inv(T_true[23]) @ T_true[20]
print(f"the sides agree to {100 * sides.std() / sides.mean():.2f} % (a good start has no outlier among them)")
print(f"baseline: {scale:.0f} mm from the markers' size, {np.linalg.norm(T_21[:3, 3]):.0f} mm true")

T_1w = np.linalg.inv(T_true[20])  # the world in camera 1's frame: only to compare with the truth
truth_1 = np.array([true_map.marker_corners(k) @ T_1w[:3, :3].T + T_1w[:3, 3] for k in shared])
corner_err = np.linalg.norm(corners_1 - truth_1, axis=2)
print(f"the {corner_err.size} corners: within {np.median(corner_err):.2f} mm (median), {corner_err.max():.1f} at worst")
assert abs(scale - np.linalg.norm(T_21[:3, 3])) < 10 and np.median(corner_err) < 2

# %% [markdown]
# Two photos and one marker's size have made a map of {{ len(shared) }} markers, to about a millimetre, with no
# tape and no map file. It lives in camera 1's frame: the gauge (section 5) is fixed by taking the first camera
# as the origin. Every other photo that sees two of these markers can now be located against it, as `locate`
# does against a map file (`solvePnP`; SQPnP, as the two markers may be on two walls), and that is the
# **tracking** half of SLAM:

# %%
two_view_map = {k: c for k, c in zip(shared, corners_1)}
located, cameras_1 = {}, {20: (np.eye(3), np.zeros(3)), 23: (R, scale * t.ravel())}  # (R, t): camera from frame 1
for f, markers in enumerate(seen):
    known = [k for k in markers if k in two_view_map]
    if f in (20, 23) or len(known) < 2:
        continue
    obj = np.concatenate([two_view_map[k] for k in known])
    img = np.concatenate([markers[k] for k in known])
    _, rvec, tvec = cv2.solvePnP(obj, img, camera.K, camera.dist, flags=cv2.SOLVEPNP_SQPNP)
    R_cf = cv2.Rodrigues(rvec)[0]  # this photo's camera from camera 1's frame
    centre = -R_cf.T @ tvec.ravel()  # its centre, in camera 1's frame
    located[f] = float(np.linalg.norm(centre - (T_1w @ T_true[f])[:3, 3]))
    cameras_1[f] = (R_cf, tvec.ravel())
print(f"{len(located)} more photos located against the two-photo map, position error (mm):")
print({f: round(e, 1) for f, e in located.items()})
located_median = float(np.median(list(located.values())))
assert len(located) >= 12 and located_median < 5

# %% [markdown]
# {{ len(located) }} of the other {{ len(seen) - 2 }} photos are located within {{ located_median:.1f }} mm (median) of
# where they were, by a map that two of them made. Those photos also see markers the first two did not: the
# **mapping** half of SLAM triangulates them in turn, step 3 again with the located cameras' $[R \mid \mathbf t]$ in
# place of $[I \mid 0]$ and $[R \mid \mathbf t]$ (from the two located photos that stood furthest apart):

# %%
grown = {}
for k in sorted({k for f in cameras_1 for k in seen[f]} - set(two_view_map)):
    photos_k = [f for f in cameras_1 if k in seen[f]]
    if len(photos_k) < 2:
        continue
    centres = {f: -cameras_1[f][0].T @ cameras_1[f][1] for f in photos_k}
    pairs = [(a, b) for a in photos_k for b in photos_k if a < b]
    a, b = max(pairs, key=lambda p: np.linalg.norm(centres[p[0]] - centres[p[1]]))
    P_a, P_b = (np.hstack([cameras_1[f][0], cameras_1[f][1][:, None]]) for f in (a, b))
    X = cv2.triangulatePoints(P_a, P_b, rays(seen[a][k]).T, rays(seen[b][k]).T)
    grown[k] = (X[:3] / X[3]).T
    truth_k = true_map.marker_corners(k) @ T_1w[:3, :3].T + T_1w[:3, 3]
    err = np.linalg.norm(grown[k] - truth_k, axis=1)
    print(f"marker {k}: from photos {a} and {b}, its corners within {err.max():.1f} mm")
print(f"the map: {len(two_view_map)} markers from the first two photos, {len(two_view_map) + len(grown)} now")
assert len(grown) >= 1

# %% [markdown]
# The map grows, and so do its errors: each new marker inherits the errors of the poses that placed it, which
# inherited those of the markers that located them. Left alone, a long walk drifts. That is why a SLAM system
# keeps the residuals of every photo and refines the growing map and every pose at once, with the bundle
# adjustment of sections 2-6, and why coming back to a marker seen at the start (a loop) is worth so much.
#
# This notebook already has that bundle adjustment: `survey`. Its start is the map grown so far, each marker's
# placement fitted to its triangulated corners (the rotation by an SVD, Kabsch's fit); no tape
# (`map_sigma_mm=inf`: the photos alone decide); one marker held (`fixed_ids`) for the gauge of section 5. The scale
# needs nothing more: every marker's printed size is in the residuals. To compare with what came before, the
# result is brought back into camera 1's frame, where camera 1 (photo 20) is now the adjusted one.

# %%
size_mm = true_map.marker_size_mm


def placement(c):
    """A map entry (mm, degrees) whose corners best fit the corners ``c`` (4, 3): the rotation by an SVD (Kabsch),
    the translation that of the top-left corner."""
    local = MARKER_CORNERS_LOCAL * size_mm  # the top-left corner at the origin
    U, _, Vt = np.linalg.svd((local - local.mean(0)).T @ (c - c.mean(0)))
    R = Vt.T @ np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))]) @ U.T
    return {"translation": (c.mean(0) - R @ local.mean(0)).tolist(), "rotation": rpy_deg_from_rotation(R).tolist()}


grown_map = {**two_view_map, **grown}
slam_map = MarkerMap.from_dict(
    {str(k): placement(c) for k, c in grown_map.items()},
    units="mm",
    marker_size_mm=size_mm,
    dictionary=true_map.dictionary,
)
order = sorted(cameras_1)  # the photos located so far, 20 and 23 among them
with warnings.catch_warnings(record=True) as caught:  # a marker seen once cannot be placed: it says so
    warnings.simplefilter("always")
    adjusted = survey([detections[f] for f in order], slam_map, camera, fixed_ids=[shared[0]], map_sigma_mm=np.inf)
print(f"{len(caught)} warning(s): {[str(w.message).split(':')[0] for w in caught]}")

T_1a = np.linalg.inv(adjusted.camera_poses[f"photo {order.index(20)}"])  # the survey's frame into camera 1's
before, after = {}, {}
for k in sorted(grown_map):
    truth_k = true_map.marker_corners(k) @ T_1w[:3, :3].T + T_1w[:3, 3]
    adjusted_k = adjusted.marker_map.marker_corners(k) @ T_1a[:3, :3].T + T_1a[:3, 3]
    before[k] = np.linalg.norm(grown_map[k] - truth_k, axis=1).max()
    after[k] = np.linalg.norm(adjusted_k - truth_k, axis=1).max()
print("each marker's worst corner (mm), before -> after the bundle adjustment:")
print({k: f"{before[k]:.1f} -> {after[k]:.1f}" for k in sorted(before)})
cam_after = [
    float(np.linalg.norm((T_1a @ adjusted.camera_poses[f"photo {n}"])[:3, 3] - (T_1w @ T_true[f])[:3, 3]))
    for n, f in enumerate(order)
    if f in located
]
map_before, map_after = np.median(list(before.values())), np.median(list(after.values()))
worst_before, worst_after = max(before.values()), max(after.values())
print(f"markers: median {map_before:.1f} -> {map_after:.1f} mm, worst {worst_before:.1f} -> {worst_after:.1f} mm")
print(f"the {len(cam_after)} other cameras: median {located_median:.1f} -> {np.median(cam_after):.1f} mm")
assert map_after < map_before / 2 and worst_after < worst_before / 2 and np.median(cam_after) < located_median / 2

# %% [markdown]
# One adjustment of {{ len(order) }} photos, every residual at once, brings the markers from
# {{ map_before:.1f }} mm (the median of each marker's worst corner; {{ worst_before:.1f }} mm at worst, marker
# {{ max(before, key=before.get) }}) to {{ map_after:.1f }} mm ({{ worst_after:.1f }} mm at worst), and the
# {{ len(cam_after) }} other cameras from {{ located_median:.1f }} to {{ np.median(cam_after):.1f }} mm (median). The
# errors that passed from poses to markers and back are shared out over every photo that saw them: each pose and
# each marker is now held by all its sightings, not by the two that happened to place it.
#
# ## 9. What full SLAM adds
#
# Here the photos were a batch, the markers known by their ids, and every camera started from `locate` with the
# tape map. Full monocular SLAM (UcoSLAM, ORB-SLAM) drops each of those crutches:
#
# * **no map to start from**: the first markers' placements come from the first photos (section 8), and the gauge
#   is fixed by declaring the first camera (or first marker) the origin;
# * **online**: a new frame is located against the map so far (tracking, notebook 10), and the map is adjusted
#   only now and then, over a window of *keyframes* (local bundle adjustment), to stay real-time;
# * **loop closure**: coming back to a place seen long ago reveals the drift accumulated on the way; a pose-graph
#   optimisation spreads the correction;
# * **natural features** beside markers (corners of the scene itself, matched by descriptors), and then scale
#   is no longer known: a marker's size, or another sensor, fixes it.
#
# The residuals and the sparse Jacobian stay exactly the ones of this notebook.
#
# ## Summary
#
# * A survey is one least-squares problem: 6 unknowns per photo and per free marker, 2 residuals per detected
#   corner and 6 per taped marker; its Jacobian is sparse (each corner touches 12 unknowns), which is what
#   `scipy.optimize.least_squares` exploits.
# * Photos alone fix the map's shape and scale, not where it is: 6 gauge freedoms. The tape (as a prior) or a
#   fixed marker removes them.
# * A robust loss on the tape keeps one wrong tape reading from dragging the rest; the Mahalanobis test, in
#   sigmas and not in millimetres, names it.
# * Ten photos or so, every marker in several of them, already give the map's shape to about a millimetre,
#   where the tape gave centimetres.
# * A printer's scale shows in one photo of four taped markers (`check_print`) and in a survey
#   (`print_scale`): write the printed sizes in the map (`size_mm`) or print again at 100 %.
# * Two photos of non-coplanar points, far enough apart, give the motion between them (the essential matrix) and
#   the points (triangulation), up to scale; one known length, a marker's side, gives the scale. Every photo
#   that sees the result can be located against it, and the markers they see triangulated in turn: the start of
#   monocular SLAM. One bundle adjustment over all those photos (`survey` with no tape) then shares out the errors
#   that building it step by step passed along.
# * A board or a bundle in the map is one rigid entry, surveyed as one object: one placement, one tape prior, one
#   suspect test, however many markers it carries.
#
# **Exercises**: [exercises/11_mapping.ipynb](exercises/11_mapping.ipynb), with automatic feedback
# (or `from fidlearn import exercises; ex = exercises.lesson("11")` in a new cell): count a survey's unknowns,
# build one residual by hand, find the moved marker, choose the next photo, write the sizes your printer made, and
# give a two-photo map its scale.
#
# ## Try it
#
# The cell below surveys with `fixed_ids=[0]` and `map_sigma_mm=float("inf")`: the photos alone, marker 0 as
# the origin. Run it, then:
#
# * Which markers are best known now (the `std` column), and why are the far ones worst?
# * Change `photos` to the first 8: does marker 7 still stand out from the tape (its `diff`)? Look at
#   `alone.photos_per_marker`.
# * In the sweep of section 7, raise the corner noise to 0.5 px: how does the curve move?

# %%
photos = detections  # try detections[:8]
alone = survey(photos, tape_map, camera, fixed_ids=[0], map_sigma_mm=float("inf"))
print(alone.table())

# %% [markdown]
# ## References
#
# * B. Triggs, P. McLauchlan, R. Hartley, A. Fitzgibbon, "Bundle adjustment — a modern synthesis", *Vision
#   Algorithms: Theory and Practice*, LNCS 1883, 2000.
# * R. Hartley, A. Zisserman, *Multiple View Geometry in Computer Vision*, 2nd ed., Cambridge, 2004, ch. 18
#   (N-view computational methods, bundle adjustment).
# * SciPy, `scipy.optimize.least_squares` (the `jac_sparsity`, `loss` and `x_scale` options):
#   https://docs.scipy.org/doc/scipy/reference/generated/scipy.optimize.least_squares.html
# * R. Muñoz-Salinas, M. J. Marín-Jiménez, E. Yeguas-Bolívar, R. Medina-Carnicer, "Mapping and localization from
#   planar markers", *Pattern Recognition* 73, 2018 (MarkerMapper).
# * R. Muñoz-Salinas, R. Medina-Carnicer, "UcoSLAM: simultaneous localization and mapping by fusion of keypoints
#   and squared planar markers", *Pattern Recognition* 101, 2020.
