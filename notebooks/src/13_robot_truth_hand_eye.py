# %% [markdown]
# # 13 The robot's truth: hand-eye calibration
#
# **What you will learn**
#
# * how a robot holding a board gives a truth that does not come from the pixels, to judge a pose by;
# * the two fixed unknowns of that truth (the camera in the robot's base, the board on the robot's flange), and
#   why photos and robot poses together find them: the hand-eye problem $AX = XB$;
# * how to solve it in a few lines (Park and Martin's method, the one behind OpenCV 4's
#   `cv2.calibrateHandEye(..., method=cv2.CALIB_HAND_EYE_PARK)`), for a camera that stands still while the robot
#   moves the board (eye-to-hand);
# * leave-one-out: judging every photo by a fit that never saw it;
# * what the robot says about three ways to measure the board's pose: OpenCV's ChArUco corners, plain
#   `cv2.solvePnP` on the marker corners, and `fidlearn.estimate_pose`, and about the uncertainty it states.
#
# Every notebook so far judged poses against renders, where the truth is known by construction. Real photos
# need a truth from somewhere else. Run the cells from top to bottom (Shift-Enter).

# %%
# %matplotlib inline
import cv2
import matplotlib.pyplot as plt
import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from fidlearn import Camera, MarkerMap, data_path, detect_markers, estimate_pose, frames
from fidlearn.detection import load_image

np.set_printoptions(precision=3, suppress=True)

# %% [markdown]
# ## 1. The photos and the robot's poses
#
# `data/real/robot_charuco/` holds 16 photos (1600 x 1200) from a camera bolted in place, of a ChArUco board
# (5 x 7 squares of 36.195 mm, markers of 18.256 mm from `DICT_6X6_250`) that an industrial robot holds on its
# tool flange, and for each photo the robot's pose: where its flange was in the robot's base frame (`N.yaml`:
# metres and a quaternion). The data come from ROS-Industrial's calibration package (Apache-2.0; provenance in
# `data/README.md`). The robot's pose is measured by its joint encoders, not by any camera.

# %%
FOLDER = data_path("real", "robot_charuco")
N = 16


def robot_pose(i):
    """T_base_tool of photo i (4x4, mm) from its yaml file (x, y, z in metres, quaternion qx, qy, qz, qw)."""
    v = {}
    for line in (FOLDER / f"{i}.yaml").read_text().splitlines():
        key, _, value = line.partition(":")
        v[key.strip()] = float(value)
    R = Rotation.from_quat([v["qx"], v["qy"], v["qz"], v["qw"]]).as_matrix()
    return frames.make_transform(R, 1000.0 * np.array([v["x"], v["y"], v["z"]]))


T_base_tool = [robot_pose(i) for i in range(N)]
photos = [load_image(FOLDER / f"{i}.png") for i in range(N)]
print(f"{N} photos of {photos[0].shape[1]} x {photos[0].shape[0]}; photo 0's flange in the base (mm):")
print(T_base_tool[0])

fig, axes = plt.subplots(1, 3, figsize=(13, 3.4))
for ax, i in zip(axes, (0, 7, 15)):
    ax.imshow(photos[i], cmap="gray")
    ax.set_title(f"photo {i}")
    ax.axis("off")
plt.show()

# %% [markdown]
# ## 2. The board's pose in every photo, three ways
#
# First the camera: `cv2.calibrateCamera` on the ChArUco corners of these same photos (notebook 02 did the
# same with a checkerboard). OpenCV's `CharucoDetector` finds the markers and, between them, the chessboard
# corners; each corner has an id and a known place on the board, in the board's frame (origin at its top-left
# outer corner, x along the first row of squares, y down the board, z into it, mm).

# %%
board = cv2.aruco.CharucoBoard((5, 7), 36.195, 18.256, cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250))
chess_mm = np.asarray(board.getChessboardCorners(), dtype=float)
charuco = [cv2.aruco.CharucoDetector(board).detectBoard(p)[:2] for p in photos]
obj = [chess_mm[ids.ravel()].astype(np.float32) for _, ids in charuco]
img = [corners.reshape(-1, 2).astype(np.float32) for corners, _ in charuco]
rms, K, dist, _, _ = cv2.calibrateCamera(obj, img, (1600, 1200), None, None)
camera = Camera(K, dist.ravel(), (1600, 1200))
print(f"{sum(len(o) for o in obj)} ChArUco corners in {N} photos; calibration RMS {rms:.3f} px")
print(camera)

# %% [markdown]
# Three measurements of `T_camera_board` per photo:
#
# * **ChArUco corners**: `cv2.solvePnP` on the chessboard corners (the board's own corners, the most precise);
# * **plain markers**: `cv2.solvePnP` on the markers' corners, as a user would write it;
# * **fidlearn**: `estimate_pose` on the same markers. The board is a map whose "world" is the board's frame:
#   a `MarkerMap` places each marker by its top-left corner and the rotation that turns the marker's own axes
#   (right, up, out of its face: world +y, +z, +x at rotation 0) into the board's (right +x, up -y, out -z).

# %%
marker_corners_mm = np.asarray(board.getObjPoints(), dtype=float)  # (17, 4, 3), TL TR BR BL
R_board_marker = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]])
rpy = [float(a) for a in frames.rpy_deg_from_rotation(R_board_marker)]
board_map = MarkerMap.from_dict(
    {
        "units": "mm",
        "marker_size_mm": 18.256,
        "dictionary": "6X6_250",
        "markers": {str(i): {"translation": list(c[0]), "rotation": rpy} for i, c in enumerate(marker_corners_mm)},
    }
)
assert np.allclose(board_map.marker_corners(5), marker_corners_mm[5], atol=1e-6)  # the same corners, in order


def solve(obj_mm, img_px):
    """T_camera_board from 3D-2D pairs with cv2.solvePnP (iterative, from OpenCV's own start)."""
    _, rvec, tvec = cv2.solvePnP(obj_mm, img_px, camera.K, camera.dist)
    return frames.transform_from_rvec_tvec(rvec.ravel(), tvec.ravel())


measured = {"ChArUco corners": [], "plain markers": [], "fidlearn": []}
poses = []
for i, p in enumerate(photos):
    measured["ChArUco corners"].append(solve(obj[i], img[i]))
    found = [d for d in detect_markers(p, "6X6_250") if d.id < 17]
    measured["plain markers"].append(
        solve(np.concatenate([marker_corners_mm[d.id] for d in found]), np.concatenate([d.corners_px for d in found]))
    )
    poses.append(estimate_pose(found, board_map, camera))
    measured["fidlearn"].append(frames.invert_transform(poses[-1].T_world_camera))
print("photo 0, T_camera_board by ChArUco corners (mm):")
print(measured["ChArUco corners"][0])

# %% [markdown]
# ## 3. The chain and its two unknowns
#
# The board's pose in the camera, from the robot alone, is a chain of three transforms:
#
# $$T^{\text{camera}}_{\text{board}}(i) = \big(T^{\text{base}}_{\text{camera}}\big)^{-1}\;
# T^{\text{base}}_{\text{tool}}(i)\; T^{\text{tool}}_{\text{board}}$$
#
# The middle one the robot reports for every photo. The outer two are fixed and unknown: where the camera is
# bolted in the robot's frame ($X = T^{\text{base}}_{\text{camera}}$), and where the board is clamped on the
# flange. Compare two photos $i$ and $j$: the flange moved by $A = T^{\text{base}}_{\text{tool}}(i)\,
# \big(T^{\text{base}}_{\text{tool}}(j)\big)^{-1}$ (in the base's frame) while the board, seen from the camera,
# moved by $B = T^{\text{camera}}_{\text{board}}(i)\,\big(T^{\text{camera}}_{\text{board}}(j)\big)^{-1}$.
# Multiply the chain of photo $i$ by the inverse of photo $j$'s: the board on the flange cancels, and
# $AX = XB$. This is the classic **hand-eye** problem (Tsai and Lenz 1989; Park and Martin 1994). One photo
# cannot tell $X$; pairs whose rotations turn about different axes can.
#
# **The rotation first.** The rotation part of $AX = XB$ reads $R_A R_X = R_X R_B$: $R_A$ is $R_B$ seen through
# $R_X$, so their rotation vectors (notebook 03) obey $\alpha = R_X \beta$. With many pairs that is the problem
# of notebook 10's mean rotation and of aligning two point sets: the best $R_X$ comes from the SVD of
# $M = \sum_k \alpha_k \beta_k^\top$ (Kabsch). **Then the translation**: the translation part,
# $(R_A - I)\, t_X = R_X t_B - t_A$, is linear in $t_X$: least squares over all pairs. Finally the board on the
# flange: every photo says where it is, $\big(T^{\text{base}}_{\text{tool}}(i)\big)^{-1} X\,
# T^{\text{camera}}_{\text{board}}(i)$; average them. **Last, refine both at once**: least squares
# (`scipy.optimize.least_squares`) on the distance between where each photo's measured pose and the chain put
# the board's corners. The closed form treats every pair alike; the refinement weighs every photo by what it
# saw.
#
# OpenCV 4 has this as `cv2.calibrateHandEye` (written for a camera *on* the hand; for a camera that stands
# still, give it the robot's poses inverted). OpenCV 5.0's Python bindings leave it out, so we write it; where
# OpenCV has it, the cell checks that both agree.


# %%
def rotvec(R):
    return Rotation.from_matrix(R).as_rotvec()


def nearest_rotation(M):
    """The rotation nearest to a 3x3 matrix (SVD, determinant +1)."""
    U, _, Vt = np.linalg.svd(M)
    return U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt


def hand_eye(photos_used, method="ChArUco corners"):
    """T_base_camera and T_tool_board (mm) from the photos' robot poses and one method's board poses."""
    return refine(*closed_form(photos_used, measured[method]), list(photos_used), measured[method])


def closed_form(photos_used, T_cb):
    """Park and Martin's closed form: T_base_camera, then T_tool_board as the photos' mean."""
    used = list(photos_used)
    pairs = [(i, j) for i in used for j in used if i < j]
    A = [T_base_tool[i] @ frames.invert_transform(T_base_tool[j]) for i, j in pairs]
    B = [T_cb[i] @ frames.invert_transform(T_cb[j]) for i, j in pairs]
    R_X = nearest_rotation(sum(np.outer(rotvec(a[:3, :3]), rotvec(b[:3, :3])) for a, b in zip(A, B)))
    lhs = np.concatenate([a[:3, :3] - np.eye(3) for a in A])
    rhs = np.concatenate([R_X @ b[:3, 3] - a[:3, 3] for a, b in zip(A, B)])
    T_base_camera = frames.make_transform(R_X, np.linalg.lstsq(lhs, rhs, rcond=None)[0])
    each = [frames.invert_transform(T_base_tool[i]) @ T_base_camera @ T_cb[i] for i in used]
    T_tool_board = frames.make_transform(
        nearest_rotation(np.mean([T[:3, :3] for T in each], axis=0)), np.mean([T[:3, 3] for T in each], axis=0)
    )
    return T_base_camera, T_tool_board


def as_params(T):
    return np.concatenate([rotvec(T[:3, :3]), T[:3, 3]])


def from_params(x):
    return frames.make_transform(Rotation.from_rotvec(x[:3]).as_matrix(), x[3:])


def chain_residuals(x, used, T_cb):
    """For every photo, the board's corners (mm, in the camera) where the chain puts them minus where measured."""
    X, Y = from_params(x[:6]), from_params(x[6:])
    corners = np.column_stack([chess_mm, np.ones(len(chess_mm))]).T
    return np.concatenate(
        [((frames.invert_transform(X) @ T_base_tool[i] @ Y - T_cb[i]) @ corners)[:3].ravel() for i in used]
    )


def refine(T_base_camera, T_tool_board, used, T_cb):
    """Both transforms refined together by least squares on the board's corners."""
    fit = least_squares(
        chain_residuals, np.concatenate([as_params(T_base_camera), as_params(T_tool_board)]), args=(used, T_cb)
    )
    return from_params(fit.x[:6]), from_params(fit.x[6:])


def predict(i, T_base_camera, T_tool_board):
    """The board's pose in the camera for photo i, from the robot alone."""
    return frames.invert_transform(T_base_camera) @ T_base_tool[i] @ T_tool_board


T_base_camera, T_tool_board = hand_eye(range(N))
if hasattr(cv2, "calibrateHandEye"):  # OpenCV 4: the same method, for a camera on the hand
    T_tool_base = [frames.invert_transform(T) for T in T_base_tool]
    T_cb = measured["ChArUco corners"]
    R_cv, t_cv = cv2.calibrateHandEye(
        [T[:3, :3] for T in T_tool_base],
        [T[:3, 3] for T in T_tool_base],
        [T[:3, :3] for T in T_cb],
        [T[:3, 3] for T in T_cb],
        method=cv2.CALIB_HAND_EYE_PARK,
    )
    ours = closed_form(range(N), T_cb)[0]  # before the refinement, which OpenCV does not do
    assert frames.rotation_angle_deg(R_cv, ours[:3, :3]) < 0.1
    assert np.linalg.norm(t_cv.ravel() - ours[:3, 3]) < 2.0
print("the camera in the robot's base (mm):")
print(T_base_camera)
print(f"the board's origin is {np.linalg.norm(T_tool_board[:3, 3]):.1f} mm from the flange")
fit_rms = float(
    np.sqrt(
        np.mean(
            np.square(
                chain_residuals(
                    np.concatenate([as_params(T_base_camera), as_params(T_tool_board)]),
                    range(N),
                    measured["ChArUco corners"],
                )
            )
            .reshape(-1, 3)
            .sum(axis=1)
        )
    )
)
print(f"the chain puts the board's corners {fit_rms:.2f} mm (RMS) from where the photos measured them")

# %% [markdown]
# ## 4. Judge every photo by a fit that never saw it
#
# Fitted to all 16 photos, the chain would partly copy each photo's own error. So for each photo, fit the two
# transforms to the *other* 15 and predict this one from the robot: **leave-one-out**. Then measure, for each
# method, how far the board's centre is from where the robot says it is, and by how much the board is turned.

# %%
centre_mm = np.array([5 * 36.195 / 2, 7 * 36.195 / 2, 0.0, 1.0])
predicted = []
for i in range(N):
    others = [j for j in range(N) if j != i]
    predicted.append(predict(i, *hand_eye(others)))

errors = {}
for name, Ts in measured.items():
    pos = [np.linalg.norm((Ts[i] - predicted[i]) @ centre_mm) for i in range(N)]
    rot = [frames.rotation_angle_deg(Ts[i][:3, :3], predicted[i][:3, :3]) for i in range(N)]
    errors[name] = np.array(pos)
    print(
        f"{name:16s} position error median {np.median(pos):5.2f} mm, worst {max(pos):5.2f} mm; "
        f"rotation median {np.median(rot):.3f} deg"
    )

fig, ax = plt.subplots(figsize=(11, 3.4))
for k, (name, e) in enumerate(errors.items()):
    ax.bar(np.arange(N) + 0.27 * (k - 1), e, width=0.27, label=name)
ax.set_xticks(range(N))
ax.set_xlabel("photo")
ax.set_ylabel("board centre vs the robot (mm)")
ax.legend()
plt.show()

# %% [markdown]
# The board's centre is about {{ np.median([np.linalg.norm((p @ centre_mm)[:3]) for p in predicted]) / 1000:.1f }} m
# from the camera; the ChArUco corners put it within {{ np.median(errors["ChArUco corners"]):.2f }} mm of the robot's
# answer (median), the markers alone within {{ np.median(errors["plain markers"]):.2f }} mm (plain OpenCV) and
# {{ np.median(errors["fidlearn"]):.2f }} mm (fidlearn). Part of every figure is the robot's own error and the
# hand-eye fit's: fitted to all photos the chain already misses the measured corners by {{ fit_rms:.1f }} mm
# (RMS), so the truth here is good to about that, and differences well under it between methods say little. Photos far
# from the rest (the worst ones) are also where the other 15
# photos say least about the chain.
#
# ## 5. Does the stated uncertainty hold?
#
# `estimate_pose` states a covariance for every pose. If it is honest, the robot's answer (the camera's place in
# the board's frame) falls inside the 95 % ellipsoid of the camera's position in about 95 % of the photos.

# %%
nees = []
for i, pose in enumerate(poses):
    truth = frames.invert_transform(predicted[i])[:3, 3]  # the camera in the board's frame, from the robot
    d = truth - pose.position_mm
    nees.append(float(d @ np.linalg.solve(pose.covariance[3:, 3:], d)))  # position block: mm^2
nees = np.array(nees)
inside = int(np.sum(nees <= 7.815))  # chi-square with 3 degrees of freedom, 95 %
print(f"robot's answer inside fidlearn's 95 % position ellipsoid: {inside} of {N} photos")
print(f"median squared Mahalanobis distance {np.median(nees):.1f} (about 2.4, the median of chi-square 3, if honest)")

# %% [markdown]
# The robot holds its answer inside the stated 95 % region in {{ inside }} of the {{ N }} photos. Two things make
# the stated uncertainty too small here: the robot's truth has errors of its own (the chain above), and the
# corners are not the only thing the pose model gets wrong on a real board (a print that is not perfectly flat,
# a lens the 5 coefficients do not describe exactly). This is why a pose's covariance must be checked against an
# independent truth before anyone plans with it, and why notebook 09 measures that coverage.
#
# ## What you have learnt
#
# * A robot's encoders give a truth independent of the pixels, through a chain with two fixed unknowns.
# * Pairs of photos give $AX = XB$: the rotation from aligned rotation vectors (SVD), then the translation by
#   linear least squares (OpenCV 4's `cv2.calibrateHandEye`, for a static camera with the robot's poses inverted).
# * Leave-one-out keeps a photo's own error out of the truth it is judged by.
# * Measured this way, the chess corners and the markers agree to within the robot's own error (its chain misses
#   by about as much as they differ): this judge cannot rank them (notebook 14 shows where the chess corners win,
#   in the rotation); the stated uncertainty must be checked, not trusted.
#
# **Exercises**: [exercises/13_hand_eye.ipynb](exercises/13_hand_eye.ipynb), with automatic feedback (or
# `from fidlearn import exercises; ex = exercises.lesson("13")` in a new cell).
#
# ## Try it
#
# * The cell below fits the chain to fidlearn's poses instead of the ChArUco corners' and judges both methods
#   again: does the judge's choice change the verdict?
# * Fit the chain with only the pairs of consecutive photos (`pairs` in `hand_eye`): how much worse is it?
# * Judge the published intrinsics (`data/real/robot_charuco/cal_data.yaml`: fx 1352.03, fy 1356.14, cx 789.67,
#   cy 627.30, no distortion) in place of the calibration of section 2.

# %%
for truth_from in ("ChArUco corners", "fidlearn"):
    loo = [predict(i, *hand_eye([j for j in range(N) if j != i], method=truth_from)) for i in range(N)]
    for name in ("ChArUco corners", "fidlearn"):
        e = [np.linalg.norm((measured[name][i] - loo[i]) @ centre_mm) for i in range(N)]
        print(f"chain fitted to {truth_from:15s}: {name:15s} median {np.median(e):.2f} mm, worst {max(e):.2f} mm")

# %% [markdown]
# ## References
#
# * R. Y. Tsai, R. K. Lenz, "A new technique for fully autonomous and efficient 3D robotics hand/eye
#   calibration", *IEEE Transactions on Robotics and Automation* 5(3), 1989.
# * F. C. Park, B. J. Martin, "Robot sensor calibration: solving AX = XB on the Euclidean group", *IEEE
#   Transactions on Robotics and Automation* 10(5), 1994.
# * P. Corke, *Robotics, Vision and Control*, 3rd ed., Springer, 2023 (camera calibration and hand-eye).
# * OpenCV 4, `cv2.calibrateHandEye`: https://docs.opencv.org/4.x/d9/d0c/group__calib3d.html
# * ROS-Industrial, `industrial_calibration` (the photos and robot poses):
#   https://github.com/ros-industrial/industrial_calibration
